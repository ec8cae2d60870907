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
    """Make every array field of the frozen dataclass ``result`` read-only, and the arrays of its tuple fields.

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
    ...     def __post_init__(self):
    ...         freeze_arrays(self)
    >>> fit = Fit(np.ones(2), (np.zeros(1), "a"))
    >>> fit.x.flags.writeable, fit.parts[0].flags.writeable, fit.parts[1]
    (False, False, 'a')
    """
    own = vars(result)
    for f in dataclasses.fields(result):
        value = own[f.name]
        if isinstance(value, np.ndarray):
            object.__setattr__(result, f.name, read_only(value))
        elif type(value) is tuple and any(isinstance(v, np.ndarray) for v in value):
            object.__setattr__(result, f.name, tuple(read_only(v) if isinstance(v, np.ndarray) else v for v in value))
        elif type(value) is dict:
            object.__setattr__(result, f.name, ReadOnlyDict(value))
