"""The process's C heap: freed blocks kept for reuse instead of given back to the system.

A plan's search makes and frees NumPy arrays of 0.1 to 30 MB many times over (the arm's
pieces of a batch of postures, a pose's peak map, the candidates' rows). glibc's malloc
serves a block above its mmap threshold (128 kB at first, raised as blocks are freed) with
fresh pages from the system and unmaps it when freed, and gives the heap's free top back
above its trim threshold (128 kB): the next array of that size faults every page in again,
zeroed by the kernel (a few microseconds a page on a virtual machine). On the random
routes' one-off plans (``benchmarks/plan_random.py``) that was 900 to 1,200 page faults
and 3 to 6 ms of system time per pose. :func:`keep_freed_memory` sets both thresholds
high (:data:`MMAP_THRESHOLD`, :data:`TRIM_THRESHOLD`), once a process: freed blocks are
reused. The price: up to :data:`TRIM_THRESHOLD` of freed memory stays with the process.
On a C library without ``mallopt`` (not glibc) nothing changes.
"""

from __future__ import annotations

import ctypes
import sys

#: glibc's ``mallopt`` parameters (malloc.h).
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3
#: Blocks up to this size come from the heap, reused when freed [bytes] (glibc's largest).
MMAP_THRESHOLD = 32 * 2**20
#: Free memory at the heap's top kept by the process [bytes].
TRIM_THRESHOLD = 256 * 2**20

_STATE = {"done": False, "kept": False}


def keep_freed_memory() -> bool:
    """Keep freed C heap blocks for reuse, once a process; whether the C library took it."""
    if not _STATE["done"]:
        _STATE["done"] = True
        _STATE["kept"] = _mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD) and _mallopt(
            M_TRIM_THRESHOLD, TRIM_THRESHOLD
        )
    return _STATE["kept"]


def _mallopt(param: int, value: int) -> bool:
    """Call the C library's ``mallopt(param, value)``; False where it has none (not glibc)."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return bool(mallopt(param, value) == 1)
