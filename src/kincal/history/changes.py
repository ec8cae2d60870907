"""What changed in a robot's history: each step between consecutive calibrations judged by ``kincal compare``'s
test (:func:`kincal.identify.compare`: a stated false-alarm probability, the same verdict as compare on the two
calibrated files), and the parameters whose values differ most in each step, with z = Δ/σ (SI inside, mm/deg/mrad
in words). Each parameter's z is one of many tests at once, on its own σ (which leaves out what the model cannot
describe): the differences are listed, never called moves; the test says whether the robot changed."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

from .._threads import blas_threads
from ..analysis.changes import ALPHA
from ..errors import MeasurementError, ModelError
from ..identify.change import Calibrated, ChangeTest, compare
from ..models.yaml_io import robot_from_text
from .records import Record

LISTED = 3  # parameter differences listed per step between consecutive calibrations, the largest |z| first


def calibrations(records: Sequence[tuple[int, Record]]) -> list[tuple[int, Record]]:
    return [(i, r) for i, r in records if r.kind == "calibration"]


def frame_names(records: Sequence[tuple[int, Record]]) -> set[str]:
    """The measurement-frame parameters (base.*: where the tracker saw the robot) of the records' models."""
    return {str(n) for _, r in records for n in (r.payload.get("frame") or ())}


def changed_parameters(records: Sequence[tuple[int, Record]], parameters: Sequence[str] | None = None) -> list[str]:
    """The parameters a history plot shows: those the steps list as their largest differences, or those asked for.

    Without ``parameters``: the robot parameters :func:`largest` lists for some step between consecutive
    calibrations (up to ``LISTED`` per step, the largest z = Δ/σ in absolute value first), the measurement frame
    left out (it moves with the tracker), in the order of the models.

    Parameters
    ----------
    records : sequence of (int, Record)
        (id, record) of one robot in time order (as :meth:`Store.records` gives them); only the
        calibrations count.
    parameters : sequence of str, optional
        The parameters to show, each checked to be in some calibration (default: the largest differences).

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
    >>> changed_parameters([(1, first), (2, second)])  # z 14.1 and 0.7: both among a step's largest
    ['j2.theta', 'j3.a']
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
    listed = {m.name for m in largest(records)}
    return [n for n in order if n in listed]


@dataclass(frozen=True)
class Move:
    """One parameter's difference between consecutive calibrations.

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


def moves(records: Sequence[tuple[int, Record]]) -> list[Move]:
    """Every parameter whose value differs between consecutive calibrations, with its size and z = Δ/σ.

    Per step in time order, the largest ``abs(z)`` first (a change without σ after those with one). A step
    between calibrations of different models (:func:`different_models`) or that held different parameters
    (:func:`held_apart`) has none: their values are in different terms.

    Parameters
    ----------
    records : sequence of (int, Record)
        (id, record) of one robot in time order (as :meth:`Store.records` gives them); only the
        calibrations count.

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
    ...     print(m.name, m.kind, f"{m.delta:.4g}", round(m.z, 2))
    j2.theta angle 0.002 14.14
    j3.a length 1e-05 0.71
    """
    cals, frame, out = calibrations(records), frame_names(records), []
    for (ia, a), (ib, b) in zip(cals, cals[1:]):
        if different_models(a, b) or any(held_apart(a, b, frame)):  # values in different terms: not compared
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


def largest(records: Sequence[tuple[int, Record]]) -> list[Move]:
    """The parameter differences a history lists: per step between consecutive calibrations the ``LISTED``
    largest z in absolute value of :func:`moves` (a difference without σ after those with one), the measurement
    frame left out.

    Parameters
    ----------
    records : sequence of (int, Record)
        (id, record) of one robot in time order; only the calibrations count.

    Returns
    -------
    list of Move
        Up to ``LISTED`` per step, in time order.
    """
    out: list[Move] = []
    for m in moves(records):
        if not m.frame and sum((o.before, o.after) == (m.before, m.after) for o in out) < LISTED:
            out.append(m)
    return out


def different_models(a: Record, b: Record) -> bool:
    """Whether two calibrations are of different models (their parameters are not the same names: the nominal
    model changed, e.g. a DH file replaced by a URDF): then nothing in them is comparable."""
    return list(a.parameters) != list(b.parameters)


@dataclass(frozen=True)
class Step:
    """Two consecutive calibrations judged by ``kincal compare``'s test.

    Parameters
    ----------
    before : int
        Id of the earlier calibration record.
    after : int
        Id of the later calibration record.
    test : ChangeTest or None
        :func:`kincal.identify.compare` of the two (the frame re-fitted): its verdict at its false-alarm
        probability; None when they cannot be compared (``reason``).
    reason : str
        Why they were not judged ('' when they were).
    differences : tuple of Move
        The parameters whose values differ most (:func:`largest`), with their z = Δ/σ.
    """

    before: int
    after: int
    test: ChangeTest | None
    reason: str
    differences: tuple[Move, ...]

    def to_dict(self) -> dict:
        """The step as JSON-ready values (SI: m or rad)."""
        return {"before": self.before, "after": self.after, "test": None if self.test is None else self.test.to_dict(),
                "not_judged": self.reason or None, "largest": [m.name for m in self.differences]}


def calibrated(rid: int, record: Record) -> Calibrated:
    """The calibration record ``rid`` as ``kincal compare`` reads its calibrated file.

    Parameters
    ----------
    rid : int
        The record's id (messages name it).
    record : Record
        A calibration record (:func:`kincal.history.calibration_record`).

    Returns
    -------
    Calibrated
        The calibrated model the record keeps (its file text, SI) with its ``calibration`` section.

    Raises
    ------
    ModelError
        Naming the record, when it keeps no model (recorded by an older kincal) or no repeat covariance.
    """
    label = f"record #{rid}"
    text = record.payload.get("model")
    if not isinstance(text, str):
        raise ModelError(f"{label} keeps no calibrated model (recorded by an older kincal, or a kind of model "
                         f"kincal writes no file for): kincal compare judges the two calibrated files")
    return Calibrated.of(robot_from_text(text, label), record.payload.get("calibration"), label)


def steps(records: Sequence[tuple[int, Record]], alpha: float = ALPHA) -> list[Step]:
    """Each step between consecutive calibrations judged by ``kincal compare``'s test, with its largest differences.

    Parameters
    ----------
    records : sequence of (int, Record)
        (id, record) of one robot in time order (as :meth:`Store.records` gives them); only the
        calibrations count.
    alpha : float, optional
        The false-alarm probability of each step's test (default ``ALPHA``, 0.05).

    Returns
    -------
    list of Step
        One per pair of consecutive calibrations, in time order.

    Examples
    --------
    >>> from kincal.history import Identity, Record, steps
    >>> arm = Identity("cell-3 arm")
    >>> first = Record(arm, "calibration", "2024-05-01T08:00Z", parameters={"j3.a": 0.425}, sigmas={"j3.a": 1e-5})
    >>> second = Record(arm, "calibration", "2024-06-01T08:00Z", parameters={"j3.a": 0.42504},
    ...                 sigmas={"j3.a": 1e-5})
    >>> [step] = steps([(1, first), (2, second)])
    >>> step.test, [m.name for m in step.differences]  # records without their calibrated model: not judged
    (None, ['j3.a'])
    >>> step.reason
    'record #1 keeps no calibrated model (recorded by an older kincal, ...
    """
    cals, listed, out = calibrations(records), largest(records), []
    for (ia, a), (ib, b) in zip(cals, cals[1:]):
        test, reason = None, ""
        if different_models(a, b):
            reason = (f"record #{ia} and record #{ib} are calibrations of different models (their parameters "
                      f"differ: the nominal model changed), so nothing in them is comparable")
        else:
            try:  # small dense work: BLAS threads spinning on a busy 2-core machine took 1 s to 28 s
                with blas_threads(1):
                    test = compare(calibrated(ia, a), calibrated(ib, b), alpha=alpha)
            except (ModelError, MeasurementError) as exc:
                reason = str(exc)
        out.append(Step(ia, ib, test, reason, tuple(m for m in listed if (m.before, m.after) == (ia, ib))))
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

