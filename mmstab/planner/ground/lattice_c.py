"""The ground's peaks under the arm's pieces on a live map: the C kernel (``lattice_peak.c``).

:class:`~mmstab.planner.ground.map_lattice.MapPoseGround` measures the arm's pieces against
the max of the ground's rise over a square about each (:meth:`PoseGround.heights`). The
NumPy path builds the lattice by tiles of 64 x 64 samples wherever a piece is looked at
(5 ms a scoring on the rough route, most of it on samples no piece's square needs); the
kernel computes a block's max, a row's and a peak only where a piece asks, and keeps them
for the pose (:class:`LatticePeaks`, kept with the pose's state while its map stands). Same
operations in the same order, so the same peaks (``tests/online/test_online_lattice.py``).
Compiled on first use (:mod:`mmstab.core.clib`); without a C compiler the NumPy path runs.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mmstab.core.clib import DOUBLE, DOUBLES, LONG, LONGS, kernel_function
from mmstab.core.files import MmstabError
from mmstab.model.robot import FloatArray
from mmstab.planner.ground.under_arm import BLOCK, LATTICE
from mmstab.terrain.heightmap import Heightmap

PEAK_NAME = "mmstab_lattice_peak"  #: the kernel's C symbol
PEAK_SOURCE = Path(__file__).with_name("lattice_peak.c")  #: its C source

_D, _L, _long, _double = DOUBLES, LONGS, LONG, DOUBLE


@lru_cache(maxsize=1)
def _kernel() -> Any:
    # elev ny nx origin res | plane steps sizes | blocks rows peaks | i j m out
    argtypes = [_D, _long, _long, _D, _double, _D, _D, _L, _D, _D, _D, _L, _L, _long, _D]
    return kernel_function(PEAK_SOURCE, PEAK_NAME, argtypes)


def kernel_available() -> bool:
    """Whether the kernel compiles and loads here (else the NumPy path is used)."""
    try:
        _kernel()
    except (MmstabError, OSError):
        return False
    return True


class LatticePeaks:
    """A pose's peaks of the rise on a map's lattice, computed where asked and kept.

    Args:
        hm: the map.
        M_T_B: the pose's resting body pose in M (4, 4).
        fill: the rise of an unknown sample above the support plane [m].
        half: the peak's half-width [blocks].
        centre: the arm's reach's centre in M (3,) [m].
        radius: a radius [m] holding every piece's centre about it.
    """

    def __init__(
        self, hm: Heightmap, M_T_B: FloatArray, fill: float, half: int, centre: FloatArray,
        radius: float,
    ) -> None:  # fmt: skip
        self.elev = np.ascontiguousarray(hm.elevation, dtype=np.float64)
        self.origin = np.ascontiguousarray(hm.origin, dtype=np.float64)
        self.res = float(hm.resolution)
        self.plane = np.ascontiguousarray(np.r_[M_T_B[:3, 2], M_T_B[:3, 3]], dtype=np.float64)
        self.steps = np.array([LATTICE, fill], dtype=np.float64)
        step = LATTICE * BLOCK
        lo = np.floor((centre[:2] - radius) / step).astype(np.int64) - half - 1
        hi = np.ceil((centre[:2] + radius) / step).astype(np.int64) + half + 1
        n = hi - lo + 1
        self.sizes = np.array([BLOCK, half, lo[0], lo[1], n[0], n[1]], dtype=np.int64)
        self._cache: NDArray[np.float64] | None = None  # blocks, rows, peaks: on first use

    def __call__(self, i: NDArray[np.intp], j: NDArray[np.intp]) -> FloatArray | None:
        """The peaks [m] at lattice samples (i, j) (m,); None if one lies off the cache."""
        if self._cache is None:
            self._cache = np.full((3, int(self.sizes[5]), int(self.sizes[4])), np.nan)
        out = np.empty(len(i))
        ny, nx = self.elev.shape
        code = _kernel()(
            self.elev, ny, nx, self.origin, self.res, self.plane, self.steps, self.sizes,
            self._cache[0], self._cache[1], self._cache[2],
            np.ascontiguousarray(i, dtype=np.int64), np.ascontiguousarray(j, dtype=np.int64),
            len(i), out,
        )  # fmt: skip
        return out if code == 0 else None
