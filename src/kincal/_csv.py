"""Reading CSV text as users' tools write it: a header line; comma, semicolon or tab separated;
UTF-8 (with or without Excel's BOM) or Latin-1; blank and '#' lines skipped; decimal commas where
the separator is not a comma. Shared by the measurement and observation readers; errors name the
file and the row."""
from __future__ import annotations

import csv
import re
from pathlib import Path

from .errors import MeasurementError

DECIMAL_COMMA = re.compile(r"^\s*[+-]?(\d+,\d*|,\d+)([eE][+-]?\d+)?\s*$")


def sniff_delimiter(header: str, path: str) -> str:
    counts = {d: header.count(d) for d in (",", ";", "\t")}
    best = max(counts, key=counts.get)
    if counts[best] == 0:
        raise MeasurementError(f"{path}: cannot find a ',', ';' or tab separator in the header line")
    return best


def read_text(path: str) -> str:
    """The file's text: UTF-8 (with or without the BOM Excel writes), else Latin-1."""
    try:
        raw = Path(path).read_bytes()
    except OSError as exc:
        raise MeasurementError(f"{path}: cannot read the file ({exc.strerror})") from None
    if b"\0" in raw[:4096]:
        raise MeasurementError(f"{path}: this is not a text file (CSV expected; UTF-16 exports: save as 'CSV UTF-8')")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def data_lines(text: str) -> list[tuple[int, str]]:
    """(1-based line number, line) of every line that is not blank or a '#' comment."""
    return [(k, line) for k, line in enumerate(text.splitlines(), start=1)
            if line.strip() and not line.lstrip().startswith("#")]


def number(cell: str, delimiter: str) -> float:
    """A cell as a float; decimal commas are read where the separator is not a comma."""
    if delimiter != "," and DECIMAL_COMMA.match(cell):
        cell = cell.replace(",", ".")
    return float(cell)


def is_float(s: str, delimiter: str = ",") -> bool:
    try:
        number(s, delimiter)
        return True
    except ValueError:
        return False


def read_table(path: str) -> tuple[list[str], list[tuple[int, list[str]]], str, int]:
    """The header (stripped names), the records as (line number, cells), the separator and the
    header's line number; every record has as many fields as the header."""
    lines = data_lines(read_text(path))
    if not lines:
        raise MeasurementError(f"{path}: the file is empty; expected a header line and one row per pose")
    delim = sniff_delimiter(lines[0][1], path)
    records = list(zip((k for k, _ in lines), csv.reader((line for _, line in lines), delimiter=delim)))
    header = [h.strip() for h in records[0][1]]
    for k, rec in records[1:]:
        if len(rec) != len(header):
            hint = (" (decimal commas in a comma-separated file? use ';' as the separator, or '.' for decimals)"
                    if len(rec) > len(header) and delim == "," else "")
            raise MeasurementError(f"{path}: row {k} has {len(rec)} fields, the header has {len(header)}{hint}")
    if len(records) < 2:
        raise MeasurementError(f"{path}: no data rows after the header")
    return header, [(k, rec) for k, rec in records[1:]], delim, records[0][0]
