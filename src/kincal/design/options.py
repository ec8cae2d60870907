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


@dataclass(frozen=True)
class DesignOptions:
    """How to choose measurement poses. Every field is checked when the record is built.

    m           -- number of poses
    method      -- "random"; "detmax" (add–compare–remove–compare exchange); "fedorov" (greedy
                   start, then modified Fedorov exchange with low-rank updates; D and I criteria
                   only), with ``restarts`` extra random starts, keeping the best; "ide" (improved
                   differential evolution over continuous poses from a random pool design,
                   ``generations``); "detmax-ide" (Guo et al. 2024's two steps: DETMAX on the pool,
                   then IDE from its design)
    criterion   -- "D", "A", "E", "I" (average prediction variance over the validation poses, default
                   the pool), "O1"…"O6", "comprehensive" (Guo et al. 2024's entropy-weighted index)
    seed        -- the random seed (random starts, IDE); None draws a fresh one
    names       -- parameters to design for (default: the identifiable set at the pool)
    base        -- "estimate" or "fixed": whether the base frame is fitted (the base-mode rule)
    certify     -- compute the certified relaxation bound, so the design reports its D-efficiency
    units       -- "scaled" (unit-invariant columns) or "paper" (raw Jacobian in mm and rad)
    f0, cr, population -- IDE's initial mutation factor (eq. 21), crossover probability (eq. 25) and
                   population size
    """

    m: int = 60
    method: str = "fedorov"
    criterion: str = "D"
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

    def __post_init__(self) -> None:
        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731
        set_("m", _whole("m", self.m, 1))
        for name, allowed in (("method", METHODS), ("criterion", CRITERIA), ("base", BASE_MODES), ("units", UNITS)):
            if self.__dict__[name] not in allowed:
                raise ValueError(f"{name} '{self.__dict__[name]}' is not one of {', '.join(allowed)}")
        if self.method == "fedorov" and self.criterion not in EXCHANGE_CRITERIA:
            raise ValueError(f"method 'fedorov' supports the D and I criteria (got '{self.criterion}'); use 'detmax' "
                             f"for the others")
        if self.seed is not None:
            set_("seed", _whole("seed", self.seed, 0))
        if self.names is not None:
            if isinstance(self.names, str) or not all(isinstance(n, str) for n in self.names):
                raise ValueError(f"names={self.names!r}: give a list of parameter names")
            set_("names", tuple(dict.fromkeys(self.names)))
        if self.certify not in (True, False):
            raise ValueError(f"certify={self.certify!r}: True or False")
        set_("restarts", _whole("restarts", self.restarts, 0))
        set_("generations", _whole("generations", self.generations, 1))
        set_("population", _whole("population", self.population, 6))  # a mutant draws 6 distinct members
        for name, lo, hi in (("f0", 0.0, 4.0), ("cr", 0.0, 1.0)):
            v = self.__dict__[name]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not lo < v <= hi:
                raise ValueError(f"{name}={v!r}: give a number in ({lo:g}, {hi:g}]")

    def replace(self, **changes: Any) -> "DesignOptions":
        """A copy with some fields changed (and checked again); an unknown field is named."""
        known = [f.name for f in dataclasses.fields(self)]
        unknown = sorted(set(changes) - set(known))
        if unknown:
            raise ValueError(f"unknown design option(s) {', '.join(unknown)}; the options are {', '.join(known)}")
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict:
        out = dataclasses.asdict(self)
        out["names"] = None if self.names is None else list(self.names)
        return out
