"""A benchmark's table: printed row by row, aligned, and written for the documentation site on request.

With the environment variable ``KINCAL_DOCS_TABLES`` set to a folder, or ``--docs`` on the benchmark's
command line (folder ``docs/generated``), ``close()`` also writes ``<folder>/<name>.md``: a MyST fragment with
the title, the protocol, the command that produced it, the day (UTC) and the machine, then the table. The
explanation page includes it, so no figure on the page is typed by hand.

    table = Table("models", "Error models on the real data", "What was run, how often, units.", ["robot", "mm"])
    table.row("ur5", f"{0.1:.4f}")
    table.close()
"""
from __future__ import annotations

import os
import platform
import shlex
import sys
from datetime import datetime, timezone
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_FOLDER = ROOT / "docs" / "generated"
ENV = "KINCAL_DOCS_TABLES"


def arguments() -> list[str]:
    """The benchmark's command-line arguments without ``--docs`` (which only asks for the fragments)."""
    return [a for a in sys.argv[1:] if a != "--docs"]


def docs_folder() -> Path | None:
    """The folder the fragments go to, or None when none was asked for."""
    if os.environ.get(ENV):
        return Path(os.environ[ENV]).resolve()
    return DEFAULT_FOLDER if "--docs" in sys.argv[1:] else None


def _text(text: str) -> str:
    """Markdown for plain text: ``<`` and ``|`` escaped outside code spans (backticks), where they are literal."""
    parts = text.split("`")
    return "`".join(p if i % 2 else p.replace("<", "\\<").replace("|", "\\|") for i, p in enumerate(parts))


def command() -> str:
    """The command that runs this benchmark with the same arguments, as typed from the project's root."""
    script = Path(sys.argv[0]).name
    return shlex.join(["python", f"benchmarks/{script}", *arguments()])


class Table:
    """A table printed as its rows come and, when asked for, written as a markdown fragment by ``close()``.

    Parameters
    ----------
    name : str
        The fragment's file name without ``.md`` (``docs/generated/<name>.md``).
    title : str
        One line, shown in bold above the table.
    protocol : str
        What was run: the data, how many trials, poses or seeds, the units of the columns, and what is
        left out (timing columns: they depend on the machine's load).
    headers : list of str
        The column headers; a column is as wide as its header or ``widths``.
    widths : list of int, optional
        Minimum widths of the printed columns, characters (the first ones; default: the headers' widths).
    align : str, optional
        One letter per column, ``l`` or ``r``; default: the first column left, the others right.
    left_out : tuple of str, optional
        Headers of columns printed but not written to the fragment (timings: they depend on the load).
    """

    def __init__(self, name: str, title: str, protocol: str, headers: list[str], *,
                 widths: list[int] | None = None, align: str | None = None, left_out: tuple[str, ...] = ()) -> None:
        self.name, self.title, self.protocol, self.headers = name, title, " ".join(protocol.split()), headers
        given = list(widths or [])[:len(headers)]
        self.widths = [max(len(h), w) for h, w in zip(headers, given + [0] * (len(headers) - len(given)))]
        self.align = align or "l" + "r" * (len(headers) - 1)
        if len(self.align) != len(headers) or set(self.align) - set("lr"):
            raise ValueError(f"table {name}: {len(headers)} headers, align {self.align!r}")
        if set(left_out) - set(headers):
            raise ValueError(f"table {name}: no column {sorted(set(left_out) - set(headers))} to leave out")
        self.kept = [i for i, h in enumerate(headers) if h not in left_out]
        self.rows: list[list[str]] = []

    def _line(self, cells: list[str]) -> str:
        return " ".join(c.ljust(w) if a == "l" else c.rjust(w)
                        for c, w, a in zip(cells, self.widths, self.align)).rstrip()

    def row(self, *cells: object) -> None:
        """Print one row (cells already formatted as the benchmark prints them) and keep it for the fragment."""
        if len(cells) != len(self.headers):
            raise ValueError(f"table {self.name}: a row of {len(cells)} cells for {len(self.headers)} columns")
        text = [str(c) for c in cells]
        if not self.rows:  # the header just above the first row, after what the benchmark printed before it
            print(self._line(self.headers), flush=True)
        self.rows.append(text)
        print(self._line(text), flush=True)

    def markdown(self) -> str:
        """The fragment: front matter (an orphan page), title, protocol, provenance and the table."""
        day = datetime.now(timezone.utc).date().isoformat()
        pick = lambda cells: " | ".join(_text(cells[i].strip()) for i in self.kept)  # noqa: E731
        rule = " | ".join("---:" if self.align[i] == "r" else ":---" for i in self.kept)
        lines = ["---", "orphan: true", "---", "",
                 f"<!-- written by benchmarks/{Path(sys.argv[0]).name}: run the command below again, do not edit -->",
                 "", f"**{_text(self.title)}**", "", _text(self.protocol), "",
                 f"Produced by `{command()}` on {day} (UTC), {platform.machine()}, {os.cpu_count()} CPUs.", "",
                 f"| {pick(self.headers)} |", f"| {rule} |"]
        lines += [f"| {pick(r)} |" for r in self.rows]
        return "\n".join(lines) + "\n"

    def close(self) -> Path | None:
        """Write ``<folder>/<name>.md`` when a folder was asked for; return its path (None otherwise)."""
        folder = docs_folder()
        if folder is None:
            return None
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / f"{self.name}.md"
        path.write_text(self.markdown(), encoding="utf-8")
        print(f"(written: {path})", flush=True)
        return path
