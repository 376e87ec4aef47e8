"""The ground under the arm on each live map (``online: {planner: roadmap}``).

The offline ``method: roadmap`` keeps the arm ``planner.ground_clearance`` above the terrain
under it at every pose, through body tilts up to ``planner.attitude_margin``
(:class:`mmstab.planner.under_arm.GroundUnderArm`). Online the same measure runs on each
map, at the horizon's poses rested on it (their ``M_T_B`` from the batched rest):

- **scoring**: a pose (re-)scored on a map gets its candidates from ``route_candidates``
  with that map's ground at the pose (:meth:`MapGround.under`), so a node too low there is
  replaced, not just dropped;
- **verifying**: on every map each planned pose's chosen node is measured on the map
  (:meth:`MapGround.node_clear`), one node per pose: first a bound from the map's cells (the
  ground's rise above the support plane is bilinear minus linear in each cell, so its max
  over a square lies at the corners of the cells the square meets), then, for the pieces
  that bound does not clear, the scoring's own value (the max over the same lattice
  samples and blocks), so a node the scoring took is not rejected by its check on the
  same ground;
- **unknown cells**: a lattice sample on an unknown (NaN) cell or off the map's window is
  infinitely high: an arm piece whose square meets one is never clear, so the arm is kept
  over mapped ground (the robot's footprint is mapped wherever it rests, and a pose whose
  contacts are not is not planned at all). A pose scored while unknown cells lay within its
  arm's reach (:meth:`MapGround.reach_unknown`, on the map's cells) had its candidates cut
  to the mapped side; it is scored again on the first map that maps its whole reach.
"""

from __future__ import annotations

import copy
import dataclasses
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from mmstab.model.robot import FloatArray, Robot
from mmstab.planner.candidates import NodeClearance
from mmstab.planner.under_arm import (
    BLOCK,
    LATTICE,
    SLACK,
    TILE,
    GroundTiles,
    GroundUnderArm,
    KeptPieces,
    PiecesB,
    PoseGround,
)
from mmstab.terrain.heightmap_terrain import HeightmapTerrain


class MapTiles(GroundTiles):
    """A live map's ground on the lattice; unknown or off the window: +inf (module text)."""

    def _tile(self, ti: int, tj: int) -> FloatArray:
        if (ti, tj) not in self.tiles:
            x = (ti * TILE + np.arange(TILE)) * LATTICE
            y = (tj * TILE + np.arange(TILE)) * LATTICE
            X, Y = np.meshgrid(x, y)
            hm = self.terrain.heightmap  # type: ignore[attr-defined]
            z = hm.sample(np.stack([X, Y], axis=-1)).height  # NaN where unknown or off
            self.tiles[ti, tj] = np.where(np.isnan(z), np.inf, z)  # G = M on a map
        return self.tiles[ti, tj]


class ArmGround(NamedTuple):
    """What every map's check shares: the arm's pieces and squares (pose-independent).

    Attributes:
        base: a :class:`GroundUnderArm` whose poses each map replaces (robot, pieces, margin).
        cells: half-width of a piece's square [lattice steps].
        reach: the ball in B holding the arm: centre [m], radius [m].
    """

    base: GroundUnderArm
    cells: int
    reach: tuple[FloatArray, float]

    @classmethod
    def of(cls, robot: Robot, terrain: HeightmapTerrain, margin: float) -> ArmGround:
        """The robot's pieces, with ``margin`` [rad] (``planner.attitude_margin``)."""
        base = GroundUnderArm(robot, terrain, np.zeros((1, 3)), np.eye(4)[None], margin)
        proto = base.poses[0]
        return cls(base, proto.cells, proto.reach)


class MapGround:
    """The ground under the arm at the horizon's poses on one map (module text).

    Args:
        arm: the arm's pieces (:class:`ArmGround`).
        terrain: the map.
        M_T_B: resting body poses of the horizon's poses, by grid index (4, 4).
    """

    def __init__(self, arm: ArmGround, terrain: HeightmapTerrain, M_T_B: dict[int, FloatArray]):
        self.arm, self.hm, self.M_T_B = arm, terrain.heightmap, M_T_B
        self.tiles = MapTiles(terrain)
        self.poses: dict[int, PoseGround] = {}

    def pose(self, k: int) -> PoseGround:
        """Pose ``k``'s ground (built lazily, kept for this map)."""
        if k not in self.poses:
            a = self.arm
            self.poses[k] = PoseGround(self.tiles, self.M_T_B[k], a.cells, a.reach)
        return self.poses[k]

    def under(self, ks: list[int]) -> GroundUnderArm:
        """A :class:`GroundUnderArm` of poses ``ks`` (its pose i is ``ks[i]``)."""
        g = copy.copy(self.arm.base)
        g.poses = [self.pose(k) for k in ks]
        return g

    def reach_unknown(self, k: int) -> bool:
        """Whether an unknown cell (or the window's edge) lies within the arm's reach at k."""
        T, (c, r) = self.M_T_B[k], self.arm.reach
        centre = T[:3, :3] @ c + T[:3, 3]
        r = r + (self.arm.cells + 2 * BLOCK) * LATTICE
        lo, hi = self._cells(centre[:2] - r, centre[:2] + r)
        ny, nx = self.hm.shape
        if lo[0] < 0 or lo[1] < 0 or hi[0] >= nx or hi[1] >= ny:
            return True
        return bool(np.isnan(self.hm.elevation[lo[1] : hi[1] + 1, lo[0] : hi[0] + 1]).any())

    def _cells(self, xy0: FloatArray, xy1: FloatArray) -> tuple[NDArray[np.intp], ...]:
        """Grid nodes (ix, iy) bounding the cells that meet the rectangle xy0..xy1 [m]."""
        o, res = self.hm.origin, self.hm.resolution
        lo = np.floor((np.asarray(xy0) - o) / res).astype(np.intp)
        hi = np.ceil((np.asarray(xy1) - o) / res).astype(np.intp)
        return lo, hi

    def node_clear(self, ks: list[int], body: PiecesB, ground: float) -> NDArray[np.bool_]:
        """Whether each pose ``ks[i]``'s posture (pieces ``body`` row i) is ``ground`` [m] up.

        The cells' bound for every piece, the scoring's value for the pieces it leaves
        (module text). Unknown under a piece: not clear.
        """
        ok = np.ones(len(ks), dtype=bool)
        for i, k in enumerate(ks):
            pose = self.pose(k)
            T = pose.M_T_B
            lowest = body.low[i] / pose.cos_tilt
            c_M = body.centre[i] @ T[:3, :3].T + T[:3, 3]
            rise = self._cell_bound(T, c_M)
            doubt = np.flatnonzero(lowest - np.maximum(rise, 0.0) < ground - SLACK)
            if doubt.size:
                ok[i] = bool(np.all(self._lattice_peak(pose, c_M[doubt], lowest[doubt], ground)))
        return ok

    def _square(self) -> float:
        """Half-width [m] of the lattice samples a piece's value covers, and a block more."""
        return ((-(-self.arm.cells // BLOCK) + 1) * BLOCK + BLOCK) * LATTICE

    def _cell_bound(self, T: FloatArray, c_M: FloatArray) -> FloatArray:
        """Per piece centre (P, 3) [m]: an upper bound of the ground's rise over its square."""
        w = self._square()
        lo, hi = self._cells(c_M[:, :2] - w, c_M[:, :2] + w)
        m = int((hi - lo).max()) + 1
        ix = lo[:, 0, None] + np.arange(m)  # (P, m)
        iy = lo[:, 1, None] + np.arange(m)
        ny, nx = self.hm.shape
        inside = ((ix >= 0) & (ix < nx))[:, None, :] & ((iy >= 0) & (iy < ny))[:, :, None]
        z = self.hm.elevation[
            np.clip(iy, 0, ny - 1)[:, :, None], np.clip(ix, 0, nx - 1)[:, None, :]
        ]
        z = np.where(inside & np.isfinite(z), z, np.inf)  # (P, m, m): rows y, columns x
        o, res = self.hm.origin, self.hm.resolution
        x, y = o[0] + res * ix, o[1] + res * iy
        rise = z - _plane(T, x[:, None, :], y[:, :, None])
        return np.asarray(rise.reshape(len(c_M), -1).max(axis=1))

    def _lattice_peak(
        self, pose: PoseGround, c_M: FloatArray, lowest: FloatArray, ground: float
    ) -> NDArray[np.bool_]:
        """The scoring's test for pieces at centres (n, 3) [m]: lattice samples, by blocks.

        :meth:`PoseGround.heights`' peak at a centre's sample is the max of the rise over
        the blocks within ``ceil(cells / BLOCK)`` blocks of the sample's block.
        """
        half = -(-self.arm.cells // BLOCK)
        i = np.floor(c_M[:, 0] / LATTICE).astype(np.intp) // BLOCK
        j = np.floor(c_M[:, 1] / LATTICE).astype(np.intp) // BLOCK
        n = (2 * half + 1) * BLOCK
        out = np.empty(len(c_M), dtype=bool)
        for p in range(len(c_M)):
            x = ((i[p] - half) * BLOCK + np.arange(n)) * LATTICE
            y = ((j[p] - half) * BLOCK + np.arange(n)) * LATTICE
            X, Y = np.meshgrid(x, y)
            z = self.hm.sample(np.stack([X, Y], axis=-1)).height
            rise = np.where(np.isnan(z), np.inf, z) - _plane(pose.M_T_B, x[None, :], y[:, None])
            peak = float(rise.max())
            h = lowest[p] - peak if peak > SLACK else lowest[p]
            out[p] = h >= ground - SLACK
        return out


def _plane(T: FloatArray, x: FloatArray, y: FloatArray) -> FloatArray:
    """The support plane z_B = 0 of body pose ``T`` in M: its z_M [m] at x, y [m]."""
    n, o = T[:3, 2], T[:3, 3]
    return np.asarray(o[2] - (n[0] * (x - o[0]) + n[1] * (y - o[1])) / n[2])


def clearance_on(base: NodeClearance, under: GroundUnderArm, kept: KeptPieces) -> NodeClearance:
    """``base``'s test with the ground ``under`` the arm; its pose-independent parts shared.

    The eligibility of the reachable nodes and their pieces in B (``kept``) are computed
    once for the run, not per map.
    """
    clear = dataclasses.replace(base, under=under, excluded={}, _low={}, _known={})
    clear.__dict__.update(above=base.above, _eligible=base.eligible(), _pieces=kept)
    return clear
