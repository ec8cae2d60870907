"""Guo et al. 2024 ("Ill-conditioned parameter separation based optimization of measurement configuration for
robot kinematic calibration") reproduced on the 3T2R robot: ill-conditioned parameter
separation, three 60-pose designs
(random, full-parameter optimised, separated-parameter optimised, both by DETMAX-IDE on the
comprehensive index), LM identification of parameter errors of 0.5 mm / 0.05 rad, identification
accuracy η (eq. 29) and validation errors (Table 8), repeated several times (repetition k draws its
errors, and in protocol "kincal" its noise, from random seed k; the first sets every error with a +
sign, as the paper does).

Two protocols. "kincal" (default): errors are set only on the kinematic parameters that poses spread
over the workspace identify (the Monte-Carlo study's exact model, :mod:`kincal.studies.guo2024_mc`),
15 µm tracker noise, adaptive LM over the same identifiable parameters: the fitted model can equal the
truth (< 1 µm training RMS without noise), so the designs are ranked by how they propagate noise, not
by a misfit no design can remove (errors on every parameter left about 0.15 mm of misfit: 0.05 rad
errors break the dependent parameters' first-order dependences). "paper": the paper's own simulation
(its §4), errors on every kinematic parameter, no noise, LM with a fixed damping μ = 1 in mm and rad
over all of them.

Deviation from the paper, by necessity: an error model with exact dependences has a zero singular
value, so every index of it is 0 (or rounding noise) and it cannot steer a design. The "full" model
is therefore the kinematic parameters (21 on guo3t2r, 25 on guo3t2r-paper) less QR's exact
dependences, and the "separated" model leaves out the branch-and-bound's choice by the paper's rule
(the lowest GCN; see :func:`~kincal.analysis.separation.separate_ill_conditioned`).

kincal numbers its own separation tables S1, S2, … and names every other printed table after the paper's
table it is the analogue of, so that no kincal table is read as the paper's.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..analysis.identifiability import identifiability
from ..checks import whole
from ..analysis.separation import TYPES, Separation, gcn, param_type, separate_ill_conditioned
from ..design import DesignOptions, candidate_pool, design_problem, pose_count_curve, select_poses
from ..identify.calibrate import calibrate, evaluate
from ..identify.positions import EXACT, EvaluationStats, e_statistics
from ..models.yaml_io import load_robot
from ..simulate import simulate
from ..units import MM
from .guo2024_mc import PAPER_REDUCTION, paper_grid

DESIGNS = ("random", "full-parameter optimised", "separated-parameter optimised")


@dataclass(frozen=True, eq=False)
class Guo2024Study:
    """The results of Guo et al. 2024's study reproduced: separation, three designs, identification, validation.

    The designs are keyed "random", "full-parameter optimised" and "separated-parameter optimised"; the
    validation and its point errors also hold "before calibration" (the nominal model). Printed
    (``str``), it gives kincal's tables beside the paper's numbers: the separation's as kincal tables
    S1, S2, … (each naming the paper's table it stands for, if any), the others headed "analogue of the
    paper's Table k", each with its protocol.

    Parameters
    ----------
    separation : Separation
        The ill-conditioned parameter separation on 100 random poses
        (:func:`kincal.analysis.separation.separate_ill_conditioned`).
    design_params : dict of str to tuple of str
        Per design, the parameters it was designed for.
    design_values : dict of str to float
        Per design, its comprehensive index.
    eta : dict of str to dict of str to float
        Per design, the identification accuracy η (eq. 29) of each identified parameter, % (first
        repetition).
    combinations : dict of str to dict of str to dict
        Per design, each identifiable combination (a kept parameter standing for kept + c·dependent) with
        its "set" and "identified" values and its "eta" (%, None for a combination set to 0; first
        repetition).
    identified : dict of str to dict of str to float
        Per design, the identified error of each parameter, m or rad (first repetition).
    true_errors : dict of str to float
        The size of the error set on each parameter given one, m or rad (the first repetition sets each
        with a + sign, as the paper does; the others draw the signs): protocol "kincal" the identifiable
        kinematic parameters only (the others keep their nominal values), protocol "paper" every
        kinematic parameter.
    validation : dict of str to EvaluationStats
        The 3-D errors on the paper's 60-point grid, first repetition: "before calibration" and each
        design.
    repeated : dict of str to tuple of float
        Per design over the repetitions: (mean, sd) of the mean ``abs(e)`` and (mean, sd) of the std of e,
        m (e: the average of the three axis errors).
    repeats : int
        Number of repetitions.
    m : int
        Poses per design.
    protocol : str, optional
        "kincal" (default: errors on the identifiable kinematic parameters, tracker noise, adaptive LM
        over them) or "paper" (errors on every kinematic parameter, no noise, LM with a fixed damping
        over all of them).
    units : str, optional
        The designs' index: "scaled" (default, unit-invariant) or "paper" (raw Jacobian in mm and rad).
    histories : dict, optional
        Per design, IDE's best index per generation, generation 0 first (Fig. 6).
    curve : dict, optional
        The index against the number of poses, separated model (Fig. 7; :meth:`PoseCountCurve.to_dict`).
    point_errors : dict, optional
        First repetition: the validation errors (60, 3), m, of "before calibration" and each design
        (Fig. 12).
    gcn_curve : dict, optional
        The GCN of the separated model's Jacobian against the number of poses: "m", "gcn", "parameters"
        (Fig. 5; raw Jacobian in mm and rad, as the paper, where the separation's tables scale the
        columns).
    positions : dict, optional
        Per design, the tool positions (m, 3), m (Fig. 10).
    train_rms : dict, optional
        First repetition: per design, the RMS of the 3-D residuals on its own poses after the fit, m
        (below 1 µm without noise when the model can equal the truth).
    noise : float, optional
        σ per axis of the simulated tracker noise, m (default 15e-6; 0 in protocol "paper").

    See Also
    --------
    guo2024_study : runs the study.
    kincal.report.guo2024_figures : its figures.
    """

    separation: Separation
    design_params: dict[str, tuple[str, ...]]
    design_values: dict[str, float]
    eta: dict[str, dict[str, float]]  # design -> parameter -> η % (first repetition)
    combinations: dict[str, dict[str, dict]]  # design -> combination -> set, identified, η (first repetition)
    identified: dict[str, dict[str, float]]  # design -> parameter -> identified error (first repetition)
    true_errors: dict[str, float]
    validation: dict[str, EvaluationStats]  # first repetition, 3-D errors; "before" is the nominal model
    repeated: dict[str, tuple[float, float, float, float]]  # mean±sd of mean |e|, mean±sd of std e (m)
    repeats: int
    m: int
    protocol: str = "kincal"
    units: str = "scaled"
    histories: dict = field(default_factory=dict)  # design -> IDE best index per generation, 0 first (Fig. 6)
    curve: dict = field(default_factory=dict)  # index vs number of poses, separated model (Fig. 7)
    point_errors: dict = field(default_factory=dict)  # first repetition: validation errors (60, 3) m per model (Fig. 12)
    gcn_curve: dict = field(default_factory=dict)  # GCN of the separated model's Jacobian vs number of poses (Fig. 5)
    positions: dict = field(default_factory=dict)  # design -> tool positions (m, 3) m (Fig. 10)
    train_rms: dict = field(default_factory=dict)  # first repetition: design -> RMS residual on its own poses, m
    noise: float = 15e-6  # σ per axis of the tracker noise, m (0 in protocol "paper")

    def to_dict(self) -> dict:
        """The study as JSON-ready values (SI: m, rad; η in %): "validation" holds the statistics of the 3-D
        errors, "validation_e" the printed table's of e (the largest and the mean absolute e, and the standard
        deviation of e)."""
        return {"separation": self.separation.to_dict(), "design_params": {k: list(v) for k, v in self.design_params.items()},
                "design_values": self.design_values, "eta_percent": self.eta, "identified_errors": self.identified,
                "combinations": self.combinations, "protocol": self.protocol, "units": self.units,
                "ide_history": {k: list(v) for k, v in self.histories.items()}, "pose_count_curve": self.curve,
                "validation_point_errors": {k: np.asarray(v).tolist() for k, v in self.point_errors.items()},
                "gcn_curve": self.gcn_curve, "positions": {k: np.asarray(v).tolist() for k, v in self.positions.items()},
                "true_errors": self.true_errors, "train_rms": self.train_rms, "noise": self.noise,
                "validation": {k: v.to_dict() for k, v in self.validation.items()},
                "validation_e": {k: dict(zip(("max_abs", "mean_abs", "std"), row))
                                 for k, row in e_statistics(self.point_errors).items()},
                "repeated": {k: {"mean_of_mean": v[0], "sd_of_mean": v[1], "mean_of_std": v[2], "sd_of_std": v[3]}
                             for k, v in self.repeated.items()}, "repeats": self.repeats, "m": self.m}

    def __str__(self) -> str:
        return "\n".join(["== Ill-conditioned parameter separation (100 random poses; GCN of scaled columns; kincal "
                          "tables S1, S2, ..., numbered apart from the paper's) ==",
                          self.separation.tables(), DEPENDENCE_NOTE, "", *self._designs(),
                          *self._tables(), *self._validation()])

    def protocol_text(self) -> str:
        """The identification protocol in words (where the errors are set, the noise, the fit).

        Returns
        -------
        str
            One line, e.g. "kincal protocol: errors on the 16 identifiable kinematic parameters only,
            15 µm noise, adaptive LM over them".
        """
        if self.protocol == "paper":
            return (f"paper protocol: errors on all {len(self.true_errors)} kinematic parameters, no noise, LM with "
                    f"fixed μ = 1 (mm, rad) over all of them")
        noise = f"{self.noise * MM * 1e3:g} µm noise" if self.noise else "no noise"
        return (f"kincal protocol: errors on the {len(self.true_errors)} identifiable kinematic parameters only, "
                f"{noise}, adaptive LM over them")

    def _designs(self) -> list[str]:
        unit = "raw Jacobian in mm and rad" if self.units == "paper" else "unit-invariant scaled columns"
        out = [f"== Designs of {self.m} poses (DETMAX-IDE, comprehensive index on {unit}; the final design's "
               f"index, then the DETMAX design IDE starts from) =="]
        for d in DESIGNS:
            paper = f" (paper: {PAPER_INDEX[d]})" if d in PAPER_INDEX else ""
            start = f", DETMAX {self.histories[d][0]:.4f}" if len(self.histories.get(d, ())) else ""
            out.append(f"  {d:<31} {len(self.design_params[d]):2d} parameters, comprehensive index "
                       f"{self.design_values[d]:.4f}{paper}{start}")
        return out + [""]

    def _table(self, values: dict[str, dict[str, float]], fmt) -> list[str]:
        """Per design its ``values`` by joint (rows) and parameter type (columns)."""
        kin = self.separation.names  # every kinematic parameter; blank: the robot has no such parameter
        joints = sorted({n.split('.')[0] for n in kin})
        rows = []
        for d in DESIGNS:
            rows += [f"  {d}", "    joint " + "".join(f"{'Δ' + t:>10}" for t in TYPES)]
            for j in joints:
                cells = [f"{'':>10}" if f"{j}.{t}" not in kin else fmt(f"{j}.{t}", values[d][f"{j}.{t}"])
                         if f"{j}.{t}" in values[d] else f"{'—':>10}" for t in TYPES]
                rows.append(f"    {j:<5} " + "".join(cells))
        return rows

    def _tables(self) -> list[str]:
        def as_units(name: str, v: float) -> str:  # mm for lengths, rad for angles, as the paper's tables
            return f"{v * MM:10.4f}" if param_type(name) in ("a", "d") else f"{v:10.4f}"
        out = [f"== Identified errors, first repetition (analogue of the paper's Tables 4-5; mm and rad; "
               f"{self.protocol_text()}; set: "
               f"{self.true_errors[next(n for n in self.true_errors if param_type(n) == 'a')] * MM:.1f} mm, "
               f"{self.true_errors[next(n for n in self.true_errors if param_type(n) == 'theta')]:.2f} rad) =="]
        out += self._table(self.identified, as_units)
        out += ["", "== Identification accuracy η (eq. 29; analogue of the paper's Fig. 8), first repetition: % per "
                    "parameter error (— = not identifiable: no error set on it, kept nominal) =="]
        out += self._table(self.eta, lambda n, v: f"{v:10.2f}")
        out += ["", "== η of the identifiable combinations (a kept parameter stands for kept + c·dependent"
                + ("; kincal protocol: the dependent parameters carry no error, so a combination's set value is "
                   "its kept parameter's)" if self.protocol != "paper" else ")") + " =="]
        for d in DESIGNS:
            out.append(f"  {d}")
            out += [f"    {k:<48} set {c['set']:+.5f}  identified {c['identified']:+.5f}  η "
                    + ("—" if c["eta"] is None else f"{c['eta']:.2f} %") for k, c in self.combinations[d].items()]
        out += ["", "== Analogue of the paper's Table 6 (η %, separated-parameter optimised vs random, first "
                    "repetition; the paper's joint k is kincal's joint k + 1 for k = 2-4 (Δd2 -> j3.d), its coupled "
                    "A1 is kincal's j1 and j2, its A5 tool row guo3t2r-paper's a5 (guo3t2r: the tool point)) =="]
        opt, rnd = DESIGNS[2], DESIGNS[0]
        for label, (name, paper) in PAPER_TABLE6.items():
            mine = (f"{self.eta[opt][name]:8.2f} {self.eta[rnd][name]:8.2f}" if name and name in self.eta[opt]
                    and name in self.eta[rnd] else f"{'—':>8} {'—':>8}")
            shown = name if name in self.separation.names else "(tool)"
            out.append(f"  {label:<5} {shown:<9} kincal {mine}   paper {paper[0]:8.3f} {paper[1]:8.3f}")
        return out + [""]

    def _validation(self) -> list[str]:
        out = [f"== Validation on the paper's 60-point grid, first repetition (analogue of the paper's Table 8, "
               f"Figs. 12-13; {self.protocol_text()}): error e in mm ==",
               "   (e: the average of the three axis errors, signed, as the paper's Table 8)",
               f"  {'':<31} {'max |e|':>9} {'mean |e|':>9} {'std e':>9}"]
        for k, row in e_statistics(self.point_errors).items():
            out.append(f"  {k:<31} " + " ".join(f"{'< 1 nm':>9}" if v < EXACT else f"{v * MM:9.4f}" for v in row))
        if self.train_rms:
            out.append("  RMS residual of each fit on its own design's poses (3-D, mm): " + ", ".join(
                f"{k} " + ("< 1 nm" if v < EXACT else f"{v * MM:.4f}") for k, v in self.train_rms.items()))
        what = "new errors and noise from random seed k" if self.noise else "new errors from random seed k, no noise"
        out += ["", f"== Repeated {self.repeats} times (repetition k: {what}; the designs stay): mean ± sd (mm) ==",
                f"  {'':<31} {'mean |e|':>22} {'std e':>22}"]
        for k, (mm, ms, sm, ss) in self.repeated.items():
            out.append(f"  {k:<31} {mm * MM:10.4f} ± {ms * MM:<9.4f} {sm * MM:10.4f} ± {ss * MM:<9.4f}")
        if max(v[0] for v in self.repeated.values()) < EXACT:
            return out + ["  every design reproduces the validation positions to < 1 nm (no noise): they tie, and the "
                          "differences shown are round-off, not a ranking"]
        rnd = self.repeated["random"][0]
        red = {d: 100 * (1 - self.repeated[d][0] / rnd) for d in DESIGNS[1:]}
        return out + [f"  mean |e|, '{DESIGNS[2]}' vs random (the paper's comparison; its Table 8: "
                      f"{PAPER_REDUCTION} %): {red[DESIGNS[2]]:+.1f} % reduction; '{DESIGNS[1]}' vs random: "
                      f"{red[DESIGNS[1]]:+.1f} %",
                      "  (one random design; 'kincal study guo2024' gives the distribution over random designs)"]


DEPENDENCE_NOTE = """why these dependences differ from the paper's Tables 1-3 (a4/a5 and d2/d3 there):
  - the paper sets the partial derivatives of its coupled A1 by theta1, alpha1, a1, d1 to zero (its section 1),
    so they cannot take part in a dependence; kincal models A1 as two DH rows (carriage j1, arm j2) whose
    parameters act. The arm's vertical offset j2.d then lies on the same vertical line as the quill's j3.d
    and J4's j4.d (J4 is coaxial with the quill): kincal's d2/d3/d4 group is the paper's d2/d3 pair (its
    A2 quill and A3 J4 rows) plus the A1 offset the paper zeroed; likewise j3.theta/j4.theta (two turns
    about that axis) would be the paper's theta1/theta3, hidden by the zero column.
  - the paper ends with a constant tool row A5 (4 DH parameters, no joint): with theta5 = 0 its a5 moves
    along the same x axis as A4's a4 (the paper's a4/a5) and alpha5 cannot move a point at the row's origin.
    guo3t2r places the reflector with a 3-parameter tool point instead, so that pair cannot appear there;
    the robot guo3t2r-paper has the fixed A5 row (kincal demo --robot guo3t2r-paper) and QR finds the
    paper's pair exactly (a5.a ~ j5.a) with its siblings a5.d ~ j5.d, a5.theta ~ j5.theta, a5.alpha (no
    effect). The same mechanism gives a2/a3 (arm and quill rows, no turn between them).
  - the paper gives no dimensions and no reflector offset, so its GCN values cannot be matched number for
    number; the structure of the dependences can, and QR names every one of them exactly."""

PROTOCOLS = ("kincal", "paper")
# the paper's Tables 4-6 (the first repetition sets every error as the paper: +0.5 mm, +0.05 rad)
PAPER_INDEX = {"full-parameter optimised": 1.833, "separated-parameter optimised": 2.049}
PAPER_TABLE6 = {"Δα4": ("j5.alpha", (17.159, 15.964)), "Δd2": ("j3.d", (98.068, 96.673)),
                "Δd3": ("j4.d", (98.066, 96.671)), "Δd4": ("j5.d", (19.557, 18.796)),
                "Δd5": ("a5.d", (31.855, 30.556))}  # paper label -> (kincal name, η %: optimised, random)


def guo2024_study(repeats: int = 20, m: int = 60, pool_size: int = 1000, generations: int = 150,
                  noise: float = 15e-6, length_error: float = 0.5e-3, angle_error: float = 0.05,
                  progress: Callable[[str], None] | None = None, protocol: str = "kincal",
                  units: str = "scaled", robot: str = "guo3t2r") -> Guo2024Study:
    """Run Guo et al. 2024's study on the 3T2R robot (about half a minute with the defaults).

    Separates the ill-conditioned parameters on 100 random poses, designs ``m`` poses three ways (random,
    full-parameter and separated-parameter DETMAX-IDE on the comprehensive index) from a pool of
    ``pool_size`` candidates, identifies parameter errors from each design and validates on the paper's
    60-point grid, ``repeats`` times (repetition k draws its errors, and in protocol "kincal" its noise,
    from random seed k; the first sets every error with a + sign, as the paper does). Every option is
    checked before any work.

    Parameters
    ----------
    repeats : int, optional
        Repetitions, 1 or more (default 20).
    m : int, optional
        Poses per design (default 60).
    pool_size : int, optional
        Candidate poses the designs choose from (default 1000).
    generations : int, optional
        IDE generations (default 150).
    noise : float, optional
        σ per axis of the tracker noise, m (default 15e-6; protocol "kincal" only: protocol "paper" has
        none, as the paper's simulation).
    length_error : float, optional
        Size of the error set on each length parameter, m (default 0.5e-3).
    angle_error : float, optional
        Size of the error set on each angle parameter, rad (default 0.05).
    progress : callable, optional
        Called with a line of text at each step.
    protocol : str, optional
        "kincal" (default): errors only on the kinematic parameters the pool identifies (the others keep
        their nominal values, so the fitted model can equal the truth: < 1 µm training RMS without
        noise), tracker noise, adaptive LM over the parameters each design identifies (η of each kept
        parameter, and of the combination it stands for); "paper": errors on every kinematic parameter
        (21 on guo3t2r, 25 on guo3t2r-paper), no noise, LM with a fixed damping μ = 1 in mm and rad over
        all of them (η for each, and for the combinations).
    units : str, optional
        The designs' index: "scaled" (default, unit-invariant) or "paper" (raw Jacobian in mm, rad).
    robot : str, optional
        "guo3t2r" (default), or "guo3t2r-paper" (the paper's rows: a fixed A5 tool row instead of a tool
        point).

    Returns
    -------
    Guo2024Study
        The separation, designs, identified errors, η, validation and repetitions.

    Raises
    ------
    ValueError
        When ``protocol``, ``units``, ``m``, ``generations`` or ``repeats`` is not valid.

    Examples
    --------
    >>> from kincal.studies import guo2024_study
    >>> guo2024_study(protocol="fast")  # checked before any work
    Traceback (most recent call last):
        ...
    ValueError: protocol='fast' is not one of ('kincal', 'paper')
    >>> guo2024_study(repeats=0)
    Traceback (most recent call last):
        ...
    ValueError: repeats=0: give a whole number, 1 or more
    """
    if protocol not in PROTOCOLS:
        raise ValueError(f"protocol='{protocol}' is not one of {PROTOCOLS}")
    DesignOptions(m=m, method="detmax-ide", criterion="comprehensive", units=units, generations=generations)  # checked first
    whole("repeats", repeats, 1)
    say = progress or (lambda msg: None)
    model = load_robot(robot)
    kin = tuple(n for n in model.params.names if param_type(n) in TYPES)
    say("separating ill-conditioned parameters")
    sep = separate_ill_conditioned(model, candidate_pool(model, 100, seed=0), kin)
    pool = candidate_pool(model, pool_size, seed=1)
    full = identifiability(model, pool, names=kin).identifiable
    # the paper's separated model: its own rule (lowest GCN), which may drop whole equivalent groups
    reduced = identifiability(model, pool, names=[n for n in kin if n not in sep.paper_choice]).identifiable
    design_names = {DESIGNS[0]: full, DESIGNS[1]: full, DESIGNS[2]: reduced}
    designs, values, histories = {}, {}, {}
    for name in DESIGNS:
        say(f"designing: {name}")
        P = design_problem(model, pool, design_names[name], units=units)
        d = select_poses(model, pool, m=m, method="random" if name == DESIGNS[0] else "detmax-ide", seed=0, problem=P,
                         criterion="comprehensive", certify=False, generations=generations)
        designs[name], values[name], histories[name] = d.q, d.value, d.history
    curve = pose_count_curve(P, "comprehensive", m_max=100, seed=0).to_dict()  # P: the separated model's
    gcns = gcn_curve(model, pool, reduced)
    noise = 0.0 if protocol == "paper" else noise
    drawn = kin if protocol == "paper" else full  # the paper sets every error; kincal's exact model the identifiable
    size = {n: length_error if model.params.kinds[model.params.index(n)] == "length" else angle_error for n in drawn}
    eta, combos, identified, validation, repeated, points, train = _identify(
        model, kin, designs, size, repeats, noise, protocol, say)
    return Guo2024Study(sep, design_names, values, eta, combos, identified, size, validation, repeated, repeats, m,
                        protocol, units, histories, curve, points, gcns,
                        {k: model.forward(q) for k, q in designs.items()}, train, noise)


def gcn_curve(robot, pool: np.ndarray, names, m_max: int = 100) -> dict:
    """Fig. 5: the GCN (cond/m) of the separated model's Jacobian in the paper's units (mm, rad) on
    the first m poses of the pool, m from the fewest that can identify it to ``m_max``. The columns are
    raw, as the paper's Fig. 5, where the separation's tables (kincal tables S1, S2, …) scale them, so
    the two are not on one scale."""
    J = design_problem(robot, pool[:m_max], names, units="paper").J
    ms = list(range(-(-J.shape[2] // 3), min(m_max, len(J)) + 1))
    return {"m": ms, "gcn": [gcn(J[:m].reshape(-1, J.shape[2]), m) for m in ms], "parameters": list(names)}


def _identify(robot, kin, designs, size, repeats, noise, protocol, say):
    """Per repetition (random seed k): errors on the parameters ``size`` names (the others stay
    nominal), identification from each design, validation; the first repetition keeps the details."""
    q_val = paper_grid(robot)
    idents = {name: identifiability(robot, q, names=kin) for name, q in designs.items()}  # fixed by the design
    eta, combos, identified, validation, runs, points, train = {}, {}, {}, {}, {n: [] for n in DESIGNS}, {}, {}
    for seed in range(repeats):
        say(f"identifying, repetition {seed + 1}/{repeats}")
        rng = np.random.default_rng(seed)
        sign = np.ones(len(size)) if seed == 0 else rng.choice([-1.0, 1.0], len(size))
        errors = {n: 0.0 for n in kin} | {n: s * size[n] for n, s in zip(size, sign)}
        true = robot.with_params({n: robot.params[n] + e for n, e in errors.items()})
        val = simulate(true, q_val, 0.0)
        if seed == 0:
            validation["before calibration"] = evaluate(robot, val)
            points["before calibration"] = val.xyz - robot.forward(val.q)
        for name in DESIGNS:
            meas = simulate(true, designs[name], noise, seed=1000 + seed)
            names = kin if protocol == "paper" else idents[name].identifiable
            fitted = paper_lm(robot, meas, kin) if protocol == "paper" else calibrate(
                robot, meas, names=names, base="fixed", diagnose=False, max_iter=200).robot
            corr = {n: fitted.params[n] - robot.params[n] for n in names}
            err = val.xyz - fitted.forward(val.q)
            runs[name].append(e_statistics({name: err})[name][1:])  # mean |e|, std e
            if seed == 0:
                validation[name], identified[name], points[name] = evaluate(fitted, val), corr, err
                eta[name] = {n: _eta(errors[n], corr[n]) for n in corr if errors[n]}  # η needs an error set
                combos[name] = _combinations(idents[name], errors, corr)
                train[name] = float(evaluate(fitted, meas).rms)  # the fit's residual on its own poses
    sd = (lambda x: float(x.std(ddof=1))) if repeats > 1 else (lambda x: 0.0)  # over the repetitions
    repeated = {name: tuple(v for x in np.array(r).T for v in (float(x.mean()), sd(x))) for name, r in runs.items()}
    return eta, combos, identified, validation, repeated, points, train


def _eta(true: float, est: float) -> float:
    """Identification accuracy (eq. 29), %."""
    return 100.0 * (1.0 - abs((true - est) / true))


def _combinations(ident, errors: dict, corr: dict) -> dict[str, dict]:
    """For each kept parameter that stands for dependent ones: the combination it identifies
    (kept + Σ c·dropped, c from the confound relations), its set and identified values and η."""
    out = {}
    for kept in ident.identifiable:
        terms = [(d, c) for d, conf in ident.confounds.items() for k, c in conf if k == kept]
        if not terms:
            continue
        true = errors[kept] + sum(c * errors[d] for d, c in terms)
        est = corr[kept] + sum(c * corr.get(d, 0.0) for d, c in terms)
        label = kept + "".join(f" {c:+.3g}·{d}" for d, c in terms)
        out[label] = {"set": true, "identified": est, "eta": _eta(true, est) if abs(true) > 1e-12 else None}
    return out


def paper_lm(robot, meas, names, mu: float = 1.0, max_iter: int = 200, tol: float = 1e-12):
    """Guo et al. 2024's identification (eq. 8): ΔX = (JᵀJ + μI)⁻¹JᵀΔP with a fixed μ, positions in mm,
    lengths in mm and angles in rad, over all ``names`` (dependent ones included: μ keeps the step
    finite and splits a dependent group evenly). Returns the fitted robot."""
    cols = robot.params.indices(names)
    unit = np.array([MM if robot.params.kinds[i] == "length" else 1.0 for i in cols])  # SI -> paper units (mm, rad)
    v = robot.params.values.copy()
    for _ in range(max_iter):
        p, J = robot.forward_and_jacobian(meas.q, v)
        r = (meas.xyz - p).reshape(-1) * MM
        A = J[:, :, cols].reshape(-1, len(cols)) * MM / unit
        step = np.linalg.solve(A.T @ A + mu * np.eye(len(cols)), A.T @ r)
        v[cols] += step / unit
        if np.max(np.abs(step)) < tol:
            break
    return robot.with_params(v)
