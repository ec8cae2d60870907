"""Has the robot changed? Two calibrations compared (``kincal compare``), or a short check of a calibrated model on a
few measured poses (``kincal check``), each a test with a stated false-alarm probability that names what moved.

Both judge a discrepancy d over the poses of use against what it would be on an unchanged robot:

* **compare A B**: d = the positions B predicts minus those A predicts, at ``REGION_POSES`` poses drawn (seed 0) in the
  joint ranges both calibrations were fitted in; its covariance the sum of each calibration's repeat covariance
  carried to those poses (:class:`kincal.analysis.changes.Repeat`: what a calibration on other poses of the same
  robot differs by, what the model cannot describe included);
* **check CAL data**: d = measured − predicted at the check poses less the miss the calibration's own samples
  predict there (a transmission error shared with poses at near joint angles:
  :meth:`kincal.analysis.changes.Repeat.conditioned`), its covariance what is left of the prediction miss per axis
  (noise and what the model cannot describe) plus the repeat covariance carried to the poses.

Unless the instrument kept its frame (``same_frame``), the frame is re-fitted first, rigidly (Kabsch, exact for any
turn: :func:`kincal.identify.registration.register_base`; compare moves B's base frame onto A's predictions, check
the model's onto the measured positions), and every direction a frame change makes is then taken out. Two tests, each at half the level α: an omnibus test of the whole discrepancy (its squared
whitened norm, an F reference with the degrees of freedom the covariance was estimated with, and for a check the
heavier-than-Gaussian spread of the calibration's own residuals, ``dispersion``), and a directed test of each single
candidate change (:func:`kincal.analysis.changes.candidates`: joint zeros, links, joint axes, the tool, the frame),
Bonferroni over the candidates. With the frame kept, its move as a whole (every frame parameter together) is
ranked with the single candidates too, its explained squared norm less log(dof) per parameter beyond one (the
Bayesian information criterion), so a bumped instrument is not blamed on the one link that comes closest; it takes
no part in the tests. The false-alarm probability is therefore at most α; simulated (UR5 and Panda, 15 µm
noise, a 0.1 mm unmodelled harmonic, 200 pairs) it is measured by ``benchmarks/change_detection.py``. The suspects are
ranked by their posterior odds (the directed statistic z² and the prior odds ``ODDS`` of their kind): the first is
the single change that most probably explains the discrepancy.

A first suspect beyond a real robot's usual error (the verdict's suspect limits, 10 mm and 2°; the frame aside, a
tool point moved beyond ``MAX_TOOL``, 2 m, an input mistake and never a change), and determined better than that,
is first made in the model, its size refined by Gauss-Newton
steps on it alone (``STEPS``), and the test run again: when that leaves a plausible test and less than half the
discrepancy (``EXPLAIN_RATIO``, as an input mistake undone must), it is named with that size, a large but genuine
change (a joint re-mastered by 3°, a link rebuilt 15 mm longer). Else a check names no change of the robot: the
data do not fit it. The input mistakes the diagnosis knows (:func:`kincal.identify.diagnosis.input_changes`: the positions' length unit,
the joints' angle unit, a joint column negated, offset or swapped, mirrored positions, shifted rows) are screened by
the rigid fit of the model to the changed data, and the best few checked again: the one whose undoing leaves a
plausible check (and halves the discrepancy) is named with its fix, else that none of them explains the data.
Two calibrations whose first suspect is beyond those limits and explains them no better are, by the same rule, no
calibrations of one robot measured the same way: ``compare`` names no change but what their records say of why (a calibration whose verdict
was suspect or refused, another robot's name or nominal model, data read in other units or columns).
"""
from __future__ import annotations

from contextlib import suppress
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from .._frozen import freeze_arrays
from .._stats import f_sf
from .._threads import blas_threads
from ..analysis.changes import ALPHA, MIN_CHECK_POSES, Candidates, Repeat, candidates, frame_basis, without
from ..errors import KincalError, MeasurementError, ModelError
from ..io.measurements import Measurements
from ..models.plausible import MAX_TOOL
from ..models.robot import Robot
from ..models.transforms import kabsch
from ..ties import first_best, order_with_ties
from ..units import DEG, MM, SHOWN, display
from .registration import register_base

REGION_POSES = 200
RANK_RTOL = 1e-6  # singular values of the discrepancy's covariance factor below this × the largest: not seen
RESOLUTION = 1e-8  # m: nor below this σ (0.01 µm, no instrument's): what is left of one calibration's frame
# directions after another's are removed, and a model's second order, would otherwise look certain
KEPT = 5  # suspects kept in a result
STEPS = 4  # Gauss-Newton steps that refine the size of a single change beyond a real robot's error
EXPLAINED_MIN = 0.5  # the first suspect must explain this share of the whitened discrepancy alone to be named
ODDS = {"joint zero": 3.0}  # prior odds of a kind of change against any other (1): how suspects are ranked. A
# joint's zero moves when a motor, encoder or gearbox is replaced, at a re-mastering or a crash, the commonest
# events in a robot's life; a link's length or a joint's axis moves only when a part is bent or replaced. Where a
# zero and a link act almost alike at the poses (the Panda's joint 4 zero and its joint 5 offset), the zero is
# named unless the data favour the link by more than these odds; both stay in the suspects with their z.


@dataclass(frozen=True)
class Suspect:
    """One candidate change, with the size that best explains the discrepancy alone.

    Parameters
    ----------
    name : str
        The change: "j2 zero", a model parameter ("j3.a"), "tool.z", "base.rx".
    kind : str
        "joint zero", "link", "joint axis", "actuator" (a leg's or a joint's scale), "tool" or "frame".
    unit : str
        "length", "angle" or "ratio": what ``size`` and ``sigma`` are in (shown in mm, deg or %).
    size : float
        The size of this change alone that best explains the discrepancy, m or rad.
    sigma : float
        Its standard deviation, m or rad.
    z : float
        size / sigma.
    also : tuple of str, optional
        Changes that act the same at these poses (merged into this one; "−" before one that acts with the
        opposite sign), e.g. a link's length in two frames' terms.
    parts : tuple of Suspect, optional
        For the measurement frame judged as a whole (the frame kept, ``--same-frame``): each of its parameters'
        share of the move; then ``size`` and ``sigma`` are the move's length, m, and ``z`` the square root of the
        whitened discrepancy the whole move explains.
    """

    name: str
    kind: str
    unit: str
    size: float
    sigma: float
    z: float
    also: tuple[str, ...] = ()  # changes that act the same at these poses (a link's length in two frames' terms)
    parts: tuple["Suspect", ...] = ()  # the frame as a whole: its parameters' shares

    def line(self) -> str:
        unit, factor = SHOWN[self.unit]
        if self.parts:
            shares = ", ".join(f"{p.name} {p.size * SHOWN[p.unit][1]:+.4f} {SHOWN[p.unit][0]}" for p in self.parts)
            return (f"{self.name} ({self.kind}: the instrument or the robot's base moved; {shares}): moved "
                    f"{self.size * MM:.4f} mm ± {self.sigma * MM:.4f} (explains {self.z ** 2:.1f} of the whitened "
                    f"discrepancy)")
        same = f"; the same at these poses as {', '.join(self.also)}" if self.also else ""
        return (f"{self.name} ({self.kind}{same}): {self.size * factor:+.4f} {unit} ± {self.sigma * factor:.4f} "
                f"(z = {self.z:+.1f})")

    def to_dict(self) -> dict:
        return {"name": self.name, "kind": self.kind, "unit": self.unit, "size": self.size, "sigma": self.sigma,
                "z": self.z, "also": list(self.also), "parts": [p.to_dict() for p in self.parts]}


@dataclass(frozen=True)
class ChangeTest:
    """The answer of ``compare`` or ``check``: has the robot changed, and what moved.

    Parameters
    ----------
    question : str
        "compare" or "check".
    changed : bool
        The verdict at level ``alpha``.
    alpha : float
        The false-alarm probability the test was run at.
    p_value : float
        The test's p-value (Bonferroni over its two parts).
    statistic : float
        The omnibus test's squared whitened norm of the discrepancy.
    dof : int
        Its degrees of freedom (the directions the discrepancy was judged in).
    suspects : tuple of Suspect
        The candidate changes ranked by their posterior odds (``ODDS``): the first most probably explains the
        discrepancy alone.
    poses : int
        How many poses the discrepancy was taken at.
    frame_refitted : bool
        Whether the measurement frame was re-fitted (then frame changes are not judged).
    rms : float
        The discrepancy's RMS per pose after the frame, m.
    notes : tuple of str, optional
        What the reader should know (poses outside the calibrated ranges, a frame shift).
    explained : float, optional
        The share of the whitened discrepancy the first suspect explains alone (1 by default); below
        ``EXPLAINED_MIN`` no single change is named in the verdict.
    misfit : str, optional
        Why the data do not fit the robot at all (check), or the two calibrations do not describe one robot
        measured the same way (compare), when the first suspect is beyond a real robot's error: the likely input
        mistake, or what their records say (a doubtful verdict, another robot, data read otherwise), or that
        nothing explains it (default ``""``: they fit; a note gives the figures and the fix).

    Examples
    --------
    >>> t = ChangeTest("check", False, 0.05, 0.6, 20.1, 24, (Suspect("j2 zero", "joint zero", "angle", 1e-6,
    ...                2e-6, 0.5),), 10, True, 3e-5)
    >>> t.verdict
    'still good'
    >>> print(t.suspects[0].line())
    j2 zero (joint zero): +0.0001 deg ± 0.0001 (z = +0.5)
    """

    question: str
    changed: bool
    alpha: float
    p_value: float
    statistic: float
    dof: int
    suspects: tuple[Suspect, ...]
    poses: int
    frame_refitted: bool
    rms: float
    notes: tuple[str, ...] = ()
    explained: float = 1.0
    misfit: str = ""

    @property
    def verdict(self) -> str:
        if self.misfit:
            return f"the data do not fit this robot: {self.misfit}" if self.question == "check" else \
                f"these calibrations do not describe one robot measured the same way: {self.misfit}"
        if not self.changed:
            return "still good" if self.question == "check" else "no significant change"
        what = "no single change explains it" if self.explained < EXPLAINED_MIN else \
            f"{self.suspects[0].kind}: {self.suspects[0].name}"
        return f"{'re-calibrate' if self.question == 'check' else 'changed'} ({what})"

    def to_dict(self) -> dict:
        return {"question": self.question, "verdict": self.verdict, "changed": self.changed, "alpha": self.alpha,
                "p_value": self.p_value, "statistic": self.statistic, "dof": self.dof, "poses": self.poses,
                "frame_refitted": self.frame_refitted, "rms": self.rms, "explained": self.explained,
                "misfit": self.misfit, "suspects": [s.to_dict() for s in self.suspects], "notes": list(self.notes)}


@dataclass(frozen=True, eq=False)
class Calibrated:
    """A calibrated robot with what a repeat calibration would differ by and the joint ranges it was fitted in.

    Parameters
    ----------
    robot : Robot
        The calibrated robot.
    repeat : Repeat
        What a calibration on other poses of the same robot differs by (:class:`kincal.analysis.changes.Repeat`).
    lower, upper : ndarray, shape (n,)
        The joint ranges of the calibration's data, rad (m for a prismatic joint).
    label : str
        How messages name it (its file).
    verdict : str, optional
        The calibration's verdict as its record keeps it ("good", "suspect", "refused"; default "": not recorded).
    nominal : dict, optional
        The nominal model it was calibrated from, its parameters' values by name, SI (default: not recorded).
    reading : dict, optional
        How its data were read, as ``kincal calibrate`` records it (``length_unit``, ``angle_unit``, ``xyz_cols``,
        ``joint_cols`` ...; default: not recorded).
    """

    robot: Robot
    repeat: Repeat
    lower: np.ndarray
    upper: np.ndarray
    label: str
    verdict: str = ""
    nominal: dict = field(default_factory=dict)
    reading: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        freeze_arrays(self)

    @classmethod
    def of(cls, robot: Robot, record: dict | None, label: str) -> "Calibrated":
        """From a calibrated robot and its file's ``calibration`` section.

        Parameters
        ----------
        robot : Robot
            The calibrated robot read from the file.
        record : dict or None
            The file's ``calibration`` section.
        label : str
            The file's name, for messages.

        Returns
        -------
        Calibrated

        Raises
        ------
        ModelError
            Naming ``label``, when the file has no calibration record or its repeat record is missing or malformed.
        """
        record = cls.required(record, label)
        rep = Repeat.from_dict(record.get("repeat"), label)
        missing = [n for n in rep.names if n not in robot.params.names]
        if missing:
            raise ModelError(f"{label}: the repeat covariance names parameters the robot does not have: {missing}")
        env, data = record["envelope"], record.get("data")
        reading = data.get("reading") if isinstance(data, dict) else None
        nominal = record.get("nominal")
        return cls(robot, rep, np.asarray(env["lower"], float), np.asarray(env["upper"], float), label,
                   str(record.get("verdict") or ""), dict(nominal) if isinstance(nominal, dict) else {},
                   dict(reading) if isinstance(reading, dict) else {})

    @staticmethod
    def required(record: dict | None, label: str) -> dict:
        """A calibrated file's ``calibration`` section, checked to be one (with the joint ranges of its data): read
        it before the file's robot, so a file of another kind (a URDF, a nominal robot file) is named as what it
        is not, not given its own loader's advice.

        Parameters
        ----------
        record : dict or None
            The file's ``calibration`` section (:func:`kincal.models.load_calibration_record`).
        label : str
            The file's name, for messages.

        Returns
        -------
        dict
            ``record``.

        Raises
        ------
        ModelError
            Naming ``label``, when it is no calibrated robot file's section.
        """
        if not record or "envelope" not in record:
            raise ModelError(f"{label}: not a calibrated robot file (no 'calibration' section with the joint ranges "
                             f"of its data); give the file `kincal calibrate -o` wrote")
        return record

    def factor(self, q: np.ndarray, refitted: bool = False, robot: Robot | None = None) -> np.ndarray:
        """(3M, K) U with U Uᵀ the repeat covariance carried to the positions at q (M, n) by ``robot`` (default: the
        calibrated one; a check's has its frame re-fitted); ``refitted``: the frame is re-fitted, so its
        parameters' part (frame directions, removed anyway) is left out first: through another calibration's
        slightly different frame it would leave remnants that look like tiny, certain directions."""
        rep, robot = self.repeat, robot or self.robot
        if refitted:
            rep = rep.restricted([n for n in rep.names if n not in set(robot.base_params())])
        w, V = np.linalg.eigh(rep.covariance)
        J = robot.param_jacobian(q)[..., robot.params.indices(rep.names)]
        return J.reshape(3 * len(q), -1) @ (V * np.sqrt(np.clip(w, 0.0, None)))


def compare(a: Calibrated, b: Calibrated, same_frame: bool = False, alpha: float = ALPHA,
            poses: int = REGION_POSES) -> ChangeTest:
    """Did the robot change from calibration ``a`` to ``b``?

    The positions each predicts at ``poses`` poses drawn (random seed 0) in the joint ranges both were fitted in,
    judged against both repeat covariances; unless ``same_frame``, b's base frame is first moved rigidly so its
    predictions match a's there (a tracker turned by any angle between the two is no change).

    Parameters
    ----------
    a, b : Calibrated
        Two calibrations of the same robot model, the earlier first.
    same_frame : bool, optional
        The instrument kept its frame (a frame change is then a change); default False: the frame is re-fitted.
    alpha : float, optional
        The false-alarm probability (default ``ALPHA``, 0.05).
    poses : int, optional
        How many poses of the shared region the predictions are compared at (default 200).

    Returns
    -------
    ChangeTest
        The verdict, its p-value and the suspects; sizes are b − a. When the most likely single change is beyond
        a real robot's (the verdict's suspect limits, 10 mm, 2°, 2 %, and determined better than that), it is
        named, its size refined, when it explains the difference alone (made in a, the two leave less than half
        of it, plausibly); else no change is named: "these calibrations do not describe one robot measured the same way" with what their records
        say of why (``misfit``: a doubtful verdict, another robot or nominal model, data read otherwise).

    Raises
    ------
    ModelError
        When a and b are calibrations of different models.
    MeasurementError
        When their joint ranges do not overlap.
    """
    _same_model(a, b)
    q = _region(a, b, poses)
    test = _compared(a, q, b, q, same_frame, alpha)
    if _implausible(test) is None:
        return test
    return _one_change(test, lambda name, size: _compared(*_undone(a, q, name, size), b, q, same_frame, alpha)) \
        or _not_one_robot(a, b, test, test.notes)


def _compared(a: Calibrated, qa: np.ndarray, b: Calibrated, q: np.ndarray, same_frame: bool,
              alpha: float) -> ChangeTest:
    """The comparison of :func:`compare` at the poses q (M, n) without its plausibility gate; ``qa``: the joint
    values a is evaluated at (q, or q with a joint's zero moved: :func:`_undone`)."""
    (ma, Fa), (mb, Fb) = _miss(a, qa), _miss(b, q)  # what each misses there, as its own residuals predict it
    seen = a.robot.forward(qa) + _in_frame(a.robot, ma)  # where a says the instrument sees the target
    rb = b.robot  # b in a's measurement frame: its base moved rigidly onto a's predictions (what check does)
    if not same_frame and rb.base_params():
        rb = register_base(rb, q, seen, mb)
    d = (rb.forward(q) + _in_frame(rb, mb) - seen).ravel()
    U = np.concatenate([a.factor(qa, not same_frame), b.factor(q, not same_frame, rb), Fa, Fb], axis=1)
    basis = None if same_frame else frame_basis(rb, q)
    notes = tuple(n for n in ([] if same_frame else [_frame_shift(a.robot, b.robot)]) if n)
    return _judged("compare", d, U, candidates(rb, q, basis), basis, a.repeat.dof + b.repeat.dof, 1.0, alpha,
                   len(q), notes, _whole_frame(rb, q) if same_frame else None)


def _not_one_robot(a: Calibrated, b: Calibrated, test: ChangeTest, notes: tuple[str, ...]) -> ChangeTest:
    """``test`` (its first suspect beyond a real robot's change) as two calibrations that do not describe one
    robot measured the same way, with what their records say of why (:func:`_unlike`), not as a change."""
    from .verdict import Thresholds

    th, first, causes = Thresholds(), test.suspects[0], _unlike(a, b)
    head = (f"the most likely single change, {first.name} {display(first.size, first.unit, digits=(2, 2))}, is "
            f"beyond a real robot's change "
            f"({th.length_suspect * MM:g} mm, {th.angle_suspect * DEG:g} deg, {th.ratio_suspect:.0%}): these "
            f"calibrations do not describe one robot measured the same way, and no change of it is named")
    if causes:
        note = (f"{head}; likely cause: {'; '.join(causes)}. Fix that (a doubtful calibration's report names its "
                f"likely mistake; read both calibrations' data the same way; compare calibrations of one robot), "
                f"then compare again")
    else:
        note = (f"{head}; their records (verdicts, robot, nominal model, units and columns the data were read in) "
                f"do not say why: check that both files are calibrations of this robot from data read the same "
                f"way; if the robot was crashed, re-mastered or rebuilt, its history starts afresh: re-calibrate")
    more = f" (and {len(causes) - 1} more: see the note)" if len(causes) > 1 else ""
    return replace(test, misfit=f"{causes[0]}{more}" if causes else "their records do not say why",
                   notes=(*notes, note))


DOUBTFUL = ("suspect", "refused")  # a calibration's verdicts whose doubt carries over to what is judged against it
READ_AS = (("length_unit", "length unit", "m"), ("angle_unit", "angle unit", "rad"),
           ("xyz_cols", "position columns", "x,y,z"), ("joint_cols", "joint columns", "the robot's joint names"))


def _unlike(a: Calibrated, b: Calibrated) -> list[str]:
    """What the records of ``a`` and ``b`` say makes them no calibrations of one robot measured the same way: a
    doubtful verdict, another robot (its name or its nominal model), data read in other units or columns."""
    out = [f"{c.label} was calibrated with the verdict {c.verdict.upper()}" for c in (a, b) if c.verdict in DOUBTFUL]
    if a.robot.name != b.robot.name:
        out.append(f"they are calibrations of two robots, '{a.robot.name}' and '{b.robot.name}'")
    names = [n for n in a.nominal if n in b.nominal and n in a.robot.params.names  # beyond 0.01 µm or 0.01 µrad
             and isinstance(a.nominal[n], (int, float)) and isinstance(b.nominal[n], (int, float))
             and abs(a.nominal[n] - b.nominal[n]) > RESOLUTION]
    if names:
        kinds = dict(zip(a.robot.params.names, a.robot.params.kinds))
        shown = ", ".join(f"{n} {display(float(a.nominal[n]), kinds[n], digits=(2, 2))} vs "
                          f"{display(float(b.nominal[n]), kinds[n], digits=(2, 2))}" for n in names[:3])
        out.append(f"they were calibrated from different nominal models ({len(names)} parameters differ: {shown}"
                   f"{' …' if len(names) > 3 else ''})")
    read = [f"{what} {_read_as(a, key, d)} vs {_read_as(b, key, d)}" for key, what, d in READ_AS
            if a.reading and b.reading and _read_as(a, key, d) != _read_as(b, key, d)]
    if read:
        out.append(f"their data were read differently ({'; '.join(read)})")
    return out


def _read_as(cal: Calibrated, key: str, default: str) -> str:
    """How ``cal``'s data were read by the reading flag ``key`` in words (its ``default`` when not given)."""
    value = cal.reading.get(key)
    return default if value is None else ",".join(map(str, value)) if isinstance(value, (list, tuple)) else str(value)


def _miss(cal: Calibrated, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """What ``cal``'s predictions at q (M, n) miss by (M, 3), m, as its own samples' residuals predict it
    (:meth:`Repeat.conditioned`), and a factor (3M, K) of its covariance: two calibrations of an unchanged robot on
    different poses differ by their models' unmodelled errors there, not only by their noise (the real UR5's grid
    halves were 'changed' at p = 8e-21). Zero and no columns for a calibration without absolute positions."""
    try:
        mean, C = cal.repeat.conditioned(cal.robot, q)
    except ModelError:
        return np.zeros((len(q), 3)), np.zeros((3 * len(q), 0))
    w, V = np.linalg.eigh((C + C.T) / 2)
    L = V * np.sqrt(np.clip(w, 0.0, None))  # (M, M): L Lᵀ = C, the same for x, y and z
    return mean, np.kron(L, np.eye(3))


def check(cal: Calibrated, q: np.ndarray, xyz: np.ndarray, same_frame: bool = False,
          alpha: float = ALPHA, units: tuple[str, str] | None = None, rows: np.ndarray | None = None) -> ChangeTest:
    """Is the calibrated model still good? A short check on a few measured poses.

    Data whose most likely single change lies beyond a real robot's usual error (the verdict's suspect limits,
    10 mm and 2°) are taken for that change when it explains them alone (with it made in the model the check
    leaves less than half the discrepancy, plausibly: a joint re-mastered by 3°), its size refined; else for no
    change of the robot: the input mistake that explains them is named (``misfit``). A few poses that carry the
    discrepancy (beyond the outlier limit of robust σ, as a calibration's "a few bad poses") are named first, by row,
    when the check without them leaves less than half of it.

    Parameters
    ----------
    cal : Calibrated
        The calibration to check.
    q : ndarray, shape (M, n)
        Joint values of the check poses, rad (m for a prismatic joint); M ≥ 4.
    xyz : ndarray, shape (M, 3)
        The positions measured there, m.
    same_frame : bool, optional
        The instrument kept the calibration's frame; default False: the frame is re-fitted.
    alpha : float, optional
        The false-alarm probability (default ``ALPHA``, 0.05).
    units : tuple of (str, str), optional
        The (length, angle) units the data were read in, to name a unit mistake (default None: SI).
    rows : ndarray of int, shape (M,), optional
        The poses' line numbers in their file, header = 1, as messages name them (default 2, 3, ...).

    Returns
    -------
    ChangeTest
        "still good" or "re-calibrate (kind: name)", with the suspects (sizes: measured − model); or "the data do
        not fit this robot: cause" when they do not.

    Raises
    ------
    MeasurementError
        With fewer than 4 poses.
    ModelError
        When the calibration's data had no absolute positions (no prediction miss to judge against).
    """
    q = cal.robot.check_q(q)
    if len(q) < MIN_CHECK_POSES:
        raise MeasurementError(f"a check needs at least {MIN_CHECK_POSES} poses (the frame takes 6 of the 3 per "
                               f"pose); {len(q)} given. Measure the poses `kincal design CAL --check` chose")
    meas = Measurements(q, xyz, cal.robot.joint_names, "check", rows, units=units)
    test = _checked(cal, meas, same_frame, alpha)
    bad = _bad_poses(cal, meas, same_frame, alpha, test)
    if bad is not None or _implausible(test) is None:
        return bad or test

    def again(name: str, size: float) -> ChangeTest:
        changed, q_at = _undone(cal, meas.q, name, size)
        return _checked(changed, replace(meas, q=q_at), same_frame, alpha)
    named = _one_change(test, again)
    return named or _misfit(cal, meas, alpha, test)


def _bad_poses(cal: Calibrated, meas: Measurements, same_frame: bool, alpha: float,
               test: ChangeTest) -> ChangeTest | None:
    """``test`` (a change found) as data that do not fit when a few poses carry the discrepancy: those
    :func:`kincal.identify.diagnosis.few_bad` finds among the poses' discrepancies, named by row when the check
    without them leaves less than ``EXPLAIN_RATIO`` of it; else None."""
    from .diagnosis import EXPLAIN_RATIO, bad_rows, few_bad

    if not test.changed:
        return None
    bad = few_bad(np.linalg.norm(_discrepancy(cal, meas.q, meas.xyz, same_frame)[2], axis=1))
    keep = np.setdiff1d(np.arange(len(meas)), bad)
    if not len(bad) or len(keep) < MIN_CHECK_POSES:
        return None
    with suppress(KincalError, ValueError, np.linalg.LinAlgError):
        again = _checked(cal, meas.subset(keep), same_frame, alpha)
        if again.rms < EXPLAIN_RATIO * test.rms:
            cause = bad_rows(meas, bad)
            note = (f"likely cause: {cause.cause}; without them the check says {again.verdict} (discrepancy "
                    f"{test.rms * MM:.4g} mm RMS per pose -> {again.rms * MM:.4g} mm). Fix: check how they were "
                    f"measured and measure them again, or leave them out of the file")
            return replace(test, misfit=cause.cause, notes=(*test.notes, note))
    return None


def _undone(cal: Calibrated, q: np.ndarray, name: str, size: float) -> tuple[Calibrated, np.ndarray]:
    """``cal`` and the joint values q (M, n), rad or m, with the single change ``name`` of ``size`` (m or rad: a
    suspect's) made in the model: a joint's zero moved (the model evaluated ``size`` further along that joint, as
    the robot reached it), or a model parameter changed by ``size``."""
    joints = [f"{j} zero" for j in cal.robot.joint_names]
    if name in joints:
        q = q.copy()
        q[:, joints.index(name)] += size
        return cal, q
    values = cal.robot.params.values.copy()
    values[cal.robot.params.indices([name])] += size
    return replace(cal, robot=cal.robot.with_params(values)), q


def _one_change(test: ChangeTest, again: Callable[[str, float], ChangeTest]) -> ChangeTest | None:
    """``test`` (its first suspect beyond a real robot's error) as that one change when it explains the
    discrepancy: its size refined by Gauss-Newton steps on it alone (``again(name, size)``: the test with that
    change made in the model; at most ``STEPS``, a 3° zero's linear size was 0.006° off, 9σ), and named when the
    test with it made is plausible and leaves less than ``EXPLAIN_RATIO`` of the discrepancy (as an input
    mistake undone must); else None: no single change explains it."""
    from .diagnosis import EXPLAIN_RATIO
    from .verdict import Thresholds

    first, size = test.suspects[0], test.suspects[0].size
    if first.kind in NOT_ROBOT:  # a tool point moved beyond any tool's reach: no change of the robot, a mistake
        return None
    with suppress(KincalError, ValueError, np.linalg.LinAlgError):
        for _ in range(STEPS):
            rest = again(first.name, size)
            step = next((s.size for s in rest.suspects if s.name == first.name), 0.0)
            if abs(step) <= 0.01 * first.sigma:
                break
            size += step
        else:
            rest = again(first.name, size)
        if _implausible(rest) is None and rest.rms < EXPLAIN_RATIO * test.rms:
            th = Thresholds()
            moved = replace(first, size=size, z=size / first.sigma if first.sigma > 0 else first.z)
            undone = "the check says" if test.question == "check" else "the two calibrations show"
            note = (f"{first.name} {display(size, first.unit, digits=(2, 2))} is beyond a real robot's usual error "
                    f"({th.length_suspect * MM:g} mm, {th.angle_suspect * DEG:g} deg) and explains the discrepancy "
                    f"alone: with it made in the model {undone} {rest.verdict} (discrepancy {test.rms * MM:.4g} mm "
                    f"RMS per pose -> {rest.rms * MM:.4g} mm). A change this large is an event: a joint re-mastered, "
                    f"a motor, encoder or gearbox replaced, a crash or a part rebuilt")
            return replace(test, suspects=(moved, *test.suspects[1:]), notes=(*test.notes, note))
    return None


def _discrepancy(cal: Calibrated, q: np.ndarray, xyz: np.ndarray,
                 same_frame: bool) -> tuple[Robot, np.ndarray, np.ndarray]:
    """The check's robot (its frame re-fitted unless ``same_frame``), the (M, M) covariance a repeat calibration's
    miss has between the poses, and the poses' discrepancies (M, 3), m: measured less model less expected miss."""
    with blas_threads(1):  # small dense work: OpenBLAS threads spinning on a busy machine cost 100x (0.4 s)
        expected, A = cal.repeat.conditioned(cal.robot, q)  # what the calibration's own samples say it misses by
    robot = cal.robot
    if not same_frame:  # the frame of the measured positions less that expected miss
        robot = register_base(robot, q, xyz, expected)
    return robot, A, xyz - _in_frame(robot, expected) - robot.forward(q)


def _checked(cal: Calibrated, meas: Measurements, same_frame: bool, alpha: float) -> ChangeTest:
    """The check of :func:`check` on ``meas`` without its plausibility gate."""
    q = meas.q
    robot, A, miss = _discrepancy(cal, q, meas.xyz, same_frame)
    d = miss.ravel()
    w, V = np.linalg.eigh(A)  # per axis, the same for x, y, z: pose-major rows
    U = np.concatenate([np.kron(V * np.sqrt(np.clip(w, 0.0, None)), np.eye(3)),
                        cal.factor(q, not same_frame, robot)], axis=1)
    basis = None if same_frame else frame_basis(robot, q)
    return _judged("check", d, U, candidates(robot, q, basis), basis, cal.repeat.dof, cal.repeat.dispersion, alpha,
                   len(q), tuple(_outside(cal, meas)), _whole_frame(robot, q) if same_frame else None)


NOT_ROBOT = ("frame", "tool")  # kinds of change that say where the instrument stands or the target is mounted


def _implausible(test: ChangeTest) -> Suspect | None:
    """The first suspect of a significant ``test`` when it lies beyond a real robot's error (the verdict's suspect
    limits, :class:`kincal.identify.verdict.Thresholds`: 10 mm, 2°, 2 %; the frame aside, the tool point beyond
    ``MAX_TOOL``, 2 m, the farthest any tool reaches from the flange) and is determined better than that (a σ
    within the limit, as a calibration judges its corrections: the real WAM's check names j7's zero at +30.7° ±
    8.0°, which these poses barely see)."""
    from .verdict import Thresholds

    first = test.suspects[0] if test.changed and test.suspects else None
    if first is None or first.kind == "frame":
        return None
    limit = MAX_TOOL if first.kind == "tool" else Thresholds().suspect(first.unit)
    return first if abs(first.size) > limit >= first.sigma else None


def _misfit(cal: Calibrated, meas: Measurements, alpha: float, test: ChangeTest) -> ChangeTest:
    """``test`` (its first suspect beyond a real robot's error) as data that do not fit the robot: each input
    mistake of :func:`kincal.identify.diagnosis.input_changes` undone is screened by the rigid fit of the model to
    it, the ``MAX_FULL`` best that halve the original's checked again (the frame re-fitted: the mirrored frame's
    fix), and the one with the smallest discrepancy whose first suspect is plausible is named; else none."""
    from .diagnosis import EXPLAIN_RATIO, MAX_FULL, input_changes
    from .options import FitOptions
    from .verdict import Thresholds

    changes = input_changes(cal.robot, meas)
    changed = [change(cal.robot, meas, FitOptions())[1] for _, change in changes]
    screens = [_rigid_rms(cal.robot, m) if isinstance(m, Measurements) else np.inf for m in changed]
    limit = EXPLAIN_RATIO * _rigid_rms(cal.robot, meas)
    tried = []
    for k in [k for k in order_with_ties(screens, descending=False) if screens[k] < limit][:MAX_FULL]:
        m = changed[k]
        assert isinstance(m, Measurements)  # screened: a change of the data
        with suppress(KincalError, ValueError, np.linalg.LinAlgError):
            again = _checked(cal, m, False, alpha)
            if _implausible(again) is None and again.rms < EXPLAIN_RATIO * test.rms:
                tried.append((changes[k][0], again))
    th, first = Thresholds(), test.suspects[0]
    head = (f"the most likely single change, {first.name} {display(first.size, first.unit, digits=(2, 2))}, is "
            f"beyond a real robot's error ({th.length_suspect * MM:g} mm, {th.angle_suspect * DEG:g} deg): not a "
            f"change of the robot, the data do not fit it")
    if not tried:
        note = (f"{head}; none of the {len(changes)} common input mistakes kincal tried (length and angle units, "
                f"joint columns negated, offset or swapped, mirrored positions, shifted rows) explains them: check "
                f"that the data are this robot's and the calibration file its own; if the robot was crashed, "
                f"re-mastered or rebuilt, re-calibrate it")
        return replace(test, misfit="no common input mistake explains them", notes=(*_outside(cal, meas), note))
    cause, again = tried[first_best([t.rms for _, t in tried], maximize=False)]
    note = (f"{head}; likely cause: {cause.cause}; with that undone the check says {again.verdict} (discrepancy "
            f"{test.rms * MM:.4g} mm RMS per pose -> {again.rms * MM:.4g} mm). Fix: {cause.fix}")
    return replace(test, misfit=cause.cause, notes=(*_outside(cal, meas), note))  # not the suspects' notes


def _rigid_rms(robot: Robot, meas: Measurements) -> float:
    """RMS distance (m) of the positions of ``meas`` from the robot's at its joints in the rigid frame that fits
    them best (the frame re-fitted, Kabsch); inf where the robot has no position there."""
    try:
        p = robot.forward(meas.q)
    except (KincalError, ValueError):
        return np.inf
    if len(p) < 3 or not np.all(np.isfinite(p)):
        return np.inf
    R, t = kabsch(p, meas.xyz)
    return float(np.sqrt(np.mean(np.sum((meas.xyz - p @ R.T - t) ** 2, axis=1))))


def _in_frame(robot: Robot, base: np.ndarray) -> np.ndarray:
    """Vectors (M, 3) given in the robot's base frame, in the measurement frame ``robot`` stands in."""
    return base @ robot.base_transform()[0].T if robot.base_params() else base


def _whole_frame(robot: Robot, q: np.ndarray) -> Candidates | None:
    """The measurement frame's parameters as one candidate, (3M, r) columns (None for a model without a frame)."""
    names = list(robot.base_params())
    if not names:
        return None
    units = tuple(robot.params.kinds[i] for i in robot.params.indices(names))
    F = robot.param_jacobian(q)[..., robot.params.indices(names)].reshape(3 * len(q), -1)
    return Candidates(tuple(names), ("frame",) * len(names), units, F)


def _frame_move(whole: Candidates, W: np.ndarray, s: np.ndarray, u: np.ndarray) -> tuple[Suspect, float]:
    """The measurement frame's move (all its parameters together) that best explains the whitened discrepancy u,
    as a suspect, and the whitened squared norm it explains (W, s: the whitening)."""
    F = (W.T @ whole.G) / s[:, None]
    move = np.linalg.lstsq(F, u, rcond=None)[0]
    cov = np.linalg.pinv(F.T @ F)
    sig = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    parts = tuple(Suspect(n, "frame", unit, float(v), float(g), float(v / g) if g > 0 else 0.0)
                  for n, unit, v, g in zip(whole.names, whole.units, move, sig))
    t = [k for k, unit in enumerate(whole.units) if unit == "length"]
    size = float(np.linalg.norm(move[t]))
    sigma = float(np.sqrt(move[t] @ cov[np.ix_(t, t)] @ move[t])) / size if size > 0 else 0.0
    explained = float(np.sum((F @ move) ** 2))
    return Suspect("measurement frame", "frame", "length", size, sigma, float(np.sqrt(explained)), parts=parts), \
        explained


def _judged(question: str, d: np.ndarray, U: np.ndarray, cands: Candidates, basis: np.ndarray | None, nu: int,
            dispersion: float, alpha: float, poses: int, notes: tuple[str, ...],
            whole: Candidates | None = None) -> ChangeTest:
    """The two tests of the discrepancy d (3M,) whose covariance is U Uᵀ, frame directions ``basis`` taken out;
    ``whole``: the frame kept, its parameters offered together too (:func:`_whole_frame`), in the ranking only."""
    if basis is not None:
        d, U = without(basis, d), without(basis, U)
    W, s, _ = np.linalg.svd(U, full_matrices=False)
    keep = s > max(s[0] * RANK_RTOL, RESOLUTION)
    W, s = W[:, keep], s[keep]
    u = (W.T @ d) / s
    G = (W.T @ cands.G) / s[:, None]
    norms = np.linalg.norm(G, axis=0)
    seen = norms > 1e-12 * max(float(norms.max()), 1e-300)
    z = np.where(seen, (G.T @ u) / np.where(seen, norms, 1.0), 0.0)
    dof, T = int(keep.sum()), float(u @ u)
    p_omni = f_sf(T / dof, dof / dispersion, nu)
    p_dir = min(1.0, int(seen.sum()) * f_sf(float(np.max(z**2)), 1.0, max(dof / dispersion, 1.0) if dispersion > 1
                                            else nu))
    odds = np.array([ODDS.get(kind, 1.0) for kind in cands.kinds])  # a zero is the commonest change
    evidence = z**2 + 2.0 * np.log(odds)  # twice the log posterior odds of each single change, up to a constant
    pool = [(float(evidence[k]), Suspect(cands.names[k], cands.kinds[k], cands.units[k], float(z[k] / norms[k]),
                                         float(1.0 / norms[k]), float(z[k]), cands.also[k] if cands.also else ()))
            for k in np.flatnonzero(seen)]
    explained = 0.0
    if whole is not None:  # its r directions together: the evidence less log(dof) per direction beyond one (BIC)
        frame, explained = _frame_move(whole, W, s, u)
        pool.append((explained - (len(whole.names) - 1) * np.log(max(dof, 2)), frame))
    ev = np.array([e for e, _ in pool])
    rank = np.round(ev / max(float(np.max(np.abs(ev))), 1e-300), 9)  # ties (kincal.ties): their order
    suspects = tuple(pool[k][1] for k in sorted(range(len(pool)), key=lambda k: -rank[k])[:KEPT])
    changed = min(p_omni, p_dir) < alpha / 2
    share = min(1.0, suspects[0].z ** 2 / T) if suspects and T > 0 else 1.0
    if changed and share < EXPLAINED_MIN:
        notes += (f"the most likely single change explains only {share:.0%} of the discrepancy: these poses are "
                  f"missed by more than the calibration predicts, in ways no one change describes (a model that "
                  f"does not carry over to them, or several changes); re-calibrate, and look at that calibration's "
                  f"verdict",)
    if changed and whole is not None and suspects[0].kind == "frame":
        notes += (f"a move of the measurement frame alone explains {explained:.1f} of the whitened "
                  f"{T:.1f}: if the instrument or the robot's base may have moved, run again without --same-frame "
                  f"(the frame re-fitted, the robot judged alone)",)
    rms = float(np.sqrt(np.sum(d**2) / poses))
    return ChangeTest(question, bool(changed), alpha, min(1.0, 2 * min(p_omni, p_dir)), T, dof, suspects, poses,
                      basis is not None, rms, notes, share)


def _same_model(a: Calibrated, b: Calibrated) -> None:
    if a.robot.params.names != b.robot.params.names or a.robot.joint_names != b.robot.joint_names:
        raise ModelError(f"{a.label} and {b.label} are calibrations of different models (joints or parameters "
                         f"differ): compare two calibrations of the same robot file")


def _region(a: Calibrated, b: Calibrated, poses: int) -> np.ndarray:
    """``poses`` joint vectors (seed 0) drawn uniformly in the joint ranges both calibrations were fitted in."""
    lo, hi = np.maximum(a.lower, b.lower), np.minimum(a.upper, b.upper)
    empty = [j for j, l, h in zip(a.robot.joint_names, lo, hi) if l > h]
    if empty:
        raise MeasurementError(f"{a.label} and {b.label} were fitted on joint ranges that do not overlap for "
                               f"{', '.join(empty)}: there is no region where both can be compared")
    q = np.random.default_rng(0).uniform(lo, hi, size=(4 * poses, len(lo)))
    q = q[a.robot.feasible(q)][:poses]
    if len(q) < poses // 2:
        raise MeasurementError(f"too few feasible poses in the joint ranges both calibrations share ({len(q)})")
    return q


def _frame_shift(a: Robot, b: Robot) -> str:
    """The re-fitted frame's change from a to b in words (mm, mrad), or '' for a model without one."""
    names = a.base_params()
    if not names:
        return ""
    da = b.params.values[b.params.indices(names)] - a.params.values[a.params.indices(names)]
    move = float(np.linalg.norm(da[:3])) * MM
    turn = float(np.linalg.norm(da[3:])) * 1e3
    return f"the measurement frame differs by {move:.3f} mm and {turn:.3f} mrad (re-fitted: not judged)"


def _outside(cal: Calibrated, meas: Measurements) -> list[str]:
    """A note when check poses ``meas`` lie outside the joint ranges the calibration was fitted in (their file
    rows named)."""
    span = np.maximum(cal.upper - cal.lower, 1e-9)
    out = np.any((meas.q < cal.lower - 0.02 * span) | (meas.q > cal.upper + 0.02 * span), axis=1)
    if not out.any():
        return []
    return [f"{int(out.sum())} of {len(meas)} poses lie outside the joint ranges the calibration was fitted in: its "
            f"model error was not measured there ({meas.describe_rows(np.flatnonzero(out))})"]
