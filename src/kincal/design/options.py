"""The options of a pose design as one frozen record, validated when it is built (before any work)."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from ..analysis.identifiability import BASE_MODES
from ..checks import whole as _whole
from .criteria import CRITERIA
from .problem import UNITS

METHODS = ("random", "detmax", "fedorov", "ide", "detmax-ide")
EXCHANGE_CRITERIA = ("D", "I")  # what the low-rank Fedorov exchange can update
DESIGN_CRITERIA = ("IMSE",) + CRITERIA


@dataclass(frozen=True)
class DesignOptions:
    """How to choose measurement poses: one frozen record, every field checked when it is built.

    Parameters
    ----------
    m : int, optional
        Number of poses, 1 or more (default 60).
    method : str, optional
        One of :data:`METHODS` (default "fedorov"):

        - "random": m distinct candidates drawn at random;
        - "detmax": add–compare–remove–compare exchange;
        - "fedorov": greedy start, then modified Fedorov exchange with low-rank updates (criteria IMSE,
          D and I only), with ``restarts`` extra random starts, keeping the best;
        - "ide": improved differential evolution over continuous poses from a random pool design, for
          ``generations``;
        - "detmax-ide": Guo et al. 2024's two steps, DETMAX on the pool, then IDE from its design.
    criterion : str, optional
        One of :data:`DESIGN_CRITERIA` (default "IMSE"): "IMSE" (mean squared prediction error over the
        region of use, counting the bias of error terms geometry cannot describe; see
        :mod:`kincal.design.robust`), "D", "A", "E", "I" (average prediction variance over the region of
        use), "O1"…"O6", "comprehensive" (Guo et al. 2024's entropy-weighted index). IMSE is searched
        one pose per joint-space stratum by method "fedorov".
    seed : int or None, optional
        The random seed of the random starts and of IDE, 0 or more (default 0); None draws a fresh one.
    names : sequence of str or None, optional
        Parameters to design for, kept in order without repeats (default None: the identifiable set at
        the pool).
    base : str, optional
        "estimate" (default) or "fixed": whether the base frame is fitted (the base-mode rule).
    certify : bool, optional
        Compute the certified relaxation bound, so the design reports its D-efficiency (default True).
    restarts : int, optional
        Extra random starts of method "fedorov", 0 or more (default 0).
    generations : int, optional
        IDE's generations, 1 or more (default 200).
    units : str, optional
        "scaled" (default: unit-invariant columns) or "paper" (raw Jacobian in mm and rad).
    f0 : float, optional
        IDE's initial mutation factor (eq. 21), in (0, 4] (default 0.2).
    cr : float, optional
        IDE's crossover probability (eq. 25), in (0, 1] (default 0.2).
    population : int, optional
        IDE's population size, 6 or more (a mutant draws 6 distinct members; default 30).
    coverage : bool or None, optional
        Keep one pose per stratum of the pool (k-means in joint space), exchanging within strata (method
        "fedorov" with criterion IMSE, D or I); None (default): on for IMSE, off otherwise.
    weight : float, optional
        IMSE: the variance of each left-out error term's effect, in units of the noise variance, in
        [0, 1e6) (default 0.3).

    Attributes
    ----------
    stratified : bool
        Whether the design keeps one pose per stratum (``coverage``, or for None: IMSE by "fedorov").

    Raises
    ------
    ValueError
        Naming the field, when a value is not allowed or a combination cannot be searched (e.g. IMSE by a
        method other than "fedorov" or "random", or method "fedorov" with a criterion other than IMSE, D
        or I).

    See Also
    --------
    select_poses : takes these options, or changes of them as keywords.

    Examples
    --------
    >>> from kincal.design import DesignOptions
    >>> o = DesignOptions(m=30, criterion="D")
    >>> o.method, o.stratified
    ('fedorov', False)
    >>> o.replace(method="detmax", criterion="A").method
    'detmax'
    >>> DesignOptions(method="exchange")
    Traceback (most recent call last):
        ...
    ValueError: method 'exchange' is not one of random, detmax, fedorov, ide, detmax-ide
    >>> DesignOptions(method="detmax")  # IMSE, the default criterion, is searched by "fedorov"
    Traceback (most recent call last):
        ...
    ValueError: criterion 'IMSE' is searched one pose per joint-space stratum by method ...
    """

    m: int = 60
    method: str = "fedorov"
    criterion: str = "IMSE"
    seed: int | None = 0
    names: tuple[str, ...] | None = None
    base: str = "estimate"
    certify: bool = True
    restarts: int = 0
    generations: int = 200
    units: str = "scaled"
    f0: float = 0.2
    cr: float = 0.2
    population: int = 30
    coverage: bool | None = None
    weight: float = 0.3

    def __post_init__(self) -> None:
        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731
        set_("m", _whole("m", self.m, 1))
        for name, allowed in (("method", METHODS), ("criterion", DESIGN_CRITERIA), ("base", BASE_MODES), ("units", UNITS)):
            if self.__dict__[name] not in allowed:
                raise ValueError(f"{name} '{self.__dict__[name]}' is not one of {', '.join(allowed)}")
        self._check_coverage()
        if self.seed is not None:
            set_("seed", _whole("seed", self.seed, 0))
        if self.names is not None:
            if isinstance(self.names, str) or not all(isinstance(n, str) for n in self.names):
                raise ValueError(f"names={self.names!r}: give a list of parameter names")
            set_("names", tuple(dict.fromkeys(self.names)))
        if self.certify not in (True, False):
            raise ValueError(f"certify={self.certify!r}: True or False")
        for name, least in (("restarts", 0), ("generations", 1), ("population", 6)):  # a mutant draws 6 distinct members
            set_(name, _whole(name, self.__dict__[name], least))
        for name, lo, hi in (("f0", 0.0, 4.0), ("cr", 0.0, 1.0)):
            v = self.__dict__[name]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not lo < v <= hi:
                raise ValueError(f"{name}={v!r}: give a number in ({lo:g}, {hi:g}]")

    def _check_coverage(self) -> None:
        """IMSE and coverage are searched by the exchange within strata (see :attr:`stratified`)."""
        if self.coverage not in (True, False, None):
            raise ValueError(f"coverage={self.coverage!r}: True, False or None (on for IMSE)")
        w = self.weight
        if isinstance(w, bool) or not isinstance(w, (int, float)) or not 0.0 <= w < 1e6:
            raise ValueError(f"weight={w!r}: give the variance of each left-out term in units of the noise variance "
                             f"(≥ 0, e.g. 0.3)")
        if self.criterion == "IMSE" and (self.coverage is False or self.method not in ("fedorov", "random")):
            raise ValueError(f"criterion 'IMSE' is searched one "
                             f"pose per joint-space stratum by method 'fedorov' with coverage; with method "
                             f"'{self.method}'{' and no coverage' if self.coverage is False else ''} choose a criterion "
                             f"such as D")
        if self.stratified and (self.method != "fedorov" or self.criterion not in ("IMSE",) + EXCHANGE_CRITERIA):
            raise ValueError(f"coverage is kept by the exchange within strata: method 'fedorov' with criterion IMSE, D "
                             f"or I (got method '{self.method}', criterion '{self.criterion}')")
        if self.method == "fedorov" and self.criterion not in ("IMSE",) + EXCHANGE_CRITERIA:
            raise ValueError(f"method 'fedorov' supports the IMSE, D and I criteria (got '{self.criterion}'); use "
                             f"'detmax' for the others")

    @property
    def stratified(self) -> bool:
        """Whether the design keeps one pose per stratum: ``coverage``, or None → on for IMSE by Fedorov."""
        return self.criterion == "IMSE" and self.method == "fedorov" if self.coverage is None else bool(self.coverage)

    def replace(self, **changes: Any) -> "DesignOptions":
        """A copy with some fields changed (and checked again).

        Parameters
        ----------
        **changes
            Fields and their new values.

        Returns
        -------
        DesignOptions
            The new record.

        Raises
        ------
        ValueError
            Naming an unknown field, or a value that is not allowed.
        """
        known = [f.name for f in dataclasses.fields(self)]
        unknown = sorted(set(changes) - set(known))
        if unknown:
            raise ValueError(f"unknown design option(s) {', '.join(unknown)}; the options are {', '.join(known)}")
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict:
        """The options as JSON-ready values (``names`` as a list or None)."""
        out = dataclasses.asdict(self)
        out["names"] = None if self.names is None else list(self.names)
        return out
