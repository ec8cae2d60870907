"""BLAS thread limits for small dense work (threadpoolctl, inspected once per process)."""
from __future__ import annotations

from functools import lru_cache


@lru_cache(maxsize=1)
def _controller():
    """threadpoolctl's controller, loaded on the first fit (not when kincal is imported)."""
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController()


def blas_threads(n: int):
    """At most ``n`` BLAS threads: for the block of a ``with`` (calibration problems are small, K ≤ ~100
    columns, and OpenBLAS threads that spin on a busy 2-core machine make them 5–10× slower), or, called
    alone, for the rest of this process (a worker sharing the cores with others)."""
    return _controller().limit(limits=n, user_api="blas")
