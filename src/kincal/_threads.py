"""BLAS thread limits for small dense work (threadpoolctl, inspected once per process)."""
from __future__ import annotations

from contextlib import contextmanager
from functools import lru_cache


@lru_cache(maxsize=1)
def _controller():
    """threadpoolctl's controller, loaded on the first fit (not when kincal is imported)."""
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController()


@contextmanager
def blas_threads(n: int):
    """Run the block with at most ``n`` BLAS threads: calibration problems are small (K ≤ ~100
    columns), and OpenBLAS threads that spin on a busy 2-core machine make them 5–10× slower."""
    with _controller().limit(limits=n, user_api="blas"):
        yield


def limit_blas(n: int) -> None:
    """At most ``n`` BLAS threads for the rest of this process (a worker sharing the cores with others)."""
    _controller().limit(limits=n, user_api="blas")
