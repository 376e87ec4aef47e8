"""The arm's link frames and its link shapes' poses in one C call (``frames.c``).

The same numbers as NumPy's batched 4x4 and 3x3 products (one BLAS call per matrix, most
of the time spent calling): ``frames.c`` makes BLAS's fused multiply-adds in BLAS's order.
That order is a property of the BLAS build and the CPU, so each kinematics (and each
checker's shapes) first computes a sample of postures both ways — random, rounded,
multiples of 45° and zero angles — and takes the C path only where every bit agrees
(signed zeros too); else, or without a C compiler or an FMA unit, NumPy's path is kept.
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mmstab.core.clib import DOUBLES, LIB_CFLAGS, LONG, compiled_library
from mmstab.core.files import MmstabError

SOURCE = Path(__file__).with_name("frames.c")  #: the kernel's C source
#: Compiled without contraction: every fused multiply-add is written out.
CFLAGS = (*LIB_CFLAGS, "-ffp-contract=off")


@lru_cache(maxsize=1)
def _kernels() -> tuple[Any, Any] | None:
    try:
        lib = ctypes.CDLL(str(compiled_library(SOURCE, "mmstab_frames", CFLAGS)))
    except (MmstabError, OSError):
        return None
    frames, shapes = lib.mmstab_link_frames, lib.mmstab_shape_poses
    frames.argtypes = [DOUBLES, DOUBLES, DOUBLES, DOUBLES, LONG, LONG, DOUBLES]
    shapes.argtypes = [DOUBLES, DOUBLES, DOUBLES, LONG, LONG, DOUBLES, DOUBLES]
    frames.restype = shapes.restype = ctypes.c_int
    return frames, shapes


def link_frames(
    trig: NDArray[np.float64], gain: NDArray[np.float64], rest: NDArray[np.float64],
    mount: NDArray[np.float64],
) -> NDArray[np.float64] | None:  # fmt: skip
    """Link frames (n, L, 4, 4) from each joint's (cos, sin) (n, L, 2); None: no kernel.

    Args:
        trig: cos and sin of each joint angle plus its offset (n, L, 2).
        gain: a DH transform's first two rows, the (cos, sin) entry's factor (L, 8).
        rest: its last two rows (L, 8) [-, m].
        mount: the arm's mount in B (4, 4) [-, m].
    """
    k = _kernels()
    if k is None:
        return None
    n, L = trig.shape[:2]
    out = np.empty((n, L, 4, 4))
    if k[0](trig, gain, rest, mount, n, L, out) != 0:
        return None
    return out


def shape_poses(
    frames: NDArray[np.float64], R_shape: NDArray[np.float64], p_shape: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """Link shapes' rotations (n, L, 3, 3) and centres (n, L, 3) [m] in B; None: no kernel.

    Args:
        frames: link frames in B (n, L, 4, 4), C-contiguous.
        R_shape: each shape's rotation in its link's frame (L, 3, 3).
        p_shape: its centre there (L, 3) [m].
    """
    k = _kernels()
    if k is None:
        return None
    n, L = frames.shape[:2]
    R, p = np.empty((n, L, 3, 3)), np.empty((n, L, 3))
    if k[1](frames, R_shape, p_shape, n, L, R, p) != 0:
        return None
    return R, p


def sample_postures(joints: int) -> NDArray[np.float64]:
    """The postures both paths are compared on (330, joints) [rad]."""
    rng = np.random.default_rng(20261129)
    q = rng.uniform(-3.2, 3.2, (300, joints))
    q[100:200] = np.round(q[100:200], 2)
    q[200:290] = np.round(q[200:290] / (np.pi / 4)) * (np.pi / 4)
    q[290:] = 0.0
    q[320:, ::2] = np.pi / 2
    return np.vstack([q, np.zeros((30, joints))])


def same_bits(a: NDArray[np.float64], b: NDArray[np.float64]) -> bool:
    """Whether two arrays hold the same numbers, signed zeros included."""
    return bool(
        a.shape == b.shape and np.array_equal(a, b) and np.array_equal(np.signbit(a), np.signbit(b))
    )


#: :func:`agrees`' answers by key (a kinematics' or a checker's constants): checked once a
#: process.
_AGREED: dict[bytes, bool] = {}


def agrees(key: bytes, fast: Callable[[], Any], reference: Callable[[], Any]) -> bool:
    """Whether ``fast()`` (None: unavailable) gives ``reference()``'s arrays bit for bit.

    Asked once per ``key`` (the constants both use) in a process.
    """
    if key not in _AGREED:
        _AGREED[key] = _agrees(fast, reference)
    return _AGREED[key]


def _agrees(fast: Callable[[], Any], reference: Callable[[], Any]) -> bool:
    got = fast()
    if got is None:
        return False
    want = reference()
    got, want = (got, want) if isinstance(want, tuple) else ((got,), (want,))
    return len(got) == len(want) and all(same_bits(g, w) for g, w in zip(got, want, strict=True))
