"""The loaded support's μ in C (``support_mu.c``), called through ctypes.

For N states at their rests: the bearing candidates placed in G, their hull seen along the
net force and the force angle's minimum over its edges, state by state, where the NumPy
path (:func:`mmstab.terrain.polygon_batch.hulls_along_batch` and
:func:`mmstab.stability.static.padded_axis_angles`) works on padded arrays of all states at
once. The states it leaves (fewer than three contacts, nearly a line, two hull vertices
closer than :data:`mmstab.terrain.polygon.MIN_EDGE`) go the per-state way, as the NumPy
path's do. Compiled on first use (:mod:`mmstab.core.clib`); without a C compiler the NumPy
path runs (its twin, tested against it).
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mmstab.core.clib import BYTES, DOUBLE, DOUBLES, LONG, optional_kernel
from mmstab.terrain.polygon import MIN_EDGE, plane_axes

SOURCE = Path(__file__).with_name("support_mu.c")  #: the kernel's C source

FloatArray = NDArray[np.float64]


@lru_cache(maxsize=1)
def _kernel() -> Any:
    """The compiled ``mmstab_support_mu``, or None (no C compiler)."""
    return optional_kernel(SOURCE, "mmstab_support_mu", [
        LONG, LONG, DOUBLES, BYTES, DOUBLES, DOUBLES, DOUBLES, DOUBLES, DOUBLES, DOUBLE,
        DOUBLES, BYTES,
    ])  # fmt: skip


def support_mu_c(
    points_body: FloatArray,
    bearing: NDArray[np.bool_],
    G_T_B: FloatArray,
    com_body: FloatArray,
    force_G: FloatArray,
) -> tuple[FloatArray, NDArray[np.bool_]] | None:
    """(μ [N rad] (N,), settled (N,)) of N states on their bearing candidates, or None.

    Args:
        points_body: the contact candidates in B (K, 3) [m].
        bearing: which candidates bear each state's load (N, K).
        G_T_B: the states' rests (N, 4, 4).
        com_body: the states' overall CoM in B (N, 3) [m].
        force_G: the net force in G (3,) [N].

    Returns:
        μ where settled (NaN elsewhere) and which states the kernel settled; None when no C
        compiler is at hand.
    """
    f = _kernel()
    if f is None:
        return None
    n, K = bearing.shape
    force = np.ascontiguousarray(force_G, dtype=np.float64)
    u, v = plane_axes(force)
    mu = np.full(n, np.nan)
    ok = np.zeros(n, dtype=np.uint8)
    status = f(n, K, np.ascontiguousarray(points_body, dtype=np.float64),
               np.ascontiguousarray(bearing, dtype=np.uint8),
               np.ascontiguousarray(G_T_B, dtype=np.float64),
               np.ascontiguousarray(com_body, dtype=np.float64), force,
               np.ascontiguousarray(u), np.ascontiguousarray(v), MIN_EDGE, mu, ok)  # fmt: skip
    if status != 0:
        raise MemoryError("mmstab_support_mu: out of memory")
    return mu, ok.astype(bool)
