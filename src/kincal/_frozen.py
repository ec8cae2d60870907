"""Read-only arrays and mappings for frozen results (a leaf module).

A frozen dataclass cannot have its fields replaced, but an array or a dict field could still be edited in place,
and what the result prints would follow the edit while what it computed before would not. :func:`freeze_arrays`,
called once as a result is built (its ``__post_init__``), makes every array it hands out read-only, and every
plain dict a :class:`ReadOnlyDict`.
"""
from __future__ import annotations

import dataclasses

import numpy as np


def read_only(value: np.ndarray) -> np.ndarray:
    """An array that cannot be edited in place: ``value`` itself when it already cannot be, else its read-only copy
    (the array given stays as it was, writeable, for whoever else holds it).

    Parameters
    ----------
    value : ndarray
        Any array.

    Returns
    -------
    ndarray
        The same values, shape and dtype, with ``flags.writeable`` False.

    Examples
    --------
    >>> import numpy as np
    >>> from kincal._frozen import read_only
    >>> a = np.zeros(3)
    >>> b = read_only(a)
    >>> b.flags.writeable, a.flags.writeable, read_only(b) is b
    (False, True, True)
    >>> b *= 2.0
    Traceback (most recent call last):
    ...
    ValueError: output array is read-only
    >>> np.array(b).flags.writeable  # a copy is the user's own
    True
    """
    if not value.flags.writeable:
        return value
    out = value.copy()
    out.setflags(write=False)
    return out


class ReadOnlyDict(dict):
    """A dict that refuses changes (still a dict: JSON writes it, ``dict(d)`` or ``{**d}`` is the user's own copy).

    Examples
    --------
    >>> from kincal._frozen import ReadOnlyDict
    >>> d = ReadOnlyDict({"j2.a": 1e-5})
    >>> d["j2.a"] *= 1000
    Traceback (most recent call last):
    ...
    TypeError: this mapping belongs to a frozen result: make a copy to change it (dict(...))
    >>> dict(d)["j2.a"] == 1e-5, isinstance(d, dict)
    (True, True)
    """

    def _refuse(self, *args, **kwargs):
        raise TypeError("this mapping belongs to a frozen result: make a copy to change it (dict(...))")

    __setitem__ = __delitem__ = update = pop = popitem = setdefault = clear = _refuse
    __ior__ = _refuse

    def __reduce__(self):  # pickled (a worker's result) as the plain dict it holds, made read-only again on arrival
        return (ReadOnlyDict, (dict(self),))


def freeze_arrays(result) -> None:
    """Make every array field of the frozen dataclass ``result`` read-only, and the arrays its tuples hold however deep
    (a tuple of pairs); a plain dict field becomes a :class:`ReadOnlyDict`, its arrays read-only.

    The one mechanism every frozen record that holds arrays calls from its ``__post_init__``: a result, and the records
    nested in it (each freezes its own as it is built).

    Parameters
    ----------
    result : dataclass instance
        A result, from its ``__post_init__``; its fields are replaced by :func:`read_only` arrays.

    Examples
    --------
    >>> import dataclasses
    >>> import numpy as np
    >>> from kincal._frozen import freeze_arrays
    >>> @dataclasses.dataclass(frozen=True)
    ... class Fit:
    ...     x: np.ndarray
    ...     parts: tuple = ()
    ...     by: dict = dataclasses.field(default_factory=dict)
    ...     def __post_init__(self):
    ...         freeze_arrays(self)
    >>> fit = Fit(np.ones(2), (np.zeros(1), "a", ("b", np.zeros(2))), {"j1": np.ones(3)})
    >>> fit.x.flags.writeable, fit.parts[0].flags.writeable, fit.parts[1], fit.parts[2][1].flags.writeable
    (False, False, 'a', False)
    >>> fit.by["j1"].flags.writeable, type(fit.by).__name__
    (False, 'ReadOnlyDict')
    """
    own = vars(result)
    for f in dataclasses.fields(result):
        if f.name not in own:  # a field set later (``init=False``): its owner freezes it once set
            continue
        value = own[f.name]
        if type(value) is dict:
            value = ReadOnlyDict({k: _frozen(v) for k, v in value.items()})
        else:
            value = _frozen(value)
        if value is not own[f.name]:
            object.__setattr__(result, f.name, value)


def _frozen(value):
    """``value`` with its arrays read-only, however deep in tuples (``value`` itself when nothing changes)."""
    if isinstance(value, np.ndarray):
        return read_only(value)
    if type(value) is tuple:
        items = tuple(_frozen(v) for v in value)
        return value if all(a is b for a, b in zip(items, value)) else items
    return value
