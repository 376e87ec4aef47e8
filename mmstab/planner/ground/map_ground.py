"""The ground under the arm on each live map (``online: {planner: roadmap}``).

The offline ``method: roadmap`` keeps the arm ``planner.ground_clearance`` above the terrain
under it at every pose, through body tilts up to ``planner.attitude_margin``
(:class:`mmstab.planner.ground.under_arm.GroundUnderArm`). Online the same measure runs on each
map, at the horizon's poses rested on it (their ``M_T_B`` from the batched rest):

- **scoring**: a pose (re-)scored on a map gets its candidates from ``route_candidates``
  with that map's ground at the pose (:meth:`MapGround.under`), so a node too low there is
  replaced, not just dropped;
- **verifying**: on every map each planned pose's chosen node is measured on the map
  (:meth:`MapGround.node_clear`), one node per pose: first a bound from the map's cells (the
  ground's rise above the support plane is bilinear minus linear in each cell, so its max
  over a square lies at the corners of the cells the square meets), then, for the pieces
  that bound does not clear, the scoring's own value (the pose's peak at the piece:
  :meth:`PoseGround._peak_at`, the C kernel's or the tiles'), so a node the scoring took
  is not rejected by its check on the same ground;
- **unknown cells** (NaN in the map, or off its window) under the arm count as high as the
  highest mapped ground within the arm's reach at the pose (:meth:`MapGround.reach`: its
  largest rise above the support plane over the map's cells there, 0 at least): an arm
  passes over an unmapped patch only ``ground_clearance`` above everything it could reach
  there, so a patch (a shadow behind a bump, the sensor's range) hides nothing the map
  shows around it, and the check keeps its bound on the highest ground (a +inf fill
  forbids every posture over a patch but checks every piece of every node: 50 against 21
  ms per scoring on the rough route). A pose scored while unknown cells lay within its
  arm's reach is scored again on the first map that maps the whole reach; the poses whose
  chosen arm passes over unknown cells are counted (``arm_ground`` in the summary).
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from mmstab.model.robot import FloatArray, Robot
from mmstab.planner.ground.kernel import kernel_available
from mmstab.planner.ground.map_lattice import (
    FilledTiles,
    LatticePeaks,
    MapPoseGround,
    MapTiles,
)
from mmstab.planner.ground.under_arm import (
    BLOCK,
    LATTICE,
    SLACK,
    GroundUnderArm,
    KeptPieces,
    PiecesB,
    PoseGround,
    plane_z,
)
from mmstab.terrain.heightmap_terrain import HeightmapTerrain

#: Largest change of a pose's rest ``M_T_B`` between maps [m, -] that keeps its state.
SAME_REST = 1e-6


class ArmGround(NamedTuple):
    """What every map's check shares: the arm's pieces and squares (pose-independent).

    Attributes:
        base: a :class:`GroundUnderArm` whose poses each map replaces (robot, pieces, margin).
        cells: half-width of a piece's square [lattice steps].
        reach: the ball in B holding the arm: centre [m], radius [m].
        kernel: the lattice's peaks by the C kernel (else the NumPy path's tiles).
    """

    base: GroundUnderArm
    cells: int
    reach: tuple[FloatArray, float]
    kernel: bool = False

    @classmethod
    def of(cls, robot: Robot, terrain: HeightmapTerrain, margin: float) -> ArmGround:
        """The robot's pieces, with ``margin`` [rad] (``planner.attitude_margin``).

        The lattice's peaks by the C kernel where it compiles (the same values, tested).
        """
        base = GroundUnderArm(robot, terrain, np.zeros((1, 3)), np.eye(4)[None], margin)
        proto = base.poses[0]
        return cls(base, proto.cells, proto.reach, kernel_available())


class PoseState:
    """A pose's ground on a map, and what was measured on it.

    Kept for the next map while the pose rests the same (``M_T_B`` within :data:`SAME_REST`:
    the batched rests differ by round-off) and the map's cells within the arm's
    reach are the same (NaN for NaN): the measures stand (made with the kept rest).

    Attributes:
        key: the reach box's cells in the map's global lattice of cells, and the window's edge.
        cells: the heights of the reach box's cells [m] (NaN: unknown).
        reach: unknown within the reach, and the fill [m] (:meth:`MapGround.reach`).
        M_T_B: the pose's resting body pose in M it was measured at (4, 4) [m].
        ground: the pose's lattice (built where pieces were looked at), made on first use
            by ``build`` (a map's check of the planned nodes mostly needs only its cells'
            bound: the lattice's set-up was a fifth of that check).
        known: per reach row: measured at this pose (N,).
        low: per reach row: measured too low (N,).
        checked: per reach row checked by :meth:`MapGround.node_clear`: (clear, over unknown).
    """

    __slots__ = (
        "key",
        "cells",
        "reach",
        "M_T_B",
        "_build",
        "_ground",
        "_rows",
        "_measured",
        "checked",
    )

    def __init__(
        self,
        key: tuple[tuple[int, ...], bool],
        cells: FloatArray,
        reach: tuple[bool, float],
        M_T_B: FloatArray,
        build: Callable[[], PoseGround],
        rows: int,
    ) -> None:
        self.key, self.cells, self.reach, self.M_T_B = key, cells, reach, M_T_B
        self._build: Callable[[], PoseGround] | None = build
        self._ground: PoseGround | None = None
        self._rows = rows
        self._measured: tuple[NDArray[np.bool_], NDArray[np.bool_]] | None = None
        self.checked: dict[int, tuple[bool, bool]] = {}

    def _masks(self) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
        if self._measured is None:  # a scoring's (the roadmap's reach: 2 x 262,000 rows)
            self._measured = np.zeros(self._rows, bool), np.zeros(self._rows, bool)
        return self._measured

    @property
    def known(self) -> NDArray[np.bool_]:
        """Per reach row: measured at this pose (N,) (made on first use, then the same)."""
        return self._masks()[0]

    @property
    def low(self) -> NDArray[np.bool_]:
        """Per reach row: measured too low (N,) (made on first use, then the same)."""
        return self._masks()[1]

    @property
    def ground(self) -> PoseGround:
        """The pose's lattice on the map that measured it (built once, on first use)."""
        if self._ground is None:
            assert self._build is not None
            self._ground, self._build = self._build(), None
        return self._ground


class MapGround:
    """The ground under the arm at the horizon's poses on one map (module text).

    Args:
        arm: the arm's pieces (:class:`ArmGround`).
        terrain: the map.
        M_T_B: resting body poses of the horizon's poses, by grid index (4, 4).
        rows: the reachable nodes (N, the measures' length).
        previous: the last map's, whose poses' states are kept where nothing changed.
    """

    def __init__(
        self,
        arm: ArmGround,
        terrain: HeightmapTerrain,
        M_T_B: dict[int, FloatArray],
        rows: int,
        previous: MapGround | None = None,
    ) -> None:
        self.arm, self.hm, self.M_T_B, self.rows = arm, terrain.heightmap, M_T_B, rows
        self.tiles: MapTiles = MapTiles(terrain, None if previous is None else previous.tiles)
        self.states: dict[int, PoseState] = {}
        self.previous = {} if previous is None else previous.states
        self.over_unknown: list[int] = []  # the poses node_clear found over unknown cells
        self._at = np.rint(self.hm.origin / self.hm.resolution).astype(int)  # its global cells

    def state(self, k: int) -> PoseState:
        """Pose ``k``'s state on this map: the last map's if nothing changed under the arm."""
        if k in self.states:
            return self.states[k]
        T, (c, r) = self.M_T_B[k], self.arm.reach
        centre = T[:3, :3] @ c + T[:3, 3]
        r = r + (self.arm.cells + 2 * BLOCK) * LATTICE
        lo, hi = self._cells(centre[:2] - r, centre[:2] + r)
        ny, nx = self.hm.shape
        edge = bool(lo[0] < 0 or lo[1] < 0 or hi[0] >= nx or hi[1] >= ny)
        lo, hi = np.maximum(lo, 0), np.minimum(hi, [nx - 1, ny - 1])
        z = self.hm.elevation[lo[1] : hi[1] + 1, lo[0] : hi[0] + 1]
        at = self._at  # the map's global cells
        key = ((*(lo + at), *(hi + at)), edge)
        old = self.previous.get(k)
        if (
            old is not None
            and old.key == key
            and np.abs(old.M_T_B - T).max() <= SAME_REST
            and np.array_equal(old.cells, z, equal_nan=True)
        ):
            self.states[k] = old
            return old
        o, res = self.hm.origin, self.hm.resolution
        x = o[0] + res * np.arange(lo[0], hi[0] + 1)
        y = o[1] + res * np.arange(lo[1], hi[1] + 1)
        rise = z - plane_z(T, x[None, :], y[:, None])
        known = np.isfinite(rise)
        top = max(float(rise[known].max()) if known.any() else 0.0, 0.0)
        tiles, hm, arm = self.tiles, self.hm, self.arm

        def build() -> PoseGround:  # this map's lattice at the pose (the same whenever built)
            ground = MapPoseGround(FilledTiles(tiles, T, top), T, arm.cells, arm.reach)  # type: ignore[arg-type]
            ground.top = top
            if arm.kernel:
                half = -(-arm.cells // BLOCK)
                ground.peaks = LatticePeaks(hm, T, top, half, centre, arm.reach[1])
            return ground

        st = PoseState(key, z, (edge or not known.all(), top), T, build, self.rows)
        self.states[k] = st
        return st

    def pose(self, k: int) -> PoseGround:
        """Pose ``k``'s ground (built lazily, kept while its map is unchanged)."""
        return self.state(k).ground

    def under(self, ks: list[int]) -> GroundUnderArm:
        """A :class:`GroundUnderArm` of poses ``ks`` (its pose i is ``ks[i]``)."""
        g = copy.copy(self.arm.base)
        g.poses = [self.pose(k) for k in ks]
        return g

    def reach(self, k: int) -> tuple[bool, float]:
        """Pose k's unknown within the arm's reach (a NaN cell, the window's edge) and fill.

        The fill: the largest rise [m] of the mapped ground there above the support plane
        (over the map's cells; 0 at least).
        """
        return self.state(k).reach

    def _cells(self, xy0: FloatArray, xy1: FloatArray) -> tuple[NDArray[np.intp], ...]:
        """Grid nodes (ix, iy) bounding the cells that meet the rectangle xy0..xy1 [m]."""
        o, res = self.hm.origin, self.hm.resolution
        lo = np.floor((np.asarray(xy0) - o) / res).astype(np.intp)
        hi = np.ceil((np.asarray(xy1) - o) / res).astype(np.intp)
        return lo, hi

    def node_clear(
        self, ks: list[int], rows: NDArray[np.intp], kept: KeptPieces, ground: float
    ) -> NDArray[np.bool_]:
        """Whether each pose ``ks[i]``'s node (``kept``'s row ``rows[i]``) is ``ground`` [m] up.

        The cells' bound for every piece, the scoring's value for the pieces it leaves
        (module text); an answer kept with the pose's state. Sets :attr:`over_unknown`.
        """
        st = [self.state(k) for k in ks]
        todo = [i for i, (x, r) in enumerate(zip(st, rows, strict=True)) if int(r) not in x.checked]
        if todo:
            sub = [ks[i] for i in todo]
            clear, over = self._node_clear(sub, kept(rows[todo]), ground)
            for j, i in enumerate(todo):
                st[i].checked[int(rows[i])] = (bool(clear[j]), bool(over[j]))
        answer = [x.checked[int(r)] for x, r in zip(st, rows, strict=True)]
        self.over_unknown = [k for k, a in zip(ks, answer, strict=True) if a[1]]
        return np.array([a[0] for a in answer], dtype=bool)

    def _node_clear(
        self, ks: list[int], body: PiecesB, ground: float
    ) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
        """Per pose ``ks[i]`` and posture (pieces row i): clear, and over unknown cells."""
        T = np.stack([self.state(k).M_T_B for k in ks])  # (n, 4, 4): the state's rest
        lowest = body.low / T[:, 2, 2, None]  # (n, P)
        c_M = np.einsum("nij,npj->npi", T[:, :3, :3], body.centre) + T[:, None, :3, 3]
        n, P = lowest.shape
        pose = np.repeat(np.arange(n), P)
        fill = np.array([self.reach(k)[1] for k in ks])[pose]
        rise, unknown = self._cell_bound(T[pose], c_M.reshape(-1, 3), fill)
        doubt = np.flatnonzero(lowest.ravel() - np.maximum(rise, 0.0) < ground - SLACK)
        ok = np.ones(n * P, dtype=bool)
        if doubt.size:
            ok[doubt] = self._lattice_test(
                [ks[x] for x in pose[doubt]],
                c_M.reshape(-1, 3)[doubt],
                lowest.ravel()[doubt],
                ground,
            )
        clear = np.asarray(ok.reshape(n, P).all(axis=1))
        return clear, np.asarray(unknown.reshape(n, P).any(axis=1))

    def _cell_bound(
        self, T: FloatArray, c_M: FloatArray, fill: FloatArray
    ) -> tuple[FloatArray, NDArray[np.bool_]]:
        """Per piece (centre (m, 3) [m], pose (m, 4, 4)): a bound of the rise over its square.

        And whether an unknown cell lies there (its rise ``fill`` (m,) [m]).
        The square holds the lattice samples the scoring's value covers, and a block more.
        """
        w = ((-(-self.arm.cells // BLOCK) + 1) * BLOCK + BLOCK) * LATTICE
        lo, hi = self._cells(c_M[:, :2] - w, c_M[:, :2] + w)
        m = int((hi - lo).max()) + 1
        ix, iy = lo[:, 0, None] + np.arange(m), lo[:, 1, None] + np.arange(m)  # (p, m)
        ny, nx = self.hm.shape
        inside = ((ix >= 0) & (ix < nx))[:, None, :] & ((iy >= 0) & (iy < ny))[:, :, None]
        z = self.hm.elevation[
            np.clip(iy, 0, ny - 1)[:, :, None], np.clip(ix, 0, nx - 1)[:, None, :]
        ]
        unknown = ~(inside & np.isfinite(z))  # (p, m, m): rows y, columns x
        o, res = self.hm.origin, self.hm.resolution
        x, y = o[0] + res * ix, o[1] + res * iy
        rise = np.where(
            unknown,
            fill[:, None, None],
            z - plane_z(T[:, None, None], x[:, None, :], y[:, :, None]),
        )
        flat = len(c_M), -1
        return np.asarray(rise.reshape(flat).max(axis=1)), unknown.reshape(flat).any(axis=1)

    def _lattice_test(
        self, ks: list[int], c_M: FloatArray, lowest: FloatArray, ground: float
    ) -> NDArray[np.bool_]:
        """The scoring's own test of pieces at poses ``ks`` (m,) (centres (m, 3) [m] in M).

        Each piece's peak is its pose's (:meth:`PoseGround.heights`' value, the C kernel's
        where it compiled, else the tiles'), its unknown filled as the scoring's; ``lowest``
        (m,) [m]: the pieces' lowest points over the support plane, vertically.
        """
        i = np.floor(c_M[:, 0] / LATTICE).astype(np.intp)
        j = np.floor(c_M[:, 1] / LATTICE).astype(np.intp)
        at = np.asarray(ks)
        peak = np.empty(len(c_M))
        for k in np.unique(at):
            of = at == k
            peak[of] = self.pose(int(k))._peak_at(i[of], j[of])
        h = np.where(peak > SLACK, lowest - peak, lowest)
        return np.asarray(h >= ground - SLACK)
