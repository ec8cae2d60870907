"""Keep freed memory for reuse in a process that works through many blocks (a leaf module).

glibc gives blocks of 128 kB and more back to the system when they are freed, and every new array
of that size is then faulted in page by page again: for block-by-block work on arrays of a few MB
that costs as much system time as the arithmetic. ``keep_freed_memory`` raises glibc's thresholds
(allocations up to 32 MB come from the heap, and the heap is trimmed only beyond 256 MB free), for
the process that calls it; elsewhere (another C library) it does nothing.
"""
from __future__ import annotations

import sys

M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3  # glibc's mallopt parameters
MMAP_THRESHOLD = 32 << 20  # glibc's largest allowed on 64-bit systems
TRIM_THRESHOLD = 256 << 20


def keep_freed_memory() -> bool:
    """Raise glibc's mmap and trim thresholds for this process; True when it did."""
    if not sys.platform.startswith("linux"):
        return False
    import ctypes

    try:
        libc = ctypes.CDLL("libc.so.6")
        return bool(libc.mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and bool(libc.mallopt(M_TRIM_THRESHOLD,
                                                                                        TRIM_THRESHOLD))
    except (OSError, AttributeError):  # not glibc
        return False
