"""What moved in a robot's history: the parameters that changed across its calibrations, and each step
between consecutive calibrations with its size and z = Δ/σ (SI inside, mm/deg/mrad in words)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

from .records import Record

MOVED_Z = 2.0  # |Δ|/σ from which a step between consecutive calibrations is shown as a move


def calibrations(records: Sequence[tuple[int, Record]]) -> list[tuple[int, Record]]:
    return [(i, r) for i, r in records if r.kind == "calibration"]


def frame_names(records: Sequence[tuple[int, Record]]) -> set[str]:
    """The measurement-frame parameters (base.*: where the tracker saw the robot) of the records' models."""
    return {str(n) for _, r in records for n in (r.payload.get("frame") or ())}


def changed_parameters(records: Sequence[tuple[int, Record]], parameters: Sequence[str] | None = None) -> list[str]:
    """``parameters`` (checked: each in some calibration), else every robot parameter that moved between two
    consecutive calibrations by at least ``MOVED_Z`` σ (or at all, without a σ), the measurement frame left out (it
    moves with the tracker), in the order of the models: a panel for a change within the noise says nothing."""
    cals = [r for _, r in calibrations(records)]
    order = list(dict.fromkeys(n for r in cals for n in r.parameters))
    if parameters is not None:
        unknown = [p for p in parameters if p not in order]
        if unknown:
            raise ValueError(f"--parameters: {', '.join(unknown)} is in no calibration of this robot; its "
                             f"parameters: {', '.join(order) or 'none (no calibration recorded)'}")
        return list(parameters)
    moved = {m.name for m in moves(records) if not m.frame and (m.z is None or abs(m.z) >= MOVED_Z)}
    return [n for n in order if n in moved]


@dataclass(frozen=True)
class Move:
    """One parameter's step between consecutive calibrations ``before`` and ``after`` (record ids): the change
    ``delta`` (m or rad), the combined σ (the two σ in quadrature; one when the other is unknown; None when
    both are), z = Δ/σ (None without σ), the parameter's kind and whether it is the measurement frame."""

    before: int
    after: int
    time: str
    name: str
    kind: str
    delta: float
    sigma: float | None
    z: float | None
    frame: bool

    def to_dict(self) -> dict:
        return {"before": self.before, "after": self.after, "time": self.time, "parameter": self.name,
                "kind": self.kind, "change": self.delta, "sigma": self.sigma, "z": self.z, "frame": self.frame}

    @property
    def shown(self) -> bool:
        """Whether it is a move to show: beyond MOVED_Z σ, or a change without a σ; never the frame."""
        return not self.frame and (self.z is None or abs(self.z) >= MOVED_Z)


def moves(records: Sequence[tuple[int, Record]]) -> list[Move]:
    """Every parameter whose value differs between consecutive calibrations, per step in time order, the
    largest |z| first (a change without σ after those with one)."""
    cals, frame, out = calibrations(records), frame_names(records), []
    for (ia, a), (ib, b) in zip(cals, cals[1:]):
        step = []
        for n, v in b.parameters.items():
            if n not in a.parameters or a.parameters[n] == v:
                continue
            sa, sb = a.sigmas.get(n), b.sigmas.get(n)
            known = [s for s in (sa, sb) if s is not None]
            sigma = math.sqrt(sum(s * s for s in known)) if known else None
            delta = v - a.parameters[n]
            z = delta / sigma if sigma else None
            step.append(Move(ia, ib, b.time, n, b.kinds[n], delta, sigma, z, n in frame))
        out += sorted(step, key=lambda m: (m.z is None, -abs(m.z or 0.0)))
    return out
