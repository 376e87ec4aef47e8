"""A live map's ground on the lattice of :mod:`mmstab.planner.ground.under_arm` (online).

:class:`GroundUnderArm` samples a terrain's ground on a 1 cm lattice aligned to M, by tiles;
on a live map (:class:`MapTiles`) an unknown (NaN) cell or one off the map's window makes
its samples +inf, and :class:`FilledTiles` puts them at a pose's fill above its support
plane (:mod:`mmstab.planner.ground.map_ground`). The samples are those of
:meth:`Heightmap.sample` (:func:`lattice_z`: the same arithmetic, separable), so the
verification of one node (:meth:`MapGround.node_clear`) reads the values the scoring read.

The tiles build the lattice by 64 x 64 samples wherever a piece is looked at (5 ms a
scoring on the rough route, most of it on samples no piece's square needs);
:class:`LatticePeaks` asks the C kernel (:func:`mmstab.planner.ground.kernel.lattice_peak_kernel`)
for a block's max, a row's and a peak only where a piece asks, and keeps them for the pose
(kept with the pose's state while its map stands). Same operations in the same order, so
the same peaks (``tests/online/test_online_lattice.py``); without a C compiler the tiles
answer.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from mmstab.model.robot import FloatArray
from mmstab.planner.ground.kernel import lattice_peak_kernel
from mmstab.planner.ground.under_arm import (
    BLOCK,
    LATTICE,
    TILE,
    GroundTiles,
    PoseGround,
    plane_z,
)
from mmstab.terrain.heightmap import Heightmap
from mmstab.terrain.heightmap_terrain import HeightmapTerrain


class MapTiles(GroundTiles):
    """A live map's ground on the lattice; unknown or off the window: +inf (module text).

    A tile whose map cells are those of the last map's tile (NaN for NaN) is taken from
    it: a fused map changes where the robot sees new ground, not everywhere.
    """

    def __init__(self, terrain: HeightmapTerrain, previous: MapTiles | None = None) -> None:
        super().__init__(terrain)
        self.cells: dict[tuple[int, int], FloatArray] = {}
        self.previous = previous
        if previous is not None:
            previous.previous = None  # one map back only: no chain of maps kept

    def _tile(self, ti: int, tj: int) -> FloatArray:
        if (ti, tj) not in self.tiles:
            x = np.asarray((ti * TILE + np.arange(TILE)) * LATTICE, float)
            y = np.asarray((tj * TILE + np.arange(TILE)) * LATTICE, float)
            hm = self.terrain.heightmap  # type: ignore[attr-defined]
            cells = _cells_under(hm, x, y)
            old = self.previous
            if (
                old is not None
                and (ti, tj) in old.cells
                and np.array_equal(old.cells[ti, tj], cells, equal_nan=True)
            ):
                self.tiles[ti, tj] = old.tiles[ti, tj]
            else:
                self.tiles[ti, tj] = lattice_z(hm, x, y)
            self.cells[ti, tj] = cells
        return self.tiles[ti, tj]


def _cells_under(hm: Heightmap, x: FloatArray, y: FloatArray) -> FloatArray:
    """The map's cells [m] that the bilinear heights at x, y [m] read (NaN beyond the map)."""
    ny, nx = hm.shape
    i0 = int(np.floor((x[0] - hm.origin[0]) / hm.resolution)) - 1
    i1 = int(np.floor((x[-1] - hm.origin[0]) / hm.resolution)) + 2
    j0 = int(np.floor((y[0] - hm.origin[1]) / hm.resolution)) - 1
    j1 = int(np.floor((y[-1] - hm.origin[1]) / hm.resolution)) + 2
    out = np.full((j1 - j0 + 1, i1 - i0 + 1), np.nan)
    a, b = max(i0, 0), min(i1, nx - 1)
    c, d = max(j0, 0), min(j1, ny - 1)
    if a <= b and c <= d:
        out[c - j0 : d - j0 + 1, a - i0 : b - i0 + 1] = hm.elevation[c : d + 1, a : b + 1]
    return out


def lattice_z(hm: Heightmap, x: FloatArray, y: FloatArray) -> FloatArray:
    """The map's bilinear heights (ny, nx) [m] at x (nx,), y (ny,) [m]; unknown or off: +inf.

    Separable (each map row along x, then between two rows along y): the same arithmetic
    as :meth:`Heightmap.sample` at each point, for a fraction of its cost on a lattice.
    """
    ny, nx = hm.shape
    u, v = (x - hm.origin[0]) / hm.resolution, (y - hm.origin[1]) / hm.resolution
    eps = 1e-9
    ix = np.clip(np.floor(u), 0, nx - 2).astype(np.intp)
    iy = np.clip(np.floor(v), 0, ny - 2).astype(np.intp)
    fx, fy = u - ix, v - iy
    rows = np.unique(np.concatenate([iy, iy + 1]))
    e = hm.elevation[rows]
    along = e[:, ix] + fx * (e[:, ix + 1] - e[:, ix])  # (rows, nx): each row at x
    a, b = along[np.searchsorted(rows, iy)], along[np.searchsorted(rows, iy + 1)]
    z = a + fy[:, None] * (b - a)
    inside = ((v >= -eps) & (v <= ny - 1 + eps))[:, None] & ((u >= -eps) & (u <= nx - 1 + eps))
    return np.where(inside & np.isfinite(z), z, np.inf)


class FilledTiles:
    """A map's lattice at one pose, its unknown samples ``fill`` [m] above the support plane."""

    def __init__(self, tiles: MapTiles, M_T_B: FloatArray, fill: float) -> None:
        self.tiles, self.M_T_B, self.fill = tiles, M_T_B, fill

    def z_M(self, box: tuple[int, int, int, int]) -> FloatArray:
        """The ground's z_M [m] on tiles ``box`` (:meth:`GroundTiles.z_M`), filled."""
        z = self.tiles.z_M(box)
        x = np.asarray((box[0] * TILE + np.arange((box[1] - box[0] + 1) * TILE)) * LATTICE, float)
        y = np.asarray((box[2] * TILE + np.arange((box[3] - box[2] + 1) * TILE)) * LATTICE, float)
        return filled(z, plane_z(self.M_T_B, x[None, :], y[:, None]), self.fill)


def filled(z: FloatArray, plane: FloatArray, fill: float) -> FloatArray:
    """Heights ``z`` [m] with the unknown (+inf) ``fill`` [m] above the plane's heights [m]."""
    unknown = np.isinf(z)
    return np.where(unknown, plane + fill, z) if unknown.any() else z


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
        return lattice_peak_kernel(
            self.elev, self.origin, self.res, self.plane, self.steps, self.sizes, self._cache,
            i, j,
        )  # fmt: skip


class MapPoseGround(PoseGround):
    """A pose's ground on a map, built only where the measured pieces reach.

    :class:`PoseGround` samples the whole arm's reach on first use, for its highest ground
    (``top``, the bound that clears high arms unlooked): 127,000 lattice samples, 7 ms. Here
    ``top`` is the map cells' bound over the reach (:meth:`MapGround.reach`, at least the
    samples' max), and the lattice is built around the pieces looked at; or, with
    ``peaks`` (:mod:`mmstab.planner.ground.kernel`), only its blocks the pieces need.
    """

    #: the C kernel's peaks at this pose (None: the NumPy path, the tiles)
    peaks: LatticePeaks | None = None

    def _peak_at(self, i: NDArray[np.intp], j: NDArray[np.intp]) -> FloatArray:
        """The rise's max over the squares about lattice samples (i, j) [m]: the kernel's."""
        if self.peaks is not None and i.size:
            peak = self.peaks(i, j)
            if peak is not None:
                return peak
        return super()._peak_at(i, j)

    def _cover(self, need: tuple[int, int, int, int] | None = None) -> None:
        if need is None:  # the reach's top: the cells' bound, set at construction
            return
        if not self.peak.size:
            self._build(need)
        else:
            super()._cover(need)

    def _build(self, box: tuple[int, int, int, int]) -> None:
        bound = self.top
        super()._build(box)
        self.top = bound  # the bound over the whole reach, not this box's max
