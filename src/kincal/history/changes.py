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
    """The parameters a history plot shows: those that moved between calibrations, or those asked for.

    Without ``parameters``: every robot parameter that moved between two consecutive calibrations by at
    least ``MOVED_Z`` σ (or at all, without a σ), the measurement frame left out (it moves with the
    tracker), in the order of the models: a panel for a change within the noise says nothing.

    Parameters
    ----------
    records : sequence of (int, Record)
        (id, record) of one robot in time order (as :meth:`Store.records` gives them); only the
        calibrations count.
    parameters : sequence of str, optional
        The parameters to show, each checked to be in some calibration (default: those that moved).

    Returns
    -------
    list of str
        The parameters' names.

    Raises
    ------
    ValueError
        When a given parameter is in no calibration of the records.

    Examples
    --------
    >>> from kincal.history import Identity, Record, changed_parameters
    >>> arm = Identity("cell-3 arm")
    >>> first = Record(arm, "calibration", "2024-05-01T08:00Z", parameters={"j2.theta": 0.0, "j3.a": 0.425},
    ...                sigmas={"j2.theta": 1e-4, "j3.a": 1e-5})
    >>> second = Record(arm, "calibration", "2024-06-01T08:00Z", parameters={"j2.theta": 2e-3, "j3.a": 0.42501},
    ...                 sigmas={"j2.theta": 1e-4, "j3.a": 1e-5})
    >>> changed_parameters([(1, first), (2, second)])  # j3.a moved by 0.7 σ only
    ['j2.theta']
    >>> changed_parameters([(1, first), (2, second)], ["j3.a"])
    ['j3.a']
    """
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
    """One parameter's step between consecutive calibrations.

    Parameters
    ----------
    before : int
        Id of the earlier calibration record.
    after : int
        Id of the later calibration record.
    time : str
        The later calibration's time, UTC ISO 8601 (:func:`utc_time`).
    name : str
        The parameter.
    kind : str
        Its kind: "length", "angle" or "ratio".
    delta : float
        The change, later minus earlier value, m or rad.
    sigma : float or None
        The combined σ of the change, m or rad: the two σ in quadrature, one when the other is unknown,
        None when both are.
    z : float or None
        ``delta / sigma`` (None without a σ).
    frame : bool
        Whether the parameter is the measurement frame (base.*: where the tracker saw the robot).

    Attributes
    ----------
    shown : bool
        Whether it is a move to show: beyond ``MOVED_Z`` σ, or a change without a σ; never the frame.
    """

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
        """The step as JSON-ready values (SI: m or rad)."""
        return {"before": self.before, "after": self.after, "time": self.time, "parameter": self.name,
                "kind": self.kind, "change": self.delta, "sigma": self.sigma, "z": self.z, "frame": self.frame}

    @property
    def shown(self) -> bool:
        """Whether it is a move to show: beyond MOVED_Z σ, or a change without a σ; never the frame."""
        return not self.frame and (self.z is None or abs(self.z) >= MOVED_Z)


def moves(records: Sequence[tuple[int, Record]]) -> list[Move]:
    """Every parameter whose value differs between consecutive calibrations, with its size and z = Δ/σ.

    Per step in time order, the largest ``abs(z)`` first (a change without σ after those with one).

    Parameters
    ----------
    records : sequence of (int, Record)
        (id, record) of one robot in time order (as :meth:`Store.records` gives them); only the
        calibrations count, and a parameter counts in a step when both calibrations have it.

    Returns
    -------
    list of Move
        One per parameter and step.

    Examples
    --------
    >>> from kincal.history import Identity, Record, moves
    >>> arm = Identity("cell-3 arm")
    >>> first = Record(arm, "calibration", "2024-05-01T08:00Z", parameters={"j2.theta": 0.0, "j3.a": 0.425},
    ...                sigmas={"j2.theta": 1e-4, "j3.a": 1e-5}, payload={"kinds": {"j2.theta": "angle"}})
    >>> second = Record(arm, "calibration", "2024-06-01T08:00Z", parameters={"j2.theta": 2e-3, "j3.a": 0.42501},
    ...                 sigmas={"j2.theta": 1e-4, "j3.a": 1e-5}, payload={"kinds": {"j2.theta": "angle"}})
    >>> for m in moves([(1, first), (2, second)]):
    ...     print(m.name, m.kind, f"{m.delta:.4g}", round(m.z, 2), m.shown)
    j2.theta angle 0.002 14.14 True
    j3.a length 1e-05 0.71 False
    """
    cals, frame, out = calibrations(records), frame_names(records), []
    for (ia, a), (ib, b) in zip(cals, cals[1:]):
        if any(held_apart(a, b, frame)):  # their values are in different terms: not compared (not_compared says)
            continue
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


def held_apart(a: Record, b: Record, frame: set[str]) -> tuple[list[str], list[str]]:
    """The robot parameters both calibrations' models have (the measurement frame ``frame`` left out) that one
    determined and the other held at its nominal value: (held in ``a`` only, held in ``b`` only). Where there are
    any, the two sets of values are in different terms (a hexapod's design frames fixed by other coordinates, a
    confounded parameter taken up by another) and are not compared parameter by parameter."""
    shared = [n for n in b.parameters if n in a.parameters and n not in frame]
    ia, ib = set(a.identifiable), set(b.identifiable)
    return [n for n in shared if n in ib and n not in ia], [n for n in shared if n in ia and n not in ib]


def not_compared(records: Sequence[tuple[int, Record]]) -> list[tuple[int, int, list[str], list[str]]]:
    """The steps between consecutive calibrations whose parameters :func:`moves` does not compare: (earlier id,
    later id, held in the earlier only, held in the later only) (:func:`held_apart`).

    Parameters
    ----------
    records : sequence of (int, Record)
        (id, record) of one robot in time order; only the calibrations count.

    Returns
    -------
    list of (int, int, list of str, list of str)
        One per step whose two calibrations held different parameters.

    Examples
    --------
    >>> from kincal.history import Identity, Record, not_compared
    >>> arm = Identity("hexapod")
    >>> a = Record(arm, "calibration", "2024-05-01T08:00Z", parameters={"leg1.bx": 0.1, "leg2.bx": 0.2},
    ...            identifiable=("leg2.bx",))
    >>> b = Record(arm, "calibration", "2024-06-01T08:00Z", parameters={"leg1.bx": 0.11, "leg2.bx": 0.2},
    ...            identifiable=("leg1.bx",))
    >>> not_compared([(1, a), (2, b)])
    [(1, 2, ['leg1.bx'], ['leg2.bx'])]
    """
    cals, frame = calibrations(records), frame_names(records)
    return [(ia, ib, *held_apart(a, b, frame)) for (ia, a), (ib, b) in zip(cals, cals[1:])
            if any(held_apart(a, b, frame))]

