"""The resting pose's C kernel (``kernel.c``), called through ctypes.

The kernel runs the algorithm of :mod:`mmstab.terrain.rest.poses` per pose, function for
function (the coarse stage, the fine stage on each pose's highest candidates with its
check, the re-solve on all), so it gives the NumPy path's rests to rounding (tested) in a
fraction of the time, batched or one pose at a time. It is compiled on first use
(:mod:`mmstab.core.clib`); the NumPy path (``RestSettings(backend="numpy")``) stays as its
independent twin.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from mmstab.core.clib import BYTES, DOUBLE, DOUBLES, LONG, LONGS, kernel_function

REST_NAME = "mmstab_rest"  #: the kernel's C symbol
REST_SOURCE = Path(__file__).with_name("kernel.c")  #: its C source

_D, _L, _U8, _long, _double = DOUBLES, LONGS, BYTES, LONG, DOUBLE


@lru_cache(maxsize=1)
def _kernel() -> Any:
    # elev ny nx origin res | c K coarse Kc corners_coarse corners_full | com poses n settings
    # | att f flags iterations
    argtypes = [_D, _long, _long, _D, _double, _D, _long, _L, _long, _L, _L, _D, _D, _long]
    argtypes += [_D, _D, _D, _U8, _L]
    return kernel_function(REST_SOURCE, REST_NAME, argtypes)


class KernelRests(NamedTuple):
    """What the kernel returns for N poses and K candidates.

    Attributes:
        att: (N, 2) resting (roll, pitch) [rad].
        f: (N, K) lifts of the candidates at it [m] (NaN where not valid).
        valid: (N,) all ground the pose needs is on the map and known.
        converged: (N,) the attitude step fell below ``tol_step``.
        tips: (N,) the robot tips over.
        iterations: (N,) rounds used.
    """

    att: NDArray[np.float64]
    f: NDArray[np.float64]
    valid: NDArray[np.bool_]
    converged: NDArray[np.bool_]
    tips: NDArray[np.bool_]
    iterations: NDArray[np.int_]


def _arrays(
    elevation: NDArray[np.float64], c: NDArray[np.float64], com: NDArray[np.float64],
    poses: NDArray[np.float64],
) -> tuple[NDArray[np.float64], ...]:  # fmt: skip
    """The kernels' inputs as C-contiguous float64: the map (checked), candidates, CoMs, poses."""
    elev = np.ascontiguousarray(elevation, dtype=np.float64)
    ny, nx = elev.shape
    if ny < 2 or nx < 2:
        raise ValueError(f"the heightmap needs at least 2 x 2 cells, not {ny} x {nx}")
    p = np.ascontiguousarray(poses, dtype=np.float64)
    g = np.ascontiguousarray(np.broadcast_to(com, (p.shape[0], 3)), dtype=np.float64)
    return elev, np.ascontiguousarray(c, dtype=np.float64), g, p


def rest_kernel(
    elevation: NDArray[np.float64],
    origin: NDArray[np.float64],
    resolution: float,
    c: NDArray[np.float64],
    coarse: NDArray[np.int_],
    corners_coarse: NDArray[np.int_],
    corners_full: NDArray[np.int_],
    com: NDArray[np.float64],
    poses: NDArray[np.float64],
    settings: tuple[float, ...],
) -> KernelRests:
    """Resting attitudes of N poses by the C kernel.

    Args:
        elevation: (ny, nx) heights [m] (grid_map layout, NaN = unknown; ny, nx >= 2).
        origin: (2,) G (x, y) of the centre of cell [0, 0] [m].
        resolution: cell size [m].
        c: (K, 3) contact candidates in B [m].
        coarse: indices of the coarse stage's candidates.
        corners_coarse: (4,) the footprint's corners in the coarse subset's numbering.
        corners_full: (4,) the footprint's corners among all candidates.
        com: (N, 3) overall CoM in B [m].
        poses: (N, 3) of (x, y, yaw) in G [m, m, rad].
        settings: (max_iterations, tol_step, max_step, max_tilt, approach, approach_factor,
            coarse_tol, active_candidates, final_step, active_tol) in
            :class:`mmstab.terrain.rest.RestSettings`'s units.

    Raises:
        MemoryError: the kernel could not allocate its work arrays.
    """
    elev, cc, g, p = _arrays(elevation, c, com, poses)
    ny, nx = elev.shape
    K, n = cc.shape[0], p.shape[0]
    sub = np.ascontiguousarray(coarse, dtype=np.int64)
    att = np.empty((n, 2))
    f = np.empty((n, K))
    flags = np.empty((n, 3), dtype=np.uint8)
    iterations = np.empty(n, dtype=np.int64)
    code = _kernel()(
        elev, ny, nx, np.ascontiguousarray(origin, dtype=np.float64), float(resolution),
        cc, K, sub, sub.size,
        np.ascontiguousarray(corners_coarse, dtype=np.int64),
        np.ascontiguousarray(corners_full, dtype=np.int64),
        g, p, n, np.array([*settings, 0.0], dtype=np.float64),
        att, f, flags, iterations,
    )  # fmt: skip
    if code != 0:
        raise MemoryError("mmstab_rest: out of memory for its work arrays")
    b = flags.astype(bool)
    return KernelRests(att, f, b[:, 0], b[:, 1], b[:, 2], iterations.astype(np.int_))


POLISH_NAME = "mmstab_polish"  #: the polish's C symbol (in the same source)


@lru_cache(maxsize=1)
def _polish_kernel() -> Any:
    # elev ny nx origin res | c K com poses n max_tilt | att f flags
    argtypes = [_D, _long, _long, _D, _double, _D, _long, _D, _D, _long, _double, _D, _D, _U8]
    return kernel_function(REST_SOURCE, POLISH_NAME, argtypes)


def polish_kernel(
    elevation: NDArray[np.float64],
    origin: NDArray[np.float64],
    resolution: float,
    c: NDArray[np.float64],
    com: NDArray[np.float64],
    poses: NDArray[np.float64],
    max_tilt: float,
    att: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_]]:
    """:func:`mmstab.terrain.rest.polish.lowest` for n poses by the C kernel, and their lifts.

    Args:
        elevation: (ny, nx) heights [m] (as :func:`rest_kernel`).
        origin: (2,) G (x, y) of the centre of cell [0, 0] [m].
        resolution: cell size [m].
        c: (K, 3) contact candidates in B [m].
        com: (n, 3) overall CoM in B [m].
        poses: (n, 3) of (x, y, yaw) in G [m, m, rad].
        max_tilt: beyond this roll or pitch [rad] the robot tips.
        att: (n, 2) the rounds' attitudes, where each starts [rad].

    Returns:
        attitudes (n, 2) [rad], lifts there (n, K) [m], ended (n,): V's minimum reached with
        all its ground known (else the row is left as it was), tips (n,): beyond ``max_tilt``.

    Raises:
        MemoryError: the kernel could not allocate its work arrays.
    """
    elev, cc, g, p = _arrays(elevation, c, com, poses)
    ny, nx = elev.shape
    n = p.shape[0]
    att_out = np.array(att, dtype=np.float64, order="C")
    f = np.zeros((n, cc.shape[0]))
    flags = np.zeros((n, 2), dtype=np.uint8)
    code = _polish_kernel()(
        elev, ny, nx, np.ascontiguousarray(origin, dtype=np.float64), float(resolution),
        cc, cc.shape[0], g, p, n, float(max_tilt), att_out, f, flags,
    )  # fmt: skip
    if code != 0:
        raise MemoryError("mmstab_polish: out of memory for its work arrays")
    b = flags.astype(bool)
    return att_out, f, b[:, 0], b[:, 1]
