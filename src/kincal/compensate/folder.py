"""A controller's programs compensated as a folder: every file of one language under a folder (a KRC backup's
R1, an ABB HOME, a FANUC or Yaskawa backup), each on its own branches (:func:`compensate_branches`), with one
report of every target and item: compensated, refused (line and why), listed (line and why) or the file not
readable at all (an encrypted, binary or broken module: its line and column where there is one); a program of
another language under the folder (by its suffix) is not read and is reported as left out, with its language.

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

import numpy as np

from ..errors import KincalError
from ..io.programs import dialects, read_program
from ..models.robot import Robot
from .branch import Rows, compensate_branches

REPORT = "kincal_report.csv"  # in the written folder: one row per target, listed item or unreadable file
STATUSES = ("compensated", "refused", "kept", "listed", "unreadable", "left out")  # of a report row


@dataclass(frozen=True)
class FileCompensation:
    """One program file: its path relative to the folder, its targets, the new text (None: unchanged or not
    read), its encoding, rows (line, what, status, why) with status compensated, refused, listed or
    unreadable, and why it looks written for another robot ('' when it does not: every target refused,
    :func:`kincal.compensate.program.foreign`)."""

    path: str
    targets: int
    text: str | None
    encoding: str
    rows: tuple[tuple[int, str, str, str], ...]
    foreign: str = ""

    def count(self, status: str) -> int:
        return sum(r[2] == status for r in self.rows)


@dataclass(frozen=True)
class FolderCompensation:
    """Every program file of a folder and what happened to each of its targets.

    Parameters
    ----------
    folder : str
        The folder read.
    dialect : str
        The language of its programs (:func:`kincal.io.dialects`: "krl", "rapid", ...).
    files : tuple of FileCompensation
        Every program file of the language under the folder, sorted by relative path: its targets, its
        new text (None: unchanged or not read) and one row (line, what, status, why) per target or item,
        with status "compensated", "refused", "kept" (a joint target at a singularity, its joints kept),
        "listed" or "unreadable".
    left_out : tuple of (str, str), optional
        The programs of other languages under the folder (relative path, language; :func:`other_programs`), not
        read: reported with status "left out" (default none).

    See Also
    --------
    compensate_folder : Makes it.
    write_folder : Writes it.

    Examples
    --------
    A folder whose only KRL module cannot be read:

    >>> import os
    >>> import tempfile
    >>> import kincal
    >>> from kincal.compensate import compensate_folder
    >>> from kincal.io import ROWS
    >>> nominal = kincal.load_robot("kuka_kr6r900sixx")
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     with open(os.path.join(folder, "broken.src"), "w") as f:
    ...         _ = f.write("DEF broken()\\nLIN {X 1, Y 2\\nEND\\n")
    ...     res = compensate_folder(nominal, nominal, folder, "krl", ROWS["krl"])
    >>> res.count("unreadable"), res.count("compensated")
    (1, 0)
    >>> print(res.report(), end="")
    file,line,what,status,why
    broken.src,2,,unreadable,"line 2, column 5: a '{' that is never closed"
    >>> {k: v for k, v in res.to_dict().items() if k not in ("folder", "files", "left_out_files")}
    {'dialect': 'krl', 'compensated': 0, 'refused': 0, 'kept': 0, 'listed': 0, 'unreadable': 1, 'left out': 0}
    """

    folder: str
    dialect: str
    files: tuple[FileCompensation, ...]
    left_out: tuple[tuple[str, str], ...] = ()

    def count(self, status: str) -> int:
        """The targets and items of every file with this ``status`` ("compensated", "refused", ...; "left out":
        the files of other languages)."""
        return len(self.left_out) if status == "left out" else sum(f.count(status) for f in self.files)

    def left_out_why(self, language: str) -> str:
        """Why a program of ``language`` under the folder was not read."""
        return (f"a program of another language ({language}), not {self.dialect}: not read (compensate it with "
                f"--program {language}); not in the written folder")

    def report(self) -> str:
        """The report as CSV: file, line, what, status, why (a file left out: line 0)."""
        out = _io.StringIO()
        w = csv.writer(out, lineterminator="\n")
        w.writerow(["file", "line", "what", "status", "why"])
        w.writerows([f.path, *row] for f in self.files for row in f.rows)
        w.writerows([path, 0, "", "left out", self.left_out_why(language)] for path, language in self.left_out)
        return out.getvalue()

    def to_dict(self) -> dict:
        """The folder, the counts by status, every file's rows and the files left out as plain JSON values."""
        return {"folder": self.folder, "dialect": self.dialect,
                **{s: self.count(s) for s in STATUSES},
                "left_out_files": [{"path": p, "language": lang} for p, lang in self.left_out],
                "files": [{"path": f.path, "targets": f.targets, "rows": [list(r) for r in f.rows],
                           "foreign": f.foreign or None} for f in self.files]}


def program_files(folder: str, dialect: str) -> list[str]:
    """The files under ``folder`` whose suffix (any case) is the language's, by relative path in name order."""
    suffixes = dialects()[dialect].suffixes
    found = [os.path.relpath(os.path.join(d, f), folder) for d, _, names in os.walk(folder) for f in names
             if os.path.splitext(f)[1].lower() in suffixes]
    return sorted(found)


def other_programs(folder: str, dialect: str) -> list[tuple[str, str]]:
    """The files under ``folder`` whose suffix (any case) is another language's than ``dialect``: (relative path,
    language), by path in name order.

    Parameters
    ----------
    folder : str
        The folder read.
    dialect : str
        The language compensated (:func:`kincal.io.dialects`).

    Returns
    -------
    list of (str, str)
        Each such file's path relative to ``folder`` and its language.

    Examples
    --------
    >>> import os
    >>> import tempfile
    >>> from kincal.compensate.folder import other_programs
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     for name in ("pick.src", "Module1.mod", "HOME.ls", "notes.txt"):
    ...         open(os.path.join(tmp, name), "w").close()
    ...     other_programs(tmp, "krl")
    [('HOME.ls', 'fanuc'), ('Module1.mod', 'rapid')]
    """
    by_suffix = {x: name for name, d in dialects().items() if name != dialect for x in d.suffixes}
    found = [(os.path.relpath(os.path.join(d, f), folder), by_suffix[os.path.splitext(f)[1].lower()])
             for d, _, names in os.walk(folder) for f in names if os.path.splitext(f)[1].lower() in by_suffix]
    return sorted(found)


def compensate_folder(model: Robot, nominal: Robot, folder: str, dialect: str, rows: Rows,
                      frames: Mapping[str, object] | None = None,
                      orientation: Robot | None = None, carry: np.ndarray | None = None) -> FolderCompensation:
    """Compensate every program file of one language under a folder, each on its own branches.

    Each file is read and compensated alone (:func:`compensate_branches`); a file that cannot be read (an
    encrypted, binary or broken module) is reported with its line, never stops the others.

    Parameters
    ----------
    model : Robot
        The calibrated model (where the robot really goes), in the controller's world frame.
    nominal : Robot
        The controller's (nominal) model, same frame.
    folder : str
        The folder read (a controller's backup); every file whose suffix is the language's, at any depth.
    dialect : str
        The language (:func:`kincal.io.dialects`: "krl", "rapid", "fanuc", "inform").
    rows : callable
        ``rows(robot, q) -> bits per row`` for joints q (N, 6) rad, as the language writes them
        (:data:`kincal.io.ROWS`).
    frames : mapping of str to object, optional
        The programs' tool and base frames by name (4x4, m; or taught frames), as for
        :func:`compensate_branches`.
    orientation : Robot, optional
        The model whose flange the corrected joints turn to the targets' rotations (default: the calibrated
        model; give the nominal one after a calibration from positions alone), as for
        :func:`compensate_branches`.
    carry : ndarray, shape (3,), optional
        What of the calibration's move of the declared target point is carried over to the TCP, m, flange frame
        (default zeros), as for :func:`compensate_branches`.

    Returns
    -------
    FolderCompensation
        Every program file (sorted by path) and what happened to each target and item; the programs of other
        languages under the folder, left out.

    Examples
    --------
    A KRC backup with a module to compensate (an axis target, a Cartesian target and a move to the current
    position, which is listed), a broken module and a file of another kind:

    >>> import os
    >>> import tempfile
    >>> import numpy as np
    >>> import kincal
    >>> from kincal.compensate import compensate_folder
    >>> from kincal.io import ROWS
    >>> nominal = kincal.load_robot("kuka_kr6r900sixx")
    >>> real = kincal.perturb(nominal, seed=1)
    >>> texts = {"demo.src": ("DEF demo()\\nPTP {A1 20, A2 -70, A3 80, A4 10, A5 40, A6 5}\\n"
    ...                       "LIN {X 609.5, Y -231.3, Z 728.6, A -29.83, B 49.15, C -20.16, S 2, T 2}\\n"
    ...                       "PTP $POS_ACT\\nEND\\n"),
    ...          "broken.src": "DEF broken()\\nLIN {X 1, Y 2\\nEND\\n",
    ...          "notes.txt": "not a program\\n"}
    >>> frames = {"default tool": np.eye(4), "default base": np.eye(4)}
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     os.makedirs(os.path.join(tmp, "R1", "Program"))
    ...     for name, text in texts.items():
    ...         with open(os.path.join(tmp, "R1", "Program", name), "w") as f:
    ...             _ = f.write(text)
    ...     res = compensate_folder(real, nominal, tmp, "krl", ROWS["krl"], frames)
    >>> [f.path for f in res.files]
    ['R1/Program/broken.src', 'R1/Program/demo.src']
    >>> {status: res.count(status) for status in ("compensated", "refused", "listed", "unreadable")}
    {'compensated': 2, 'refused': 0, 'listed': 1, 'unreadable': 1}
    >>> print(res.report(), end="")
    file,line,what,status,why
    R1/Program/broken.src,2,,unreadable,"line 2, column 5: a '{' that is never closed"
    R1/Program/demo.src,2,PTP,compensated,
    R1/Program/demo.src,3,LIN,compensated,
    R1/Program/demo.src,4,PTP $POS_ACT,listed,"$POS_ACT is the robot's position when the move starts, read at run time"
    """
    return FolderCompensation(folder, dialect, tuple(_one(model, nominal, folder, p, dialect, rows, frames, orientation,
                                                          carry) for p in program_files(folder, dialect)),
                              tuple(other_programs(folder, dialect)))


def _one(model: Robot, nominal: Robot, folder: str, path: str, dialect: str, rows: Rows,
         frames: Mapping[str, object] | None, orientation: Robot | None,
         carry: np.ndarray | None = None) -> FileCompensation:
    full = os.path.join(folder, path)
    try:
        prog = read_program(full, dialect)
    except KincalError as exc:
        line = _line_of(str(exc))
        return FileCompensation(path, 0, None, "utf-8", ((line, "", "unreadable", str(exc).replace(full + ": ", "")),))
    res = compensate_branches(model, nominal, prog, rows, frames, orientation=orientation, carry=carry)
    out = [(t.line, t.variable or t.move, "compensated", "") for k, t in enumerate(prog.targets) if k in res.texts]
    out += [(prog.targets[k].line, prog.targets[k].variable or prog.targets[k].move, "refused", why)
            for k, why in res.refused.items()]
    out += [(line, what, "kept", why) for line, what, why in res.kept]
    out += [(line, what, "listed", why) for line, what, why in res.not_literal]
    text = prog.with_targets(res.texts, res.refused) if res.texts or res.refused else None
    return FileCompensation(path, len(prog.targets), text, prog.encoding, tuple(sorted(out)), res.foreign)


def _line_of(message: str) -> int:
    """The line a reader's error names ('…: line 12, column 3: …'), 0 when none."""
    m = re.search(r": line (\d+)", message)
    return int(m.group(1)) if m else 0


def check_folder_output(folder: str, out: str) -> None:
    """Check that a compensated folder can be written at ``out``, before any work.

    Parameters
    ----------
    folder : str
        The folder read.
    out : str
        Where the compensated folder is to be written.

    Raises
    ------
    ValueError
        When ``out`` exists, lies inside ``folder`` (or is the folder itself) or its parent folder does not
        exist.

    Examples
    --------
    >>> import os
    >>> import tempfile
    >>> from kincal.compensate import check_folder_output
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     backup = os.path.join(tmp, "KRC")
    ...     os.mkdir(backup)
    ...     check_folder_output(backup, os.path.join(tmp, "KRC_cal"))  # fine: nothing said
    ...     check_folder_output(backup, os.path.join(backup, "new"))
    Traceback (most recent call last):
    ...
    ValueError: /.../KRC/new: inside the folder read (/.../KRC); write the compensated folder elsewhere
    """
    src, dst = os.path.realpath(folder), os.path.realpath(out)
    if os.path.exists(out):
        raise ValueError(f"{out}: exists; kincal writes a compensated folder only where there is none (never over one)")
    if dst == src or dst.startswith(src + os.sep):
        raise ValueError(f"{out}: inside the folder read ({folder}); write the compensated folder elsewhere")
    if not os.path.isdir(os.path.dirname(dst)):
        raise ValueError(f"{out}: the folder {os.path.dirname(dst)} does not exist; create it or choose another output")


def write_folder(result: FolderCompensation, out: str) -> None:
    """Write a compensated folder: every program file, compensated or copied as it was, and the report.

    The folder is built beside ``out`` and renamed into place only when complete, so there is never half of
    one; the files keep their relative paths and encodings, and the report is ``kincal_report.csv``
    (:meth:`FolderCompensation.report`).

    Parameters
    ----------
    result : FolderCompensation
        The compensated folder (:func:`compensate_folder`).
    out : str
        Where to write it: it must not exist, nor lie inside the folder read (:func:`check_folder_output`).

    Raises
    ------
    ValueError
        When ``out`` cannot be written (:func:`check_folder_output`).

    Examples
    --------
    >>> import os
    >>> import tempfile
    >>> import kincal
    >>> from kincal.compensate import compensate_folder, write_folder
    >>> from kincal.io import ROWS
    >>> nominal = kincal.load_robot("kuka_kr6r900sixx")
    >>> real = kincal.perturb(nominal, seed=1)
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     backup = os.path.join(tmp, "KRC")
    ...     os.makedirs(os.path.join(backup, "R1"))
    ...     with open(os.path.join(backup, "R1", "home.src"), "w") as f:
    ...         _ = f.write("DEF home()\\nPTP {A1 20, A2 -70, A3 80, A4 10, A5 40, A6 5}\\nEND\\n")
    ...     res = compensate_folder(real, nominal, backup, "krl", ROWS["krl"])
    ...     write_folder(res, os.path.join(tmp, "KRC_cal"))
    ...     print(sorted(os.listdir(os.path.join(tmp, "KRC_cal"))))
    ...     with open(os.path.join(tmp, "KRC_cal", "R1", "home.src")) as f:
    ...         print(f.read(), end="")
    ['R1', 'kincal_report.csv']
    DEF home()
    PTP {A1 19.8158..., A2 -70.0937..., A3 80.1103..., A4 10.2834..., A5 40.0511..., A6 4.6542...}
    END
    """
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
