"""Reading CSV text as users' tools write it: a header line; comma, semicolon or tab separated;
UTF-8 (with or without Excel's BOM) or Latin-1; blank and '#' lines skipped; decimal commas where
the separator is not a comma. Shared by the measurement and observation readers (``Table``: every
column they read is checked the same way: named once, present, a number as a CSV cell writes it,
finite, physically possible, converted to SI); errors name the file, the row and the column."""
from __future__ import annotations

import csv
import io
import os
import re
from dataclasses import dataclass, field

import numpy as np

from .errors import MeasurementError
from .units import ANGLE_UNITS, LENGTH_UNITS, MRAD

DECIMAL_COMMA = re.compile(r"^\s*[+-]?(\d+,\d*|,\d+)([eE][+-]?\d+)?\s*$")
# a number as a CSV cell writes it: ASCII digits, one optional '.', an optional exponent (Python's float()
# also takes '0_5' as 5 and '١٢' as 12: neither is a number in a measurement file)
NUMBER = re.compile(r"[+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?")
# a cell whose '.' or ',' groups thousands (1-3 digits, then groups of exactly 3: '-432.472', '1,234,567'), and a
# number with that mark as its decimal mark and not so grouped (the file's decimals: '-22,933297', '0.5')
GROUPED = {m: re.compile(rf"[+-]?[0-9]{{1,3}}(\{m}[0-9]{{3}})+") for m in ".,"}
DECIMALS = {m: re.compile(rf"[+-]?[0-9]*\{m}[0-9]+([eE][+-]?[0-9]+)?") for m in ".,"}
# a number whose digits a '.' or ',' groups by three, decimals after the other mark or none ('-432.471,963')
THOUSANDS = re.compile(r"[+-]?[0-9]{1,3}([.,])[0-9]{3}(\1[0-9]{3})*((?!\1)[.,][0-9]*)?")
NO_1000 = "write the numbers without thousands separators; in Excel: Format Cells > Number, untick 'Use 1000 Separator'"
# a number with its unit written after it ('-22.9 deg', '-22.9°', '-432.4 mm'): the unit named the flag's way
UNIT_IN_CELL = re.compile(r"[+-]?[0-9.,]*[0-9]([eE][+-]?[0-9]+)?\s*(?P<unit>mm|um|µm|m|rad|deg|°|rev)")
UNIT_NAMES = {"µm": ("length", "um"), "°": ("angle", "deg"), **{u: ("length", u) for u in LENGTH_UNITS},
              **{u: ("angle", u) for u in ANGLE_UNITS}}
NOT_FINITE = re.compile(r"[+-]?(nan|inf|infinity)", re.IGNORECASE)  # read, then refused by row (check_finite)
MAX_LISTED = 10  # rows named in an error message
# SI magnitudes beyond any robot's: a coordinate or prismatic joint value 10 km from the base, a joint (a screw's
# motor included) turned 16000 times, an orientation value (quaternion, matrix entry, angle) of 10000 are a wrong
# cell or unit (and 1e300 overflows every square): refused by row and column
LIMIT = {"length": 1e4, "angle": 1e5, "number": 1e4}
LIMIT_TEXT = {"length": "10 km from the robot's base", "angle": "100000 rad (16000 turns)",
              "number": "10000 (orientation values are at most 1 or a few turns)"}
# (kind, SI factor) of a file unit: a length ('mm'), an angle ('deg', 'mrad') or None (plain numbers)
FILE_UNITS: dict[str | None, tuple[str, float]] = {
    None: ("number", 1.0), "mrad": ("angle", 1.0 / MRAD), **{u: ("length", f) for u, f in LENGTH_UNITS.items()},
    **{u: ("angle", f) for u, f in ANGLE_UNITS.items()}}


def sniff_delimiter(header: str, path: str) -> str:
    counts = {d: header.count(d) for d in (",", ";", "\t")}
    best = max(counts, key=counts.__getitem__)
    if counts[best] == 0:
        raise MeasurementError(f"{path}: cannot find a ',', ';' or tab separator in the header line")
    return best


def _read_bytes(path: str, size: int = -1) -> bytes:
    """The file's first ``size`` bytes (-1: all); MeasurementError when it cannot be read or is not
    text (a NUL byte in its first 4 kB: UTF-16, a binary file)."""
    try:
        with open(path, "rb") as fh:
            raw = fh.read(size)
    except OSError as exc:
        raise MeasurementError(f"{path}: cannot read the file ({exc.strerror})") from None
    if b"\0" in raw[:4096]:
        raise MeasurementError(f"{path}: this is not a text file (CSV expected; UTF-16 exports: save as 'CSV UTF-8')")
    return raw


def read_text(path: str) -> str:
    """A user's text file whole (a leading BOM dropped; Latin-1 when it is not UTF-8); MeasurementError naming it
    when it cannot be read or is not text."""
    return _decoded(_read_bytes(str(path)), "utf-8-sig")


def _decoded(raw: bytes, encoding: str = "utf-8") -> str:
    """``raw`` as UTF-8 ('utf-8-sig': a leading BOM dropped), else Latin-1."""
    try:
        return raw.decode(encoding)
    except UnicodeDecodeError:
        return raw.decode("latin-1")


PLAN_HEAD = "# kincal verification plan"  # the first line of the plans 'kincal verify -o' writes
INDEX_COLUMNS = {"pose", "id", "index", "sample", "row", "n"}  # a poses file's row-number column


def data_lines(text: str) -> list[tuple[int, str]]:
    """(1-based line number, line) of every line that is not blank or a '#' comment."""
    return [(k, line) for k, line in enumerate(text.splitlines(), start=1)
            if line.strip() and not line.lstrip().startswith("#")]


def number(cell: str, delimiter: str) -> float:
    """A cell as a float: ``NUMBER`` (decimal commas where the separator is not a comma) or nan/inf,
    which the callers refuse; anything else (``0_5``, '0x10', '') is a ValueError."""
    text = cell.strip()
    if delimiter != "," and DECIMAL_COMMA.match(text):
        text = text.replace(",", ".")
    if not (NUMBER.fullmatch(text) or NOT_FINITE.fullmatch(text)):
        raise ValueError(f"'{cell}' is not a number")
    return float(text)


def why_not(cell: str) -> str:
    """What is wrong with a cell that is not a number, for the message ('' when it says itself)."""
    text = cell.strip()
    if not text:
        return " (the cell is empty)"
    if "_" in text:
        return " (no '_' inside numbers: write 0.5 or 5, not 0_5)"
    unit = UNIT_IN_CELL.fullmatch(text)
    if unit:
        kind, name = UNIT_NAMES[unit["unit"]]
        return (f" (the unit '{unit['unit']}' is written in the cell: write the number alone and give the unit as the "
                f"file's {kind} unit, {kind}_unit='{name}' (CLI: --{kind}-unit {name}))")
    grouped = THOUSANDS.fullmatch(text)
    if grouped and (grouped[3] or grouped[2]):  # both marks, or one twice: a thousands separator
        return f" ('{grouped[1]}' as a thousands separator: {NO_1000})"
    if "," in text:
        return (" (a decimal comma" + (", or ',' as a thousands separator" if grouped else "")
                + ": use '.' for decimals (no thousands separator) or a ';' separated file)")
    return ""


def open_table(path: str, kinds: str = "joint, position or σ") -> Table:
    """The CSV at ``path`` read whole as a ``Table`` (``kinds``: what its columns may be, for messages):
    the header (stripped names), the records as (line number, cells), the separator and the header's
    line number; every record has as many fields as the header."""
    text = _decoded(_read_bytes(path), "utf-8-sig")  # Excel writes UTF-8 with a BOM
    if text.startswith(PLAN_HEAD):
        raise MeasurementError(f"{path}: a kincal verification plan (the commands to run and the positions the model "
                               f"predicts there), not measurements: run its commands, measure, and judge them with "
                               f"kincal verify ROBOT --plan {path} --measured MEASUREMENTS")
    lines = data_lines(text)
    if not lines:
        raise MeasurementError(f"{path}: the file is empty; expected a header line and one row per pose")
    delim = sniff_delimiter(lines[0][1], path)
    records = list(zip((k for k, _ in lines), csv.reader((line for _, line in lines), delimiter=delim)))
    header = [h.strip() for h in records[0][1]]
    while len(records) > 1 and not any(c.strip() for c in records[-1][1]):
        records.pop()  # rows of separators only after the data: the rows a spreadsheet leaves below its table
    check_fields(path, records[1:], header, delim)
    if len(records) < 2:
        raise MeasurementError(f"{path}: no data rows after the header")
    return Table(path, header, records[1:], delim, records[0][0], kinds)


def check_fields(path: str, records, header: list[str], delim: str) -> None:
    """MeasurementError naming the first of ``records`` ((line number, cells)) without the header's field count."""
    for k, rec in records:
        if len(rec) != len(header):
            hint = (" (decimal commas in a comma-separated file? use ';' as the separator, or '.' for decimals)"
                    if len(rec) > len(header) and delim == "," else "")
            raise MeasurementError(f"{path}: row {k} has {len(rec)} fields, the header has {len(header)}{hint}")


def check_once(path: str, header: list[str], columns, kinds: str) -> None:
    """Each of ``columns`` asked for once and named once in the header, else an error saying which
    (``kinds``: what the columns are, for the message)."""
    columns = list(columns)
    asked = [c for c in dict.fromkeys(columns) if columns.count(c) > 1]
    if asked:
        raise MeasurementError(f"{path}: column(s) {', '.join(asked)} given more than once (as {kinds} columns); "
                               f"each value must come from its own column")
    twice = [c for c in dict.fromkeys(columns) if header.count(c) > 1]
    if twice:
        raise MeasurementError(f"{path}: the header names column(s) {', '.join(twice)} more than once (columns "
                               f"{', '.join(str(k + 1) for k, h in enumerate(header) if h in twice)}); rename them so "
                               f"that each name is one column")


def cell_numbers(path: str, records, header: list[str], cols, delim: str, empty_ok: bool = False,
                 finite: bool = True):
    """The named columns of ``records`` ((line number, cells) pairs) as floats (N, len(cols)), each
    cell checked: a cell that is not a number (or empty, with ``empty_ok``: NaN) is refused, naming
    the file, row and column and why; with ``finite`` NaN and inf too, else they are read for the
    caller to refuse by row (``check_finite``)."""
    check_grouping(path, records, header, cols, delim)
    idx = [header.index(c) for c in cols]
    out = np.empty((len(records), len(cols)))
    for r, (k, rec) in enumerate(records):
        for j, i in enumerate(idx):
            cell = rec[i].strip()
            if empty_ok and cell == "":
                out[r, j] = np.nan
                continue
            try:
                out[r, j] = number(cell, delim)
                if not finite or np.isfinite(out[r, j]):
                    continue
            except ValueError:
                pass
            if not any(c.strip() for c in rec):
                raise MeasurementError(f"{path}: row {k} is empty (only separators, as a spreadsheet writes a row it "
                                       f"has cleared) among the data: delete the row, or fill in its values")
            kind = "finite number" if finite else "number"
            raise MeasurementError(f"{path}: row {k}, column '{cols[j]}': '{rec[i]}' is not a {kind}"
                                   f"{' (or empty)' if empty_ok else ''}{why_not(rec[i])}")
    return out


def check_grouping(path: str, records, header: list[str], cols, delim: str) -> None:
    """MeasurementError when a column of ``cols`` writes '.' (',') in a file whose decimals are commas (points) and
    every such cell groups thousands ('-432.472' beside '-22,933297'): a spreadsheet's thousands separator, which
    the cell-by-cell reading would take for a decimal mark (1000 times too small) or a decimal comma; which one
    the file means is not guessed. ``records``: (line number, cells) of the file (or of a block of it), every
    column looked at for the file's decimals. In a comma-separated file a ',' in a cell is refused cell by cell."""
    if delim == ",":
        return
    for col in cols:
        i = header.index(col)
        for mark, other in ((".", ","), (",", ".")):
            cells = [(k, rec[i].strip()) for k, rec in records if mark in rec[i]]
            if not cells or not all(GROUPED[mark].fullmatch(c) for _, c in cells):
                continue
            seen = next(((k, h, c.strip()) for k, rec in records for h, c in zip(header, rec)
                         if DECIMALS[other].fullmatch(c.strip()) and not GROUPED[other].fullmatch(c.strip())), None)
            if seen:
                (k, cell), names = cells[0], {".": "points", ",": "commas"}
                raise MeasurementError(
                    f"{path}: column '{col}' groups thousands with '{mark}' (row {k}: '{cell}'; all {len(cells)} of "
                    f"its cells with a '{mark}' have groups of 3 digits) while the file's decimals are {names[other]} "
                    f"(row {seen[0]}, column '{seen[1]}': '{seen[2]}'); kincal does not guess whether '{cell}' is "
                    f"{cell.replace(mark, '')} or {cell.replace(mark, '.')}: {NO_1000}")


def listed(rows) -> str:
    """'5, 17, 30 and 4 more' for messages."""
    rows = [str(int(r)) for r in rows]
    more = f" and {len(rows) - MAX_LISTED} more" if len(rows) > MAX_LISTED else ""
    return ", ".join(rows[:MAX_LISTED]) + more


def check_finite(path: str, values: np.ndarray, rows: np.ndarray, cols, what: str = "values", skip=None) -> None:
    """MeasurementError naming the rows (file line numbers) that hold NaN or infinite ``values``
    (N, len(cols)) and the first such cell's row and column; ``skip``: cells not to look at (empty)."""
    bad = ~np.isfinite(values) if skip is None else ~np.isfinite(values) & ~skip
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise MeasurementError(f"{path}: NaN or infinite {what} in row(s) {listed(rows[bad.any(axis=1)])} (first: "
                               f"row {rows[r]}, column '{list(cols)[c]}'); remove or fix those rows")


def in_si(path: str, values: np.ndarray, rows: np.ndarray, cols, units) -> np.ndarray:
    """``values`` (N, len(cols)) given in the file's ``units`` (one per column; None: plain numbers)
    in SI; a value no robot can have (beyond ``LIMIT``) is refused naming the row, column and unit.
    NaN (empty cells) pass."""
    unknown = [u for u in units if u not in FILE_UNITS]
    if unknown:
        raise ValueError(f"unknown unit '{unknown[0]}'")
    kinds, factors = zip(*(FILE_UNITS[u] for u in units)) if len(units) else ((), ())
    si = values * np.array(factors)
    with np.errstate(invalid="ignore"):
        over = np.abs(si) > np.array([LIMIT[k] for k in kinds])
    if over.any():
        r, c = np.argwhere(over)[0]
        unit = f" {units[c]}" if units[c] else ""
        raise MeasurementError(f"{path}: row {rows[r]}, column '{list(cols)[c]}': {values[r, c]:g}{unit} is not "
                               f"physically possible for a robot (beyond {LIMIT_TEXT[kinds[c]]}); fix the cell"
                               + (f", or the {kinds[c]} unit if the file is in another" if unit else ""))
    return si


def check_present(path: str, header: list[str], cols, what: str = "", header_line: int = 1) -> None:
    """MeasurementError listing the header when a column of ``cols`` is not in it; ``what``: what the
    columns are for (e.g. '--type pose needs the orientation columns'), else they are just named."""
    missing = [c for c in cols if c not in header]
    if missing:
        head = f"{what} ({', '.join(missing)} not found)" if what else f"column(s) {', '.join(missing)} not found"
        where = f" (line {header_line})" if header_line != 1 else ""
        raise MeasurementError(f"{path}: {head}; the header has: {', '.join(header)}{where}")


@dataclass(frozen=True)
class Table:
    """A CSV read whole (``open_table``) whose columns every reader reads through ``numbers`` and
    ``text``, checked the same way: asked for once and named once in the header (over all the reads
    of the file, ``kinds`` naming what the columns are), present, numbers as a CSV cell writes them,
    finite, physically possible, in SI."""

    path: str
    header: list[str]
    records: list  # (line number, cells)
    delim: str
    header_line: int
    kinds: str
    used: list = field(default_factory=list)  # the columns read so far

    @property
    def rows(self) -> np.ndarray:
        return np.array([k for k, _ in self.records], dtype=int)

    def need(self, cols, what: str = "") -> None:
        """``cols`` each named once in the header and present (``what``: what they are for); a file that holds
        nothing but the columns read so far (joint values only: a design's or a plan's poses) is said to be one."""
        check_once(self.path, self.header, list(cols), self.kinds)
        try:
            check_present(self.path, self.header, list(cols), what, self.header_line)
        except MeasurementError as exc:
            if not set(self.header) <= set(self.used) | set(cols) | INDEX_COLUMNS:  # it has columns of its own
                raise
            raise MeasurementError(f"{exc}; it holds joint values only: a list of poses (a design, poses to run)? "
                                   f"measure at them, then give the instrument's readings") from None

    def use(self, cols) -> None:
        """Mark ``cols`` read: each once, named once in the header, present."""
        cols = list(cols)
        self.need(self.used + cols)  # the columns read before are present: only these can be missing
        self.used.extend(cols)

    def text(self, col: str) -> np.ndarray:
        self.use([col])
        i = self.header.index(col)
        return np.array([rec[i].strip() for _, rec in self.records])

    def numbers(self, cols, units=None, empty_ok: bool = False, what: str = "values") -> np.ndarray:
        """The columns' values in SI (N, len(cols)); ``units``: the file's unit of each column, or one
        for all (None: plain numbers); ``empty_ok``: an empty cell is NaN."""
        cols = list(cols)
        self.use(cols)
        values = cell_numbers(self.path, self.records, self.header, cols, self.delim, empty_ok, finite=False)
        rows, idx = self.rows, [self.header.index(c) for c in cols]
        empty = np.array([[rec[i].strip() == "" for i in idx] for _, rec in self.records], bool) if empty_ok else None
        check_finite(self.path, values, rows, cols, what, empty)
        units = [units] * len(cols) if units is None or isinstance(units, str) else list(units)
        return in_si(self.path, values, rows, cols, units)


BLOCK_BYTES = 4 << 20  # a streamed file is read this many bytes at a time (whole lines)


@dataclass(frozen=True)
class Block:
    """Whole lines of a streamed CSV (blank and '#' lines included): ``nbytes`` bytes from ``offset``,
    the first being line ``first_line``; ``text`` holds them when they are not to be read from the file."""

    first_line: int
    offset: int
    nbytes: int
    text: str | None = None


@dataclass(frozen=True)
class Stream:
    """A CSV read block by block: its header (stripped names), separator, and where the data start."""

    path: str
    header: list[str]
    delim: str
    header_line: int
    offset: int  # bytes: the first byte after the header line
    size: int  # bytes: where the data end (the file's size, rows of separators only at its end left out)
    block_bytes: int = BLOCK_BYTES

    def blocks(self):
        """(block, its last data line as a block of its own or None) for the data after the header, in
        blocks of about ``block_bytes`` bytes of whole lines; only the line breaks are looked at here."""
        line, offset, size = self.header_line + 1, self.offset, self.block_bytes
        with open(self.path, "rb") as fh:
            fh.seek(offset)
            tail = b""
            while True:
                raw = fh.read(min(size, self.size - fh.tell()))
                if not raw and not tail.strip():
                    return
                raw = tail + raw
                cut = raw.rfind(b"\n") + 1 if raw and fh.tell() < self.size else len(raw)
                if cut == 0:
                    tail = raw
                    continue
                block, tail = Block(line, offset, cut), raw[cut:]
                yield block, _last_line(raw[:cut], line)
                line, offset = line + raw.count(b"\n", 0, cut), offset + cut

    def read(self, block: Block) -> bytes:
        if block.text is not None:
            return block.text.encode("utf-8")
        with open(self.path, "rb") as fh:
            fh.seek(block.offset)
            return fh.read(block.nbytes)

    def numbers(self, block: Block, cols, units=None) -> tuple[np.ndarray, np.ndarray]:
        """(row numbers (N,), values in SI (N, len(cols))) of the block's data lines: numpy's C reader when
        the block is plain (no comment, blank or quoted line; the header's field count on every line)
        and every cell a finite number in '.' notation, else cell by cell (decimal commas, quoted
        cells), with an error naming the row and column; ``units``: the file's unit of each column (None: plain
        numbers), checked as ``Table.numbers`` checks them (``in_si``)."""
        rows, values = self._numbers(block, list(cols))
        units = [units] * len(cols) if units is None or isinstance(units, str) else list(units)
        return rows, in_si(self.path, values, rows, list(cols), units)

    def _numbers(self, block: Block, cols: list) -> tuple[np.ndarray, np.ndarray]:
        raw = self.read(block)
        idx = [self.header.index(c) for c in cols]
        n = raw.count(b"\n") + (0 if raw.endswith(b"\n") else 1)
        d = self.delim.encode()
        plain = (b"#" not in raw and b'"' not in raw and b"\n\n" not in raw and not raw.startswith((b"\n", b"\r"))
                 and raw.count(d) == n * (len(self.header) - 1) and (d == b"," or b"," not in raw))  # (decimal
        # commas, thousands separators: cell by cell)
        if plain:
            try:
                out = np.loadtxt(io.BytesIO(raw), delimiter=self.delim, usecols=idx, ndmin=2, comments=None)
                if out.shape == (n, len(idx)) and np.all(np.isfinite(out)):
                    return block.first_line + np.arange(n), out
            except ValueError:
                pass  # the careful reader names the cell
        return self._careful(_decoded(raw), block.first_line, list(cols))

    def _careful(self, text: str, first_line: int, cols: list) -> tuple[np.ndarray, np.ndarray]:
        lines = data_lines(text)
        records = list(zip([first_line + k - 1 for k, _ in lines], csv.reader([s for _, s in lines],
                                                                                  delimiter=self.delim)))
        check_fields(self.path, records, self.header, self.delim)
        rows = np.array([k for k, _ in records], dtype=int)
        return rows, cell_numbers(self.path, records, self.header, cols, self.delim).reshape(len(rows), len(cols))


def _last_line(raw: bytes, first_line: int) -> Block | None:
    """The last data line of whole lines ``raw`` (starting at line ``first_line``) as a block holding its text."""
    end = len(raw)
    while end > 0:
        start = raw.rfind(b"\n", 0, end - 1) + 1
        text = _decoded(raw[start:end])
        if text.strip() and not text.lstrip().startswith("#"):
            return Block(first_line + raw.count(b"\n", 0, start), -1, 0, text.rstrip("\r\n") + "\n")
        end = start
    return None


def open_stream(path: str, block_bytes: int = BLOCK_BYTES) -> Stream:
    """The header of a CSV to stream (the first line that is not blank or a '#' comment; UTF-8 with or
    without a BOM, else Latin-1) and where its data start."""
    head = _read_bytes(path, 1 << 16)
    size = os.path.getsize(path)
    start = 3 if head.startswith(b"\xef\xbb\xbf") else 0
    pos, line = start, 1
    while True:
        end = head.find(b"\n", pos)
        if end < 0:
            raise MeasurementError(f"{path}: no header line in the first 64 kB (a header line, then one row per "
                                   f"target)")
        text = _decoded(head[pos:end])
        if text.strip() and not text.lstrip().startswith("#"):
            break
        pos, line = end + 1, line + 1
    delim = sniff_delimiter(text, path)
    header = [h.strip() for h in next(csv.reader([text], delimiter=delim))]
    return Stream(path, header, delim, line, end + 1, _data_end(path, size, end + 1, delim), block_bytes)


def _data_end(path: str, size: int, start: int, delim: str) -> int:
    """The byte after the last line from ``start`` that holds more than separators, quotes and white space: the rows
    a spreadsheet leaves below its table (',,,,,,') are not data, as ``open_table`` drops them."""
    filler = (delim + ' \t\r\n"').encode()
    end = size
    with open(path, "rb") as fh:
        while end > start:
            lo = max(start, end - (1 << 16))
            fh.seek(lo)
            kept = fh.read(end - lo).rstrip(filler)
            if kept:
                fh.seek(lo + len(kept))
                rest = fh.read(size - lo - len(kept))
                cut = rest.find(b"\n")
                return size if cut < 0 else lo + len(kept) + cut + 1
            end = lo
    return start
