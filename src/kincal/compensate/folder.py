"""A controller's programs compensated as a folder: every file of one language under a folder (a KRC backup's
R1, an ABB HOME, a FANUC or Yaskawa backup), each on its own branches (:func:`compensate_branches`), with one
report of every target and item: compensated, refused (line and why), listed (line and why) or the file not
readable at all (an encrypted, binary or broken module: its line and column where there is one).

The written folder holds every program file of the language, compensated or as it was, at the same relative
paths: it is built beside the output path and renamed into place only when complete, so there is never half of
one; an existing output is never replaced, and it may not lie inside the folder read.
"""
from __future__ import annotations

import csv
import io as _io
import os
import re
import shutil
import tempfile
from dataclasses import dataclass
from typing import Mapping

from ..errors import KincalError
from ..io.programs import dialects, read_program
from ..models.robot import Robot
from .branch import Rows, compensate_branches

REPORT = "kincal_report.csv"  # in the written folder: one row per target, listed item or unreadable file


@dataclass(frozen=True)
class FileCompensation:
    """One program file: its path relative to the folder, its targets, the new text (None: unchanged or not
    read), its encoding, and rows (line, what, status, why) with status compensated, refused, listed or
    unreadable."""

    path: str
    targets: int
    text: str | None
    encoding: str
    rows: tuple[tuple[int, str, str, str], ...]

    def count(self, status: str) -> int:
        return sum(r[2] == status for r in self.rows)


@dataclass(frozen=True)
class FolderCompensation:
    """Every program file of the folder (sorted by path) and what happened to each target."""

    folder: str
    dialect: str
    files: tuple[FileCompensation, ...]

    def count(self, status: str) -> int:
        return sum(f.count(status) for f in self.files)

    def report(self) -> str:
        """The report as CSV: file, line, what, status, why."""
        out = _io.StringIO()
        w = csv.writer(out, lineterminator="\n")
        w.writerow(["file", "line", "what", "status", "why"])
        w.writerows([f.path, *row] for f in self.files for row in f.rows)
        return out.getvalue()

    def to_dict(self) -> dict:
        return {"folder": self.folder, "dialect": self.dialect,
                **{s: self.count(s) for s in ("compensated", "refused", "listed", "unreadable")},
                "files": [{"path": f.path, "targets": f.targets, "rows": [list(r) for r in f.rows]}
                          for f in self.files]}


def program_files(folder: str, dialect: str) -> list[str]:
    """The files under ``folder`` whose suffix (any case) is the language's, by relative path in name order."""
    suffixes = dialects()[dialect].suffixes
    found = [os.path.relpath(os.path.join(d, f), folder) for d, _, names in os.walk(folder) for f in names
             if os.path.splitext(f)[1].lower() in suffixes]
    return sorted(found)


def compensate_folder(model: Robot, nominal: Robot, folder: str, dialect: str, rows: Rows,
                      frames: Mapping[str, object] | None = None) -> FolderCompensation:
    """Every program file of ``dialect`` under ``folder``, compensated (module docstring)."""
    return FolderCompensation(folder, dialect, tuple(_one(model, nominal, folder, p, dialect, rows, frames)
                                                     for p in program_files(folder, dialect)))


def _one(model: Robot, nominal: Robot, folder: str, path: str, dialect: str, rows: Rows,
         frames: Mapping[str, object] | None) -> FileCompensation:
    full = os.path.join(folder, path)
    try:
        prog = read_program(full, dialect)
    except KincalError as exc:
        line = _line_of(str(exc))
        return FileCompensation(path, 0, None, "utf-8", ((line, "", "unreadable", str(exc).replace(full + ": ", "")),))
    res = compensate_branches(model, nominal, prog, rows, frames)
    out = [(t.line, t.variable or t.move, "compensated", "") for k, t in enumerate(prog.targets) if k in res.texts]
    out += [(prog.targets[k].line, prog.targets[k].variable or prog.targets[k].move, "refused", why)
            for k, why in res.refused.items()]
    out += [(line, what, "listed", why) for line, what, why in res.not_literal]
    text = prog.with_targets(res.texts, res.refused) if res.texts or res.refused else None
    return FileCompensation(path, len(prog.targets), text, prog.encoding, tuple(sorted(out)))


def _line_of(message: str) -> int:
    """The line a reader's error names ('…: line 12, column 3: …'), 0 when none."""
    m = re.search(r": line (\d+)", message)
    return int(m.group(1)) if m else 0


def check_folder_output(folder: str, out: str) -> None:
    """ValueError unless a compensated folder can be written at ``out``: it does not exist, is not inside
    ``folder`` (nor the folder itself) and its parent folder does."""
    src, dst = os.path.realpath(folder), os.path.realpath(out)
    if os.path.exists(out):
        raise ValueError(f"{out}: exists; kincal writes a compensated folder only where there is none (never over one)")
    if dst == src or dst.startswith(src + os.sep):
        raise ValueError(f"{out}: inside the folder read ({folder}); write the compensated folder elsewhere")
    if not os.path.isdir(os.path.dirname(dst)):
        raise ValueError(f"{out}: the folder {os.path.dirname(dst)} does not exist; create it or choose another output")


def write_folder(result: FolderCompensation, out: str) -> None:
    """The compensated folder at ``out`` (which must not exist, nor lie inside the folder read): every program
    file, compensated or copied as it was, and the report; built beside ``out`` and renamed into place."""
    check_folder_output(result.folder, out)
    dst = os.path.realpath(out)
    work = tempfile.mkdtemp(prefix=".kincal-", dir=os.path.dirname(dst))
    try:
        for f in result.files:
            target = os.path.join(work, f.path)
            os.makedirs(os.path.dirname(target), exist_ok=True)
            if f.text is None:
                shutil.copyfile(os.path.join(result.folder, f.path), target)
            else:
                with open(target, "w", encoding=f.encoding, newline="") as fh:
                    fh.write(f.text)
        with open(os.path.join(work, REPORT), "w", encoding="utf-8", newline="") as fh:
            fh.write(result.report())
        os.rename(work, dst)
    except BaseException:
        shutil.rmtree(work, ignore_errors=True)
        raise
