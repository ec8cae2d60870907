"""Robot programs: the move targets in a program's text, and the text with new targets put back.

One module per vendor language — a :class:`Dialect` — finds the moves and their literal targets:
``program_ur.py`` (Universal Robots' URScript), ``program_krl.py`` (KUKA KRL), ``program_rapid.py``
(ABB RAPID), ``program_fanuc.py`` (FANUC TP, ASCII ``.ls``) and ``program_inform.py`` (Yaskawa
INFORM ``.JBI``). Everything else — comments, declarations, speeds, blends, other commands, spacing,
line endings, a byte-order mark — stays byte for byte, because only the spans of the literal targets
(URScript) or of their numbers (the other languages: each written again in its own style,
:mod:`kincal._numstyle`) are replaced. A move whose target is not a literal (a variable filled at
run time, an offset computed by the controller) is listed with its line and why, never touched.

A target's values are in SI and one convention for every language: a pose is x, y, z (m) and a
rotation vector (rad) of the TCP in the program's frame; joints are rad (revolute) or m. Its
``config`` keeps the branch as written (KRL S and T, RAPID cf1/cf4/cf6/cfx, FANUC ``CONFIG``,
INFORM ``RCONF``) and its ``frames`` the tool and base (work object, user frame) the program names.
"""
from __future__ import annotations

import dataclasses
import functools
import os
import unicodedata
from dataclasses import dataclass, field
from typing import Callable, Mapping, Sequence

import numpy as np

from .._atomic import write_text_atomic
from .._collector import paused_collector
from .._numstyle import restyle_all
from ..errors import MeasurementError
from ..models.transforms import zyx_nearest


@dataclass(frozen=True)
class Target:
    """One literal target of a robot program: where it is in the text, the move, and its values.

    Parameters
    ----------
    start, end : int
        The span of the literal in the program's text (character positions; for a move to a variable, the
        span of the variable's literal).
    line : int
        The line of the literal, from 1.
    move : str
        The move as the program names it ("movel", "PTP", …; for a variable no move of the file goes to, its
        type).
    kind : str
        "pose", "joints" or "pulses".
    values : ndarray, shape (6,) or (n,)
        A pose: x, y, z (m) and a rotation vector (rad) of the TCP in the program's frame (``kind`` "pose");
        joint values (rad, m for a prismatic joint; "joints"); or a Yaskawa PULSE position's encoder counts
        as written ("pulses": joints once the robot's pulses per degree are known).
    at : int, optional
        Where the move is in the text, a character position (default -1: not given).
    variable : str, optional
        The variable the move goes to (default '': a literal in the move).
    fields : tuple of (int, int), optional
        In the vendor languages, the spans of the numbers that carry ``values``, in the language's order
        and units: what a rewrite replaces (default (): URScript, whose whole literal is replaced).
    config : tuple, optional
        The branch as written: KRL (S, T); RAPID (cf1, cf4, cf6, cfx); FANUC ('N U T', turn1, turn2,
        turn3); INFORM's RCONF digits (default (): none written).
    frames : tuple of (str, str), optional
        The (tool, base) the target is in, as the program names them ('' for none named: the controller's
        default; default ('', '')).

    See Also
    --------
    Program : The text and its targets.

    Examples
    --------
    A KUKA KRL program: the numbers as written, in mm and deg, and the values in SI:

    >>> import os, tempfile
    >>> import numpy as np
    >>> from kincal.io import read_program
    >>> text = ("DEF prog()\\r\\n"
    ...         "  $BASE = BASE_DATA[1]\\r\\n"
    ...         "  PTP {A1 0, A2 -90, A3 90, A4 0, A5 45, A6 0}\\r\\n"
    ...         "  LIN {X 500.0, Y 0.0, Z 400.0, A 0.0, B 90.0, C 0.0, S 2, T 2} ; approach\\r\\n"
    ...         "END\\r\\n")
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = os.path.join(tmp, "prog.src")
    ...     with open(path, "w", newline="") as f:
    ...         _ = f.write(text)
    ...     program = read_program(path, "krl")
    >>> ptp, lin = program.targets
    >>> ptp.move, ptp.kind, ptp.line, np.round(np.degrees(ptp.values), 6).tolist()
    ('PTP', 'joints', 3, [0.0, -90.0, 90.0, 0.0, 45.0, 0.0])
    >>> lin.move, lin.kind, lin.config, lin.frames
    ('LIN', 'pose', (2, 2), ('', 'BASE_DATA[1]'))
    >>> [text[a:b] for a, b in lin.fields]
    ['500.0', '0.0', '400.0', '0.0', '90.0', '0.0']
    >>> np.round(lin.values, 6).tolist()
    [0.5, 0.0, 0.4, 0.0, 1.570796, 0.0]
    """

    start: int
    end: int
    line: int
    move: str
    kind: str
    values: np.ndarray
    at: int = -1
    variable: str = ""
    fields: tuple[tuple[int, int], ...] = ()
    config: tuple = ()
    frames: tuple[str, str] = ("", "")


@dataclass(frozen=True)
class Program:
    """A robot program's text and its literal targets, as :func:`read_program` finds them.

    Parameters
    ----------
    source : str
        Where the text comes from (a file's path), named in messages.
    text : str
        The program's text, byte for byte as decoded (line endings and a byte-order mark kept).
    targets : tuple of Target
        The literal targets, in the order of the moves.
    not_literal : tuple of (int, str, str), optional
        What is listed, never touched: (line, what: the move or item as written, why: the reason a user
        reads) (default ()).
    encoding : str, optional
        The text's encoding, "utf-8" or "latin-1", in which it is written again (default "utf-8").
    tcps : tuple of (int, ndarray or None), optional
        The TCPs the program sets: (position in the text, the pose (6,) in m and rad, or None when not a
        literal) (default ()).
    in_force : tuple of (int, object), optional
        What the program's flow (:mod:`kincal.io.flow`) leaves in force at a target's moves: (the target's
        ``start``, URScript's TCP there — the pose (6,), None for a TCP set from a non-literal, () for none set —
        or, in any language, a str: why no one TCP, tool or base is known there) (default (): () for every
        target).
    comment : str, optional
        The language's comment mark ('' for a language that allows none beside a target) (default "#").
    dialect : str, optional
        The dialect's name, one of :data:`DIALECT_NAMES` (default "ur").

    See Also
    --------
    read_program : A program read from its file.
    write_program : The program written with new targets.

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np
    >>> from kincal.io import read_program
    >>> text = ("def prog():\\n"
    ...         "  set_tcp(p[0, 0, 0.15, 0, 0, 0])\\n"
    ...         "  movel(p[0.4, -0.1, 0.3, 0, 1.5708, 0])  # approach\\n"
    ...         "end\\n")
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = os.path.join(tmp, "prog.script")
    ...     with open(path, "w") as f:
    ...         _ = f.write(text)
    ...     program = read_program(path)
    >>> program.dialect, program.encoding, program.comment, len(program.targets)
    ('ur', 'utf-8', '#', 1)
    >>> program.in_force_of(program.targets[0]).tolist()
    [0.0, 0.0, 0.15, 0.0, 0.0, 0.0]

    The target written again 1 mm higher, every other byte as it was:

    >>> new = program.with_values({0: program.targets[0].values + [0.0, 0.0, 1e-3, 0.0, 0.0, 0.0]})
    >>> print(new.splitlines()[2])
      movel(p[0.4, -0.1, 0.301, 0, 1.5708, 0])  # approach
    """

    source: str
    text: str
    targets: tuple[Target, ...]
    not_literal: tuple[tuple[int, str, str], ...] = field(default=())
    encoding: str = "utf-8"
    tcps: tuple = ()
    comment: str = "#"
    dialect: str = "ur"
    in_force: tuple = ()

    def in_force_of(self, target: Target):
        """What is in force at ``target``'s moves by the program's flow (``in_force``): URScript's TCP pose (6,),
        None if set from a non-literal, () when none is set (or in another language); a str: why no one TCP, tool or
        base is known there."""
        return self._tcp_by_start.get(target.start, ())

    @functools.cached_property
    def _tcp_by_start(self) -> dict:
        return dict(self.in_force)

    def with_targets(self, texts: dict[int, str], marks: dict[int, str] | None = None) -> str:
        """The text with target k's span replaced by ``texts[k]`` (the others as they are), and a
        comment ``marks[k]`` at the end of the line of each target k that is left as it is (in ASCII:
        :func:`ascii_text`)."""
        edits = sorted([(t.start, t.end, texts[k]) for k, t in enumerate(self.targets) if k in texts]
                       + _marks(self, marks or {}))
        out, at = [], 0
        for a, b, new in edits:
            out += [self.text[at:a], new]
            at = b
        return "".join(out) + self.text[at:]

    def with_values(self, values: dict[int, np.ndarray], marks: dict[int, str] | None = None) -> str:
        """The text with target k written again from ``values[k]`` (SI, the target's kind) by the
        program's dialect — in the vendor languages number by number, each in the style it had — and
        every other byte as it is; ``marks`` as in :meth:`with_targets`."""
        ks = list(values)
        new = dialects()[self.dialect].write(self.text, [self.targets[k] for k in ks], [values[k] for k in ks])
        return self.with_targets(dict(zip(ks, new)), marks)


def no_frames(program: Program) -> dict[str, np.ndarray]:
    """A language whose programs declare no frame values of their own: none."""
    return {}


def used_otherwise(how: str) -> str:
    """Why a point variable given one literal is listed, not compensated: the module uses it otherwise than as a
    place a move goes to (``how``: where and how, or that no move goes to it), so a new value would change what
    the program does with it (a comparison, a limit); a data target is compensated only when every use of it is a
    move's (KRL and RAPID alike).

    Parameters
    ----------
    how : str
        Where and how the module uses it, in words.

    Returns
    -------
    str
        The reason, as listed.

    Examples
    --------
    >>> from kincal.io.programs import used_otherwise
    >>> print(used_otherwise("compared in line 92 (IF jtPos.robax<>pRobHome.robax THEN)"))
    compared in line 92 (IF jtPos.robax<>pRobHome.robax THEN): a value the module uses otherwise (a limit, a
    comparison, a speed, a record), not only a move target
    """
    return (f"{how}: a value the module uses otherwise (a limit, a comparison, a speed, a record), not only a move "
            f"target")


def as_given(frames: Mapping[str, object]) -> dict[str, object]:
    """A language with one spelling of each frame's name: the frames as they are."""
    return dict(frames)


def nothing_beside(path: str) -> tuple[str, ...]:
    """A language whose reader reads no file but the program's own: none."""
    return ()


@dataclass(frozen=True)
class Dialect:
    """A vendor language: how its programs are read and written again.

    Parameters
    ----------
    name : str
        The dialect's name, one of :data:`DIALECT_NAMES`.
    suffixes : tuple of str
        The file suffixes it is read from, lower case (".script", …).
    comment : str
        Its comment mark ('' for a language that allows none beside a target).
    parse : callable
        Its reader, ``parse(source, text) -> Program``.
    write : callable
        Its writer, ``write(text, targets, values) -> texts``: the new texts of the targets' spans for new SI
        values, all at once (see :func:`write_fields`).
    frames : callable, optional
        ``frames(program)``: the tool and base frames a program declares (or its controller holds beside it)
        with their values, by the names its targets use (4x4, m; or a str: why a frame it names cannot be
        known) (default: none).
    beside : callable, optional
        ``beside(path) -> paths``: the other files that reading the program at ``path`` and its frames reads (a
        KRL ``.dat``'s module ``.src``, the controller's ``$config.dat`` and ``$machine.dat``): an output must
        replace none of them (default: none).
    spellings : callable, optional
        ``spellings(frames) -> frames``: frames by name (a frames file's, or what ``frames`` gives) with each also
        under the language's other names of the same frame, where that mapping names none of them (KRL:
        ``TOOL_DATA[1]`` and ``TOOL_NO 1``; default: as given).
    step : tuple of float, optional
        The finest step the controller keeps of a position's length and angle fields, (m, rad): its writer
        writes rewritten numbers to it, as the controller's own files do, and the end-to-end check of a
        written target allows the miss that rounding to it makes (default (0, 0): as finely as a value needs).

    See Also
    --------
    dialects : The dialects kincal reads, by name.

    Examples
    --------
    >>> from kincal.io import dialects
    >>> krl = dialects()["krl"]
    >>> krl.name, krl.suffixes, krl.comment
    ('krl', ('.src', '.dat', '.sub'), ';')
    """

    name: str
    suffixes: tuple[str, ...]
    comment: str
    parse: Callable[[str, str], Program]
    write: Callable[[str, Sequence[Target], Sequence[np.ndarray]], list[str]]
    frames: Callable[[Program], Mapping[str, np.ndarray | str]] = no_frames
    step: tuple[float, float] = (0.0, 0.0)
    beside: Callable[[str], tuple[str, ...]] = nothing_beside
    spellings: Callable[[Mapping[str, object]], dict[str, object]] = as_given


Numbers = Callable[[str, Sequence[Target], np.ndarray], tuple[np.ndarray, np.ndarray]]


def write_fields(text: str, targets: Sequence[Target], values: Sequence[np.ndarray], numbers: Numbers) -> list[str]:
    """The new texts of the targets' spans for new SI ``values``, field by field: the targets are taken in
    groups of one kind and one number of values, ``numbers(text, group, values (G, V))`` gives each group's
    field numbers (G, F) in the fields' units and their resolution (G, F) or (F,), and each number is written
    in its old style with at least the decimals that carry it to its resolution
    (:func:`kincal._numstyle.restyle_all`), in ASCII (:func:`ascii_text`); every other byte of a span as it is.
    All at once per group (a 10^4-target program is converted in one step, not target by target)."""
    out = [""] * len(targets)
    groups: dict[tuple[str, int], list[int]] = {}
    for k, (t, v) in enumerate(zip(targets, values)):
        groups.setdefault((t.kind, np.size(v)), []).append(k)
    for ks in groups.values():
        group = [targets[k] for k in ks]
        found, resolution = numbers(text, group, np.array([values[k] for k in ks], dtype=float))
        olds = [text[a:b] for t in group for a, b in t.fields]
        new = iter(restyle_all(olds, found.ravel(), np.broadcast_to(resolution, found.shape).ravel()))
        for k, t in zip(ks, group):
            out[k] = _spliced(text, t, [ascii_text(next(new)) for _ in t.fields])
    return out


def old_numbers(text: str, targets: Sequence[Target], fields: slice = slice(None)) -> np.ndarray:
    """The numbers (G, F) the targets' ``fields`` hold in ``text`` now (each target the same count)."""
    return np.array([[float(text[a:b]) for a, b in t.fields[fields]] for t in targets], dtype=float).reshape(
        len(targets), -1)


def controller_angles(R: np.ndarray, old: np.ndarray, middle: float = 180.0) -> np.ndarray:
    """The Euler angles a writer puts where a program wrote ``old``: fixed axes x, y, z (R = Rz·Ry·Rx), in the
    controller's range.

    Of R's equivalent triples, the one nearest the old numbers (:func:`kincal.models.transforms.zyx_nearest`);
    then each angle in [-180°, 180°] and the middle one (about y) in [-``middle``, ``middle``], the same rotation:
    an angle past 180° becomes one past -180°, and a middle angle ry past ±``middle`` (90°: KUKA's B) becomes
    ±180° - ry with the other two turned by 180°. A row whose rotation is the old one keeps the old numbers as
    written, in or out of range (a program written again unchanged is the same text).

    Parameters
    ----------
    R : ndarray, shape (G, 3, 3)
        The new rotations.
    old : ndarray, shape (G, 3)
        The numbers the program wrote, deg: (rz, ry, rx).
    middle : float, optional
        The largest middle angle the controller takes, deg (default 180: no limit beyond the others').

    Returns
    -------
    ndarray, shape (G, 3)
        (rz, ry, rx) in deg with Rz(rz)·Ry(ry)·Rx(rx) = R.

    Examples
    --------
    A rotation 0.1° past the old 179.95° about x is written 0.05° past -180°, not as 180.05°:

    >>> import numpy as np
    >>> from scipy.spatial.transform import Rotation
    >>> from kincal.io.programs import controller_angles
    >>> R = Rotation.from_euler("ZYX", [10.0, 20.0, 180.05], degrees=True).as_matrix()[None]
    >>> np.round(controller_angles(R, np.array([[10.0, 20.0, 179.95]])), 9).tolist()
    [[10.0, 20.0, -179.95]]

    With B in [-90°, 90°] (KUKA), a middle angle of 95° is written as the same rotation with 85°:

    >>> R = Rotation.from_euler("ZYX", [10.0, 95.0, 20.0], degrees=True).as_matrix()[None]
    >>> np.round(controller_angles(R, np.array([[10.0, 94.9, 20.0]]), middle=90.0), 9).tolist()
    [[-170.0, 85.0, -160.0]]
    """
    rad = np.radians(old)
    near = zyx_nearest(R, rad)
    angles = _wrapped(np.degrees(near))
    flip = np.abs(angles[:, 1]) > middle
    angles[flip] = _wrapped(angles[flip] * [1.0, -1.0, 1.0] + [180.0, 180.0, 180.0])
    return np.where((near == rad).all(axis=1)[:, None], old, angles)


def _wrapped(degrees: np.ndarray) -> np.ndarray:
    """Each angle (deg) outside [-180, 180] turned by whole turns into it (one in it as it is)."""
    return np.where(np.abs(degrees) > 180.0, degrees - 360.0 * np.round(degrees / 360.0), degrees)


def _spliced(text: str, target: Target, numbers: list[str]) -> str:
    """The target's span of ``text`` with its fields' texts replaced by ``numbers`` (in the fields' order)."""
    pieces, at = [], target.start
    for (a, b), new in sorted(zip(target.fields, numbers)):  # the span left to right
        pieces += [text[at:a], new]
        at = b
    return "".join(pieces) + text[at:target.end]


DIALECT_NAMES = ("ur", "krl", "rapid", "fanuc", "inform")  # what dialects() holds (known without loading them)


def dialects() -> dict[str, Dialect]:
    """The vendor languages kincal reads, by name (the modules load when first asked).

    Returns
    -------
    dict of str to Dialect
        Each dialect by its name, in the order of :data:`DIALECT_NAMES`.

    Examples
    --------
    >>> from kincal.io import dialects
    >>> {name: d.suffixes for name, d in dialects().items()}
    {'ur': ('.script', '.urscript'), 'krl': ('.src', '.dat', '.sub'), 'rapid': ('.mod', '.modx', '.prg', '.sys'),
     'fanuc': ('.ls',), 'inform': ('.jbi',)}
    """
    from . import program_fanuc, program_inform, program_krl, program_rapid, program_ur

    return {d.name: d for d in (program_ur.DIALECT, program_krl.DIALECT, program_rapid.DIALECT, program_fanuc.DIALECT,
                                program_inform.DIALECT)}


ASCII_FOR = {"°": " deg", "…": "...", "—": "-", "–": "-", "−": "-", "×": "x", "·": "*", "±": "+/-", "∓": "-/+",
             "≤": "<=", "≥": ">=", "≠": "!=", "≈": "~", "→": "->", "←": "<-", "‖": "|", "√": "sqrt", "∂": "d",
             "µ": "u", "‘": "'", "’": "'", "′": "'", "“": '"', "”": '"', "″": '"', "½": "1/2", "§": "S"}
# what kincal writes into a program in place of a character outside ASCII (Greek letters by name: σ -> sigma)


def ascii_text(text: str) -> str:
    """Text kincal inserts into a program (a number, a comment beside a target), in ASCII only.

    Controllers read their programs as ASCII or a code page (KRL ``.src``/``.dat``, RAPID ``.mod``, FANUC
    ``.ls``, INFORM ``.JBI``) and may refuse a file with other bytes, and a Latin-1 file cannot hold σ at
    all; the file keeps its own encoding and every byte kincal does not insert. Each character outside ASCII
    is written as :data:`ASCII_FOR` says ("°" -> " deg", "…" -> "...", "—" -> "-", "×" -> "x"), a Greek
    letter by its name ("σ" -> "sigma"), a letter with an accent without it ("é" -> "e"), anything else as
    "?"; a line break or other control character becomes a blank (a comment stays on its line).

    Parameters
    ----------
    text : str
        The text to insert.

    Returns
    -------
    str
        The text in ASCII, the same where it was.

    Examples
    --------
    >>> from kincal.io.programs import ascii_text
    >>> ascii_text("a3 moves from +0.091° to -0.876° (limits -170…170°), 2σ — 3×")
    'a3 moves from +0.091 deg to -0.876 deg (limits -170...170 deg), 2sigma - 3x'
    """
    if text.isascii() and text.isprintable():
        return text
    return "".join(_ascii_char(c) for c in text)


def _ascii_char(c: str) -> str:
    """One character of :func:`ascii_text`."""
    if c.isascii():
        return c if c.isprintable() else " "
    if c in ASCII_FOR:
        return ASCII_FOR[c]
    name = unicodedata.name(c, "")
    if name.startswith("GREEK ") and " LETTER " in name and len(name.split()) == 4:
        letter = name.split()[-1].lower()
        return letter.capitalize() if "CAPITAL" in name else letter
    plain = "".join(p for p in unicodedata.normalize("NFKD", c) if p.isascii() and p.isprintable())
    return plain or ("" if unicodedata.category(c) == "Mn" else " " if c.isspace() else "?")


def _marks(program: Program, marks: dict[int, str]) -> list[tuple[int, int, str]]:
    """Insertions (at the end of each marked target's line, before its line ending) of one comment
    per line with the reasons of every marked target on it."""
    by_end: dict[int, list[str]] = {}
    if not program.comment:  # a language with no comment at the end of a target's line (FANUC /POS, INFORM //POS)
        return []
    for k, why in marks.items():
        t = program.targets[k]
        end = program.text.find("\n", t.end)
        end = len(program.text) if end < 0 else end - (program.text[end - 1:end] == "\r")
        by_end.setdefault(end, []).append(why)
    return [(e, e, ascii_text(f"  {program.comment} kincal: not compensated: {'; '.join(w)}"))
            for e, w in by_end.items()]


def dialect_of(path: str) -> str:
    """The dialect of a robot program, by its file's suffix (any case).

    Parameters
    ----------
    path : str
        The program's path.

    Returns
    -------
    str
        The name of the dialect whose suffixes hold the file's.

    Raises
    ------
    ValueError
        When no dialect reads that suffix, naming every suffix kincal reads.

    Examples
    --------
    >>> from kincal.io import dialect_of
    >>> dialect_of("cell/PICK.SRC"), dialect_of("pick.script"), dialect_of("Main.mod")
    ('krl', 'ur', 'rapid')
    """
    suffix = os.path.splitext(str(path))[1].lower()
    found = [d.name for d in dialects().values() if suffix in d.suffixes]
    if not found:
        known = ", ".join(f"{s} ({d.name})" for d in dialects().values() for s in d.suffixes)
        raise ValueError(f"{path}: a robot program's suffix says its language; kincal reads {known}")
    return found[0]


@paused_collector
def read_program(path: str, dialect: str = "ur") -> Program:
    """Read a robot program and find its literal targets.

    The file is read byte for byte: UTF-8 (a byte-order mark kept), else Latin-1; line endings as they are.
    The dialect finds the moves and their literal targets; a move whose target is not a literal is listed
    in ``not_literal`` with its line and why.

    Parameters
    ----------
    path : str
        The program's file.
    dialect : str, optional
        The vendor language, one of :data:`DIALECT_NAMES` (:func:`dialects`; default "ur";
        :func:`dialect_of` names it from the file's suffix).

    Returns
    -------
    Program
        The text, its targets (SI values) and what is listed, with the file's encoding, the dialect's
        comment mark and name.

    Raises
    ------
    ValueError
        When the dialect is unknown.
    MeasurementError
        When the file cannot be read, holds binary data (an encrypted or compiled module), or its text breaks
        the language's rules (named with the line).

    See Also
    --------
    write_program : The program written again with new targets.

    Examples
    --------
    >>> import os, tempfile
    >>> from kincal.io import read_program
    >>> text = ("def prog():\\n"
    ...         "  movej([0.1, -1.5, 1.6, -1.7, -1.6, 0.2], a=1.4, v=1.05)\\n"
    ...         "  movel(p[0.4, -0.1, 0.3, 0, 1.5708, 0], a=1.2, v=0.25)\\n"
    ...         "  movel(pose_add(get_actual_tcp_pose(), p[0, 0, 0.01, 0, 0, 0]))\\n"
    ...         "end\\n")
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = os.path.join(tmp, "prog.script")
    ...     with open(path, "w") as f:
    ...         _ = f.write(text)
    ...     program = read_program(path, "ur")
    >>> [(t.move, t.kind, t.line, t.values.tolist()) for t in program.targets]
    [('movej', 'joints', 2, [0.1, -1.5, 1.6, -1.7, -1.6, 0.2]),
     ('movel', 'pose', 3, [0.4, -0.1, 0.3, 0.0, 1.5708, 0.0])]
    >>> line, what, why = program.not_literal[0]
    >>> line, what
    (4, 'movel(pose_add(get_actual_tcp_pose(), p[0, 0, 0.01, 0, 0, 0]))')
    """
    known = dialects()
    if dialect not in known:
        raise ValueError(f"robot program dialect '{dialect}': kincal reads {', '.join(known)}")
    try:
        raw = open(path, "rb").read()
    except OSError as exc:
        raise MeasurementError(f"{path}: cannot read the program ({exc.strerror})") from None
    if b"\x00" in raw:
        raise MeasurementError(f"{path}: holds binary data (an encrypted or compiled module?), not a program's text")
    try:
        text, encoding = raw.decode("utf-8"), "utf-8"
    except UnicodeDecodeError:
        text, encoding = raw.decode("latin-1"), "latin-1"
    found = known[dialect].parse(path, text)
    return dataclasses.replace(found, encoding=encoding, dialect=dialect, comment=known[dialect].comment)


def write_program(path: str, program: Program, texts: dict[int, str], marks: dict[int, str] | None = None) -> None:
    """Write a program with the given targets replaced and the marked ones commented (atomically).

    Every other byte is as it was (:meth:`Program.with_targets`); the text is written in the program's own
    encoding.

    Parameters
    ----------
    path : str
        The file to write.
    program : Program
        The program as read.
    texts : dict of int to str
        The new text of target k's span, by k (the index in ``program.targets``); the others stay as they are.
    marks : dict of int to str, optional
        A reason for target k, written as a comment (``kincal: not compensated: …``, in ASCII: :func:`ascii_text`)
        at the end of its line (default None: none; a language without comments beside a target gets none).

    See Also
    --------
    Program.with_values : The text with targets written again from new SI values, in the language's own style.

    Examples
    --------
    >>> import os, tempfile
    >>> from kincal.io import read_program, write_program
    >>> text = ("def prog():\\n"
    ...         "  movej([0.1, -1.5, 1.6, -1.7, -1.6, 0.2])\\n"
    ...         "  movel(p[0.4, -0.1, 0.3, 0, 1.5708, 0])\\n"
    ...         "end\\n")
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path, out = os.path.join(tmp, "prog.script"), os.path.join(tmp, "new.script")
    ...     with open(path, "w") as f:
    ...         _ = f.write(text)
    ...     program = read_program(path)
    ...     write_program(out, program, {1: "p[0.4, -0.1, 0.31, 0, 1.5708, 0]"}, marks={0: "kept as taught"})
    ...     with open(out) as f:
    ...         print(f.read(), end="")
    def prog():
      movej([0.1, -1.5, 1.6, -1.7, -1.6, 0.2])  # kincal: not compensated: kept as taught
      movel(p[0.4, -0.1, 0.31, 0, 1.5708, 0])
    end
    """
    write_text_atomic(path, program.with_targets(texts, marks), program.encoding)


def line_column(text: str, at: int) -> tuple[int, int]:
    """The line and column (both from 1) of position ``at`` in ``text``."""
    line = text.count("\n", 0, at) + 1
    return line, at - (text.rfind("\n", 0, at) + 1) + 1
