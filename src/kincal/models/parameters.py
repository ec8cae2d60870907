"""Named kinematic parameters: an immutable, ordered vector with SI values and a kind per entry."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterable, Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ModelError

KINDS = ("length", "angle", "ratio")  # ratio: a dimensionless factor (an actuator's scale, 1 nominal)
# The largest correction a real robot plausibly needs, per kind (m, rad, ratio), and for a closed chain's design
# points ("mounting"): the verdict's suspect limits (kincal.Thresholds' defaults), and the size of the real error a
# parameter kept at nominal may have
SUSPECT = {"length": 10e-3, "angle": float(np.deg2rad(2.0)), "ratio": 0.02, "mounting": 50e-3}


@dataclass(frozen=True, eq=False, init=False)
class Parameters:
    """An ordered, immutable vector of named kinematic parameters in SI units.

    Every entry has a stable name, a value and a kind; the values are stored as a read-only float array, and a
    change makes new Parameters (:meth:`replace`).

    Parameters
    ----------
    names : iterable of str
        Distinct, stable names such as ``j2.a``, ``base.rz``, ``tool.z``.
    values : array_like, shape (P,)
        The values in SI units: m for a length, rad for an angle, 1 for a ratio; all finite.
    kinds : iterable of str
        The kind of each entry: ``"length"``, ``"angle"`` or ``"ratio"`` (a dimensionless factor such as an
        actuator's scale, 1 nominal).

    Raises
    ------
    ModelError
        When the three do not have the same length, a name is given twice, a kind is unknown or a value is not
        finite.

    Examples
    --------
    >>> import numpy as np
    >>> from kincal.models import Parameters
    >>> p = Parameters(["j1.a", "j1.alpha", "tool.z"], [0.3, np.pi / 2, 0.05], ["length", "angle", "length"])
    >>> len(p), p["j1.a"], p.index("tool.z"), "j1.a" in p
    (3, 0.3, 2, True)
    >>> p.is_length()
    array([ True, False,  True])
    >>> longer = p.replace({"tool.z": 0.1})
    >>> longer["tool.z"], p["tool.z"], longer == p
    (0.1, 0.05, False)
    """

    names: tuple[str, ...]
    values: np.ndarray
    kinds: tuple[str, ...]
    _index: dict[str, int] = field(init=False, repr=False)

    def __init__(self, names: Iterable[str], values: ArrayLike, kinds: Iterable[str]) -> None:
        names, kinds = tuple(names), tuple(kinds)
        values = np.array(values, dtype=float).reshape(-1)
        if not (len(names) == len(kinds) == values.size):
            raise ModelError(f"parameters: {len(names)} names, {len(kinds)} kinds and {values.size} values must match")
        if len(set(names)) != len(names):
            dup = sorted({n for n in names if names.count(n) > 1})
            raise ModelError(f"parameters: duplicate names {dup}")
        bad = [k for k in kinds if k not in KINDS]
        if bad:
            raise ModelError(f"parameters: unknown kind(s) {sorted(set(bad))}; use one of {KINDS}")
        if not np.all(np.isfinite(values)):
            raise ModelError("parameters: non-finite values for "
                             + ", ".join(n for n, v in zip(names, values) if not np.isfinite(v)))
        values.setflags(write=False)
        for key, value in (("names", names), ("kinds", kinds), ("values", values),
                           ("_index", {n: i for i, n in enumerate(names)})):
            object.__setattr__(self, key, value)

    def __len__(self) -> int:
        return len(self.names)

    def __contains__(self, name: object) -> bool:
        return name in self._index

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Parameters):
            return NotImplemented
        return self.names == other.names and self.kinds == other.kinds and np.array_equal(self.values, other.values)

    def index(self, name: str) -> int:
        """Position of ``name``; ModelError naming the known parameters if absent."""
        try:
            return self._index[name]
        except KeyError:
            raise ModelError(f"unknown parameter '{name}'; this model has: {', '.join(self.names)}") from None

    def indices(self, names: Iterable[str]) -> np.ndarray:
        """Positions (int array) of ``names``; ModelError for a name that is not a parameter."""
        return np.array([self.index(n) for n in names], dtype=int)

    def __getitem__(self, name: str) -> float:
        return float(self.values[self.index(name)])

    def as_dict(self) -> dict[str, float]:
        """The values by name, as floats (SI units)."""
        return {n: float(v) for n, v in zip(self.names, self.values)}

    def replace(self, values: Mapping[str, float] | Sequence[float] | np.ndarray) -> "Parameters":
        """New Parameters with some values changed (by name) or all values replaced (array of length P)."""
        if isinstance(values, Mapping):
            new = self.values.copy()
            for name, v in values.items():
                new[self.index(name)] = float(v)
        else:
            new = np.array(values, dtype=float).reshape(-1)
            if new.size != len(self):
                raise ModelError(f"expected {len(self)} parameter values, got {new.size}")
        return Parameters(self.names, new, self.kinds)

    def is_length(self) -> np.ndarray:
        """(P,) bool mask of length parameters."""
        return np.array([k == "length" for k in self.kinds])
