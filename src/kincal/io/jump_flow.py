"""Frames a program with labels and jumps writes at run time (FANUC TP's ``UTOOL[n]=PR[i]`` and ``UFRAME[n]=PR[i]``,
Yaskawa INFORM's ``MFRAME UF#(n)`` and ``SETTOOL TL#(n)``): the moves such a write may reach, by the program's flow
(:mod:`kincal.io.flow`), where the frame's value is the controller's, not the one given with the frames.

A jump may go to any label (TP's ``JMP LBL[n]``, ``IF …,JMP LBL[n]``, ``Skip,LBL[n]``; INFORM's ``JUMP *NAME``), so
the text is no tree of blocks; it is read into one that lets through every path the program has, and perhaps more:
the stretch from a label back to a later jump to it, and a loop's (``FOR`` … ``ENDFOR``, ``WHILE`` … ``ENDWHILE``,
``FOR`` … ``NEXT``), is a :class:`~kincal.io.flow.Loop` (all of it may run after any of it), stretches that overlap
joined into one; a jump forward is read as falling through. A path that skips a write leaves in force an earlier
write or the given value where the tree's path leaves that write, so the tree never has fewer writes in force at a
move than the program: a target is refused wherever a write may be in force, and perhaps where none is.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence

from . import flow


@dataclass(frozen=True)
class Write:
    """A frame written at run time: where (``at``, a character position; ``line``, from 1), the frame as targets
    name it ("UT 2"; its kind alone, "UT", where the number is chosen at run time: every frame of that kind; any
    case) and the statement as written."""

    at: int
    line: int
    frame: str
    text: str

    def hits(self, frame: str) -> bool:
        """Whether the write may change ``frame`` (names compared case-insensitively)."""
        return frame.lower() == self.frame.lower() or frame.lower().startswith(self.frame.lower() + " ")


def unknown_frames(writes: Sequence[Write], marks: Sequence[tuple[int, str, Optional[str]]],
                   targets: Sequence[tuple[tuple[str, ...], tuple[int, ...]]]) -> list[str]:
    """Why each target's frames are not the given ones where it is moved to ('' where they are).

    Parameters
    ----------
    writes : sequence of Write
        The frames the program writes at run time.
    marks : sequence of (int, str, str or None)
        Its flow, by character position: (at, "label", name), (at, "jump", name; None: any label) and a loop's
        (at, "open", None) and (at, "close", None).
    targets : sequence of (tuple of str, tuple of int)
        Each target's frames as it names them, (tool, base) ("UT 2", "UF 1"), and the positions of the moves to it
        (none: a target no move uses, which any write of its frames may reach).

    Returns
    -------
    list of str
        Per target, why the value of a frame of it may be the controller's (the writes' lines and text), or ''.

    Examples
    --------
    ``UTOOL[2]=PR[9]`` at position 30, between moves at 10 and 50, both with tool 2; then the same with a jump at
    60 back to a label at 5:

    >>> from kincal.io.jump_flow import Write, unknown_frames
    >>> w = [Write(30, 3, "UT 2", "UTOOL[2]=PR[9]")]
    >>> [bool(s) for s in unknown_frames(w, [], [(("UT 2",), (10,)), (("UT 2",), (50,))])]
    [False, True]
    >>> [bool(s) for s in unknown_frames(w, [(5, "label", "1"), (60, "jump", "1")], [(("UT 2",), (10,))])]
    [True]
    """
    slots = sorted({f for frames, _ in targets for f in frames if any(w.hits(f) for w in writes)})
    if not slots:
        return [""] * len(targets)
    nodes: list[tuple[int, object]] = [(w.at, flow.Set(flow.Setting(w.line, w.line), slots.index(f)))
                                       for w in writes for f in slots if w.hits(f)]
    nodes += [(at, flow.Move(at)) for _, ats in targets for at in ats]
    nodes.sort(key=lambda n: n[0])
    reached = flow.reach(_looped(nodes, _stretches(marks)), [flow.Setting(flow.START, "given")] * len(slots))
    out = []
    for frames, ats in targets:
        why = []
        for side, f in ((side, f) for side, f in enumerate(frames) if f in slots):
            k = slots.index(f)
            lines = ({s.line for at in ats for s in reached.get(at, ((frozenset(),) * len(slots)))[k]} if ats
                     else {w.line for w in writes if w.hits(f)})
            found = [w for w in writes if w.line in lines and w.hits(f)]
            if found:
                why.append(_why(("tool", "base")[min(side, 1)], f, found, bool(ats)))
        out.append("; ".join(why))
    return out


def _why(side: str, frame: str, found: list, moved: bool) -> str:
    """Why a target in ``frame`` (its ``side``: tool or base) is refused: the writes (``found``) that may be in force
    at its moves."""
    lines = ", ".join(str(w.line) for w in found)
    texts = ", ".join(w.text for w in found)
    where = "at the moves to it" if moved else "where it is used (no move of the program goes to it)"
    return (f"its {side} frame '{frame}' may be the one the program sets at run time on line{'s' * (len(found) > 1)} "
            f"{lines} ({texts}) {where}: a value only the controller knows, not the one given with the frames; teach "
            f"it in a frame the program does not set")


def _stretches(marks: Sequence[tuple[int, str, Optional[str]]]) -> list[tuple[int, int]]:
    """The stretches (first, last position) that may run again after any of their parts: from a label back to a
    later jump to it, and the loops; overlapping ones joined."""
    labels: dict[Optional[str], list[int]] = {}
    for at, kind, name in marks:
        if kind == "label":
            labels.setdefault(name, []).append(at)
            labels.setdefault(None, []).append(at)
    spans, opened = [], []
    for at, kind, name in sorted(marks, key=lambda m: m[0]):
        if kind == "jump":
            spans += [(a, at) for a in labels.get(name, []) if a <= at]
        elif kind == "open":
            opened.append(at)
        elif kind == "close" and opened:
            spans.append((opened.pop(), at))
    joined: list[tuple[int, int]] = []
    for a, b in sorted(spans):
        if joined and a <= joined[-1][1]:
            joined[-1] = (joined[-1][0], max(b, joined[-1][1]))
        else:
            joined.append((a, b))
    return joined


def _looped(nodes: list, stretches: list[tuple[int, int]]) -> list:
    """The nodes (position, node) in text order, those within each stretch one :class:`~kincal.io.flow.Loop`."""
    out, k = [], 0
    for a, b in stretches:
        while k < len(nodes) and nodes[k][0] < a:
            out.append(nodes[k][1])
            k += 1
        body = []
        while k < len(nodes) and nodes[k][0] <= b:
            body.append(nodes[k][1])
            k += 1
        out.append(flow.Loop((), tuple(body), "tail"))
    return out + [n for _, n in nodes[k:]]
