"""Numbers to CSV text a whole table at a time (a leaf module).

Formatting a million rows through Python's %-operator costs seconds. Here every cell is rounded to
a fixed number of decimals as an integer (exact below 2**53), its digits are taken four at a time
from one lookup table into a byte array, the leading zeros are blanked and the bytes left joined.
The text equals printf's '%.Nf' (integers: '%d'), except that a cell within round-off of half a
unit in the last place may round the other way (it is rounded once, after scaling by 10**N), and
that -0 is written 0.
"""
from __future__ import annotations

import numpy as np

_DIGITS = np.frombuffer("".join(f"{k:04d}" for k in range(10_000)).encode(), np.uint8).reshape(10_000, 4)
_EXACT = 2.0**53


def fixed_lines(first: np.ndarray, table: np.ndarray, decimals: int, sep: str = ",") -> str | None:
    """Lines of ``sep``-separated cells: the integers ``first`` (N,) (e.g. row numbers), then the
    cells of ``table`` (N, C) with ``decimals`` (1–15) places. None when a cell is not finite or too
    large for exact integer rounding (|value| · 10**decimals ≥ 2**53): format such a table another way."""
    table = np.asarray(table, dtype=float)
    first = np.asarray(first, dtype=float)[:, None]
    if len(table) == 0:
        return ""
    a, b = _cells(first, 0), _cells(table, decimals)
    if a is None or b is None:
        return None
    width = max(a.shape[2], b.shape[2])
    out = np.zeros((len(table), 1 + table.shape[1], width), np.uint8)
    out[:, :1, width - a.shape[2]:] = a  # cells are right-aligned; the blank places are dropped below
    out[:, 1:, width - b.shape[2]:] = b
    out[:, :-1, -1] = ord(sep)
    out[:, -1, -1] = ord("\n")
    return out[out != 0].tobytes().decode("ascii")


def _cells(v: np.ndarray, d: int) -> np.ndarray | None:
    """Cells (N, k, width) of the values v (N, k) with d decimals: sign, integer digits (leading
    zeros blanked), point and decimals, and a last place for the separator; blank places are 0."""
    scaled = np.rint(np.abs(v) * 10.0**d)
    if not np.all(np.isfinite(scaled)) or scaled.max() >= _EXACT:
        return None
    m = scaled.astype(np.int64)
    whole = m // 10**d
    w = len(str(int(whole.max())))  # integer places
    total = w + d
    n_groups = -(-total // 4)
    digits = np.empty(v.shape + (4 * n_groups,), np.uint8)
    rest = m
    for g in range(n_groups - 1, -1, -1):
        rest, part = np.divmod(rest, 10_000)
        digits[..., 4 * g:4 * g + 4] = np.take(_DIGITS, part, axis=0)
    skip = 4 * n_groups - total
    out = np.zeros(v.shape + (total + (3 if d else 2),), np.uint8)
    out[..., 0] = np.where((v < 0) & (m > 0), ord("-"), 0)
    out[..., 1:1 + w] = digits[..., skip:skip + w]
    out[..., 1:w] *= whole[..., None] >= 10 ** np.arange(w - 1, 0, -1)  # leading zeros blanked (the units digit stays)
    if d:
        out[..., 1 + w] = ord(".")
        out[..., 2 + w:2 + w + d] = digits[..., skip + w:]
    return out
