"""The options of a calibration as one frozen record, validated when it is built.

:class:`FitOptions` is what :func:`kincal.calibrate` takes, what a calibrated robot file keeps
(``to_dict``) and what ``kincal report`` refits from (``from_dict``). Everything that can be checked
without the robot is checked in ``__post_init__``; :meth:`FitOptions.check` adds the checks that
need the robot (parameter names, the joint-space residual). Both run before any work, and every
message names the option.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Mapping

from ..analysis.identifiability import BASE_MODES, RANK_TOL
from ..checks import number as _number
from ..checks import one_of as _one_of
from ..checks import whole as _whole
from ..models.robot import Robot
from ..models.terms import ErrorModel
from .relevance import PRIORS
from .robust import LOSSES
from .verdict import Thresholds

METHODS = ("lm", "pso", "pso+lm")
_LEGACY = {"params": "names", "tol": "rank_tol", "pso_options": "pso"}  # keys of records written by kincal 0.1


def _names(name: str, value) -> tuple[str, ...]:
    if isinstance(value, str) or not all(isinstance(n, str) for n in value):
        raise ValueError(f"{name}={value!r}: give a list of parameter names")
    return tuple(dict.fromkeys(value))


def _flag(default: Any, flag: str, help: str, form: str = "value", choices: tuple = ()) -> Any:
    """A field the command line gives as ``flag``, declared here once: its help, the form of its value
    ("names": a comma-separated list; "count": a whole number ≥ 1; "switch": present or not; "value":
    one of ``choices``) and its default, the record's."""
    return field(default=default, metadata={"flag": flag, "help": help, "form": form, "choices": choices})


RESIDUAL_NAMES = ("cartesian", "joint")  # what a position fit minimises (identify.calibrate.RESIDUALS)
PRIOR_CHOICES = ("auto", *PRIORS)  # "auto": each kind's default, chosen by held-out evidence (identify.fitting)

@dataclass(frozen=True)
class PSOOptions:
    """Particle swarm settings (defaults: the 3-PUU paper of 2024, Table 2).

    The paper: "Error analysis model of parallel robot based on parameters identification". The swarm searches
    the nominal values ± its position limits, 8 mm for lengths, 8 mrad for angles, 8 ‰ for ratios
    (:data:`kincal.identify.pso.HALF_WIDTH`, not an option): an estimate on that box's edge is named in the
    verdict (``search-box``); ``method="pso+lm"`` polishes the swarm's best with Levenberg–Marquardt, unbound.

    Every field is checked when the record is built (ValueError naming it).

    Parameters
    ----------
    particles : int, optional
        Swarm size, 2 or more (default 500).
    iterations : int, optional
        Iterations, 1 or more (default 200).
    w : float, optional
        Inertia weight, ≥ 0 (default 0.8).
    c1 : float, optional
        Cognitive (own best) coefficient, ≥ 0 (default 0.5).
    c2 : float, optional
        Social (swarm best) coefficient, ≥ 0 (default 1.2).
    seed : int or None, optional
        Random seed of the swarm, ≥ 0; None: a fresh one each run (default 0).

    Examples
    --------
    >>> from kincal.identify import FitOptions, PSOOptions
    >>> PSOOptions(particles=50, iterations=20)
    PSOOptions(particles=50, iterations=20, w=0.8, c1=0.5, c2=1.2, seed=0)
    >>> FitOptions(method="pso+lm", pso={"particles": 50}).pso.particles  # a mapping of its fields works too
    50
    >>> PSOOptions(particles=1)
    Traceback (most recent call last):
    ...
    ValueError: pso particles=1: give a whole number, 2 or more
    """

    particles: int = 500
    iterations: int = 200
    w: float = 0.8
    c1: float = 0.5
    c2: float = 1.2
    seed: int | None = 0

    def __post_init__(self) -> None:
        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731
        set_("particles", _whole("pso particles", self.particles, 2))
        set_("iterations", _whole("pso iterations", self.iterations, 1))
        for k in ("w", "c1", "c2"):
            set_(k, _number(f"pso {k}", self.__dict__[k], positive=False))
        if self.seed is not None:
            set_("seed", _whole("pso seed", self.seed, 0))

    @classmethod
    def of(cls, value) -> "PSOOptions":
        if isinstance(value, PSOOptions):
            return value
        if isinstance(value, Mapping):
            unknown = sorted(set(value) - {f.name for f in dataclasses.fields(cls)})
            if unknown:
                raise ValueError(f"pso options {unknown}: known are {', '.join(f.name for f in dataclasses.fields(cls))}")
            return cls(**value)
        raise ValueError(f"pso={value!r}: give kincal.PSOOptions(...) or a mapping of its fields")

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


@dataclass(frozen=True)
class FitOptions:
    """How to calibrate: one frozen record of the options, checked when it is built.

    Every field is checked in ``__post_init__`` (ValueError naming it); :meth:`check` adds the checks
    that need the robot. A calibrated robot file keeps the record (:meth:`to_dict`, :meth:`from_dict`).

    Parameters
    ----------
    names : "auto" or sequence of str, optional
        ``"auto"`` (default): the identifiable set at the poses; or the parameter names to estimate.
    base : {"estimate", "fixed"}, optional
        ``"estimate"`` (default): register the measurement frame (Kabsch), then fit the base frame with
        the rest; ``"fixed"``: the base frame is known.
    loss : {"linear", "huber", "soft_l1"}, optional
        ``"linear"`` (default), or a robust loss on each sample's whitened residual block (a pose's
        3-D residual), reweighted from the start; method ``"lm"`` only.
    f_scale : float or None, optional
        The robust loss's scale, m on position data (default None: 3 robust σ of the residuals).
    method : {"lm", "pso", "pso+lm"}, optional
        ``"lm"`` (Levenberg–Marquardt, default), ``"pso"`` (particle swarm; ``pso``) or ``"pso+lm"``.
    residual : {"cartesian", "joint"}, optional
        ``"cartesian"`` (positions, default) or ``"joint"`` (commanded − inverse kinematics of the
        measured positions, the residual of the 3-PUU paper of 2024; robots with a
        closed-form inverse).
    joint_std : float, optional
        With ``residual="joint"``: the joints' reading noise σ, rad or m, the residual's stated σ (default None:
        1e-4, assumed, and the verdict says so).
    keep : sequence of str, optional
        Names to prefer among confounded parameters (default none).
    rank_tol : float, optional
        Relative singular-value tolerance of the identifiable set, in (0, 1) (the one rule shared with
        pose design; default :data:`kincal.analysis.RANK_TOL`, 3e-5).
    max_iter : int, optional
        Iterations of each solver run at most, 1 or more (default 100): a fit runs Levenberg–Marquardt several
        times (again after a parameter is kept nominal, the noise weights re-estimated, a robust reweighting,
        the identifiable set judged anew) and the learned prior's fit once; the result's ``iterations`` are
        summed over its ``runs``.
    pso : PSOOptions or mapping or None, optional
        Particle swarm settings for method ``"pso"`` / ``"pso+lm"`` (default None: its defaults; refused
        with ``"lm"``).
    thresholds : Thresholds or mapping, optional
        The verdict's limits (default ``Thresholds()``).
    error_model : ErrorModel or str or None, optional
        None (default: the robot as given), or an error model (a name is accepted:
        ``"compliance+harmonics:2"``, ``"auto"``).
    drift : bool, optional
        Also fit the instrument's drift over acquisition (row) order, cartesian residual only (default
        False).
    reject_outliers : bool, optional
        Leave out the poses a robust refit puts beyond ``thresholds.outlier_z`` robust σ (at most a
        tenth of them), named by row in the result; method ``"lm"`` only (default False).
    diagnose : bool, optional
        When the verdict doubts the data, try the common input mistakes and name the one that explains
        them (:mod:`kincal.identify.diagnosis`; default True).
    prior : {"auto", "relevance", "none"}, optional
        ``"none"`` (least squares); ``"relevance"``: a prior σ per joint origin's lengths and angles
        learned from the data (:mod:`kincal.identify.relevance`), after the least-squares fit (not with
        a particle swarm alone); ``"auto"`` (default): none for position data, relevance for the other
        kinds (:func:`kincal.identify.fitting.resolved_prior`).

    Raises
    ------
    ValueError
        For an invalid value or a combination that does not work (a robust loss or outlier rejection
        without ``"lm"``, ``pso`` with ``"lm"``, ``drift`` with the joint residual, the relevance prior
        with a particle swarm alone), naming the option.

    Examples
    --------
    >>> from kincal.identify import FitOptions
    >>> options = FitOptions(base="fixed", loss="huber")
    >>> options.base, options.loss, options.method, options.names
    ('fixed', 'huber', 'lm', 'auto')
    >>> options.replace(max_iter=20).max_iter
    20
    >>> FitOptions.from_dict(options.to_dict()) == options  # the record a calibrated robot file keeps
    True
    >>> FitOptions(loss="huber", method="pso")
    Traceback (most recent call last):
    ...
    ValueError: loss='huber' needs method='lm' (got method='pso'): robust reweighting refits with ...
    >>> options.replace(tolerance=1e-6)
    Traceback (most recent call last):
    ...
    ValueError: unknown calibration option(s) tolerance; the options are names, base, loss, ...
    """

    names: str | tuple[str, ...] = _flag("auto", "--params", "parameters to estimate (default: the identifiable set)",
                                         "names")
    base: str = _flag("estimate", "--base", "estimate the measurement (tracker) frame, or take the robot's base as "
                                            "known", choices=BASE_MODES)
    loss: str = _flag("linear", "--loss", "huber or soft_l1 down-weight the samples far off: each sample's residual "
                                          "against its stated σ (a point, a 6-D pose, a marker sample, a seat), "
                                          "reweighted from the start (default linear)", choices=LOSSES)
    f_scale: float | None = None
    method: str = _flag("lm", "--method", "lm (Levenberg-Marquardt), pso (particle swarm, the 3-PUU paper of 2024's "
                                          "settings) or pso+lm (default lm)", choices=METHODS)
    residual: str = _flag("cartesian", "--residual", "joint: commanded − inverse kinematics of the measured "
                                                     "positions (parallel robots)", choices=RESIDUAL_NAMES)
    joint_std: float | None = _flag(None, "--std-joint", "--residual joint: the joints' reading noise σ with its unit "
                                                        "(0.001rev, 0.05deg, 0.01mm; default 1e-4 rad or m)",
                                    "joint sigma")
    keep: tuple[str, ...] = _flag((), "--keep", "parameters to prefer among confounded ones", "names")
    rank_tol: float = RANK_TOL
    max_iter: int = _flag(100, "--max-iter", "iterations of each solver run at most (default 100); a fit runs "
                                             "several (refits as parameters are kept nominal, the noise weights "
                                             "re-estimated, robust reweighting; the learned prior's) and prints "
                                             "their iterations summed over its runs", "count")
    pso: PSOOptions | None = None
    thresholds: Thresholds = field(default_factory=Thresholds)
    error_model: ErrorModel | None = None
    drift: bool = _flag(False, "--drift", "also fit the measuring instrument's drift over acquisition (row) order, "
                                          "e.g. a tracker creeping; reported, not kept in the model", "switch")
    reject_outliers: bool = _flag(False, "--reject-outliers", "leave out the samples a robust refit puts beyond the "
                                                              "outlier limit (at most a tenth of a file's); named by "
                                                              "file and row in the output and the report", "switch")
    diagnose: bool = True
    prior: str = _flag("auto", "--prior", "relevance (a prior σ per joint origin's lengths and angles, learned from "
                                          "the data; corrections the data do not confirm stay near nominal), none "
                                          "(least squares) or auto (default): relevance for poses, markers, sockets "
                                          "and planes, none for points (on the real UR5 it did not help: 40 grid "
                                          "poses, 0.115 vs 0.103 mm on the random poses)", choices=PRIOR_CHOICES)

    def __post_init__(self) -> None:
        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731
        if self.names != "auto":
            set_("names", _names("names", self.names))
        set_("keep", _names("keep", self.keep))
        for k, allowed in (("base", BASE_MODES), ("loss", LOSSES), ("method", METHODS), ("residual", RESIDUAL_NAMES),
                           ("prior", PRIOR_CHOICES)):
            _one_of(k, self.__dict__[k], allowed)
        if self.f_scale is not None:
            set_("f_scale", _number("f_scale", self.f_scale, unit="m"))
        set_("rank_tol", _number("rank_tol", self.rank_tol))
        if not self.rank_tol < 1:
            raise ValueError(f"rank_tol={self.rank_tol!r}: the relative singular-value tolerance must lie in (0, 1)")
        set_("max_iter", _whole("max_iter", self.max_iter, 1))
        if self.loss != "linear" and self.method != "lm":
            raise ValueError(f"loss='{self.loss}' needs method='lm' (got method='{self.method}'): robust reweighting "
                             f"refits with Levenberg-Marquardt; use loss='linear' with '{self.method}', or method='lm'")
        if self.pso is not None:
            set_("pso", PSOOptions.of(self.pso))
            if self.method == "lm":
                raise ValueError(f"pso={self.pso.to_dict()}: particle-swarm options apply to method='pso' or 'pso+lm' "
                                 f"only (method='lm')")
        set_("thresholds", Thresholds.of(self.thresholds))
        if self.error_model is not None:
            set_("error_model", ErrorModel.of(self.error_model))
        if self.joint_std is not None:
            set_("joint_std", _number("joint_std", self.joint_std, unit="rad or m"))
            if not self.joint_std > 0 or self.residual != "joint":
                raise ValueError(f"joint_std={self.joint_std!r} (--std-joint): the joints' reading noise σ, > 0, of the "
                                 f"joint-space residual (residual='joint', --residual joint; got '{self.residual}')")
        if self.drift not in (True, False) or (self.drift and self.residual != "cartesian"):
            raise ValueError(f"drift={self.drift!r}: True or False; the drift term needs residual='cartesian'")
        set_("drift", bool(self.drift))
        for k in ("reject_outliers", "diagnose"):
            if self.__dict__[k] not in (True, False):
                raise ValueError(f"{k}={self.__dict__[k]!r}: True or False")
            set_(k, bool(self.__dict__[k]))
        if self.prior == "relevance" and self.method == "pso":
            raise ValueError(f"prior='{self.prior}' refits a least-squares fit: it needs method 'lm' or 'pso+lm' "
                             f"(got method='{self.method}')")
        if self.reject_outliers and self.method != "lm":
            raise ValueError(f"reject_outliers=True needs method='lm' (got '{self.method}'): the outliers are found "
                             f"by a robust Levenberg-Marquardt refit")

    def check(self, robot: Robot) -> "FitOptions":
        """The checks that need the robot: known parameter names, a residual the robot supports."""
        if self.names != "auto":
            robot.params.indices(self.names)  # unknown names raise, naming them
        robot.params.indices(self.keep)
        if self.residual == "joint" and not (robot.has_inverse or robot.has_pose_inverse):
            raise ValueError(f"residual='joint' needs a robot with closed-form inverse kinematics; robot "
                             f"'{robot.name}' has none: use residual='cartesian'")
        return self

    def replace(self, **changes: Any) -> "FitOptions":
        """A copy with some fields changed (and checked again); an unknown field is named."""
        unknown = sorted(set(changes) - {f.name for f in dataclasses.fields(self)})
        if unknown:
            raise ValueError(f"unknown calibration option(s) {', '.join(unknown)}; the options are "
                             f"{', '.join(f.name for f in dataclasses.fields(self))}")
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict:
        """The record a calibrated robot file keeps (SI; plain lists, numbers and strings)."""
        return {**self.__dict__, "names": self.names if isinstance(self.names, str) else list(self.names),
                "keep": list(self.keep), "pso": None if self.pso is None else self.pso.to_dict(),
                "thresholds": self.thresholds.to_dict(),
                "error_model": None if self.error_model is None else self.error_model.to_dict()}

    @classmethod
    def from_dict(cls, data: Mapping, where: str = "calibration record") -> "FitOptions":
        """The record written by :meth:`to_dict` (also the keys kincal 0.1 wrote); ValueError naming
        ``where`` and the key when it is malformed."""
        if not isinstance(data, Mapping):
            raise ValueError(f"{where}: the options must be a mapping, got {type(data).__name__}")
        d = {_LEGACY.get(k, k): v for k, v in data.items()}
        if "model" in d:  # 0.1: model and payload side by side
            model, payload = d.pop("model"), d.pop("payload", 0.0)
            d["error_model"] = None if model is None else {"name": model, "payload": payload}
        d.pop("payload", None)
        if d.get("pso") == {}:
            d["pso"] = None
        if isinstance(d.get("names"), list):
            d["names"] = tuple(d["names"])
        try:
            return cls().replace(**d)
        except (ValueError, TypeError) as exc:
            raise ValueError(f"{where}: {exc}") from None
