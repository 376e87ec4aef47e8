"""The ground under the arm at each planned pose (``planner.ground_clearance`` on terrain).

:func:`mmstab.model.plane_clearance.arm_ground_clearance` measures the arm against the
support plane z_B = 0; on uneven ground the terrain under the arm rises above that plane (a
kerb, a bump); the online loop runs this same check on each live map
(:mod:`mmstab.planner.ground.map_ground`).
Here a pose's check reads the terrain through its interface only (``M_T_B``, ``G_T_M``,
``surface_G``, ``bounds``): the height of an arm point above the ground is its z in the map
frame M less the ground's z_M at the point's map x, y (vertical in M).

With the support plane in M, ``z = P(x, y)``, and ``c`` the cosine of the body's tilt
(``M_T_B``'s z-z entry), a point p of the arm is ``z_B(p) / c`` above the plane, vertically,
so its height above the ground is ``z_B(p) / c − r(x, y)`` with ``r = s − P`` the ground's
rise above the support plane (0 on a plane: the slope is not counted twice). The arm's
collision shapes are cut into pieces (:func:`arm_pieces`: a capsule into segments of at most
``arm_pieces.PIECE`` [m], a box into boxes of edges at most that); a piece is at least
``z_low / c − max(r, 0)`` above the ground, ``z_low`` its lowest point in B, the max over a
square about its centre's map x, y that holds the ball around the piece and :data:`SWEEP`
more (a move's samples). ``r`` is sampled on a lattice of :data:`LATTICE` [m] aligned to M's
origin, and a square's max is that of the :data:`BLOCK` x :data:`BLOCK` blocks of samples
that cover it (the square widened by less than a block): exact for a map whose cells'
corners lie on the lattice (bilinear or triangle cells: a surface linear or bilinear within
each lattice cell peaks at the cell's corners), which holds for the shipped maps (2 and 5
cm cells); on another map the ground between samples may rise above them by its slope times
the lattice step. Beyond a map's edge the edge's ground is used. On a plane ``r`` is 0 and
the check is ``z_B / c ≥ z_B``: the planner keeps the plane check too, so on a plane nothing
changes. A move's samples leave the pieces over ground not above the support plane to the
plane check (its own, denser samples), so on a plane a move is not checked twice either.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any, Literal, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import maximum_filter

from mmstab.model.plane_clearance import tilted_height
from mmstab.model.robot import FloatArray, Robot
from mmstab.planner.ground.arm_pieces import ArmPieces, arm_pieces, arm_reach
from mmstab.terrain import Terrain
from mmstab.terrain.base import GridHeights

#: Lattice step of the ground's samples in M [m] (the shipped maps' cells are multiples).
LATTICE = 0.01
#: Largest move of an arm point between the sampled postures of a move [m]: the squares
#: are widened by it, so the ground under the arm between two samples counts.
SWEEP = 0.01
#: Round-off allowance of the height test [m] (the plane case equals the plane check).
SLACK = 1e-9
#: Samples along a block's edge: the squares' max is taken over blocks (4x fewer values)
BLOCK = 2
#: Lattice samples along a tile's edge (the ground is sampled by tiles, kept for a route).
TILE = 64
#: Rows of arm pieces :class:`KeptPieces` makes room for at first (1.3 kB a row, 43 MB).
FIRST_ROWS = 32768
#: Who computes the pieces, the peak maps and the heights: the C kernel (default) or its NumPy twin.
Backend = Literal["c", "numpy"]


class PiecesB(NamedTuple):
    """Pieces of many postures in B: lowest z (n, P) [m] and centres (n, P, 3) [m]."""

    low: FloatArray
    centre: FloatArray


class KeptRows(NamedTuple):
    """Pieces of n postures read where they are kept (:meth:`KeptPieces.view`).

    Posture i's pieces are row ``at[i]`` of ``low`` (m, P) [m] and ``centre`` (m, P, 3) [m].
    """

    low: FloatArray
    centre: FloatArray
    at: NDArray[np.intp]

    def pieces(self) -> PiecesB:
        """The rows' pieces copied out (n, P) and (n, P, 3)."""
        return PiecesB(self.low[self.at], self.centre[self.at])


def pieces_in_body(
    robot: Robot,
    pieces: ArmPieces,
    postures: ArrayLike,
    margin: float = 0.0,
    backend: Backend = "numpy",
) -> PiecesB:
    """Each piece's lowest point z_B and centre in B for postures (n, 4) [rad].

    ``margin`` [rad]: the lowest over the body's tilts up to it (:func:`tilted_height`).
    ``backend``: ``numpy`` (here) or ``c`` (:mod:`mmstab.planner.ground.kernel`, its twin).
    """
    q = np.atleast_2d(np.asarray(postures, dtype=float))
    frames = robot.kinematics.link_frames(q)  # (n, links, 4, 4)
    if backend == "c":
        from mmstab.planner.ground.kernel import pieces_kernel

        return PiecesB(*pieces_kernel(frames, pieces.link, pieces.points, pieces.radius, margin))
    low = np.empty((len(q), len(pieces.link)))
    centre = np.empty((len(q), len(pieces.link), 3))
    mid = pieces.points.mean(axis=1)  # (P, 3)
    for i in np.unique(pieces.link):  # one product per link: (n, 3) @ (3, points)
        at = np.flatnonzero(pieces.link == i)
        R, t = frames[:, i, :3, :3], frames[:, i, :3, 3]
        pts = pieces.points[at].reshape(-1, 3)
        if margin == 0.0:
            z = R[:, 2] @ pts.T + t[:, 2, None]
        else:  # every point in B, then its least height over the tilts
            z = tilted_height(np.einsum("nij,mj->nmi", R, pts) + t[:, None, :], margin)
        low[:, at] = z.reshape(len(q), len(at), -1).min(axis=2) - pieces.radius[at]
        for r in range(3):
            centre[:, at, r] = R[:, r] @ mid[at].T + t[:, r, None]
    return PiecesB(low, centre)


def plane_z(T: FloatArray, x: FloatArray, y: FloatArray) -> FloatArray:
    """The support plane z_B = 0 of body pose(s) ``T`` (..., 4, 4) in M: z_M [m] at x, y [m].

    One arithmetic for every user (:meth:`PoseGround._build`, the live map's fill and cells'
    bound), so the same values on the same samples.
    """
    n, o = T[..., :3, 2], T[..., :3, 3]
    return np.asarray(
        o[..., 2] - (n[..., 0] * (x - o[..., 0]) + n[..., 1] * (y - o[..., 1])) / n[..., 2]
    )


class GroundTiles:
    """The ground's z_M on the lattice, sampled by tiles of :data:`TILE` samples and kept."""

    def __init__(self, terrain: Terrain) -> None:
        self.terrain = terrain
        self.M_T_G = np.linalg.inv(terrain.G_T_M())
        self.tiles: dict[tuple[int, int], FloatArray] = {}
        self.nonfinite: set[tuple[int, int]] = set()  # tiles with a NaN or an infinity

    def _tile(self, ti: int, tj: int) -> FloatArray:
        if (ti, tj) not in self.tiles:
            self._sample([(ti, tj)])
        return self.tiles[ti, tj]

    def _sample(self, keys: list[tuple[int, int]]) -> None:
        """Sample tiles ``keys`` (ti, tj) in one call of the terrain.

        The terrain's surface is elementwise, and the product with M's z row is taken per
        row of a tile (``(TILE, 3) @ (3,)``) as for a tile alone: the same values.
        """
        at = np.asarray(keys, dtype=np.intp).reshape(-1, 2)
        x = (at[:, :1] * TILE + np.arange(TILE)) * LATTICE  # (k, TILE)
        y = (at[:, 1:] * TILE + np.arange(TILE)) * LATTICE
        if isinstance(self.terrain, GridHeights):  # the same values, a tile's rows at once
            b = self.terrain.bounds
            if b is not None:
                x, y = np.clip(x, b[0], b[1]), np.clip(y, b[2], b[3])
            for key, xk, yk in zip(keys, x, y, strict=True):
                self._keep(key, self.terrain.height_grid_M(xk, yk))
            return
        shape = (len(at), TILE, TILE)  # each tile (y, x) as numpy.meshgrid lays it
        X, Y = np.broadcast_to(x[:, None, :], shape), np.broadcast_to(y[:, :, None], shape)
        b = self.terrain.bounds
        if b is not None:  # beyond the map's edge: the edge's ground
            X, Y = np.clip(X, b[0], b[1]), np.clip(Y, b[2], b[3])
        p_G = self.terrain.surface_G(X, Y)
        z = p_G @ self.M_T_G[2, :3] + self.M_T_G[2, 3]  # a tile's (TILE, 3) @ (3,) each
        for key, tile in zip(keys, z, strict=True):
            self._keep(key, tile)

    def _keep(self, key: tuple[int, int], tile: FloatArray) -> None:
        self.tiles[key] = np.ascontiguousarray(tile)
        if not np.isfinite(tile).all():
            self.nonfinite.add(key)

    def mosaic(self, box: tuple[int, int, int, int]) -> list[list[FloatArray]]:
        """The tiles ``box = (ti0, ti1, tj0, tj1)`` (inclusive), by rows along y."""
        ti0, ti1, tj0, tj1 = box
        rows, cols = range(tj0, tj1 + 1), range(ti0, ti1 + 1)
        new = [(ti, tj) for tj in rows for ti in cols if (ti, tj) not in self.tiles]
        if len(new) > 1 and type(self)._tile is GroundTiles._tile:  # one call for the new
            self._sample(new)
        return [[self._tile(ti, tj) for ti in cols] for tj in rows]

    def finite(self, box: tuple[int, int, int, int]) -> bool:
        """Whether the tiles ``box`` (built) are all finite."""
        return not any(
            box[0] <= ti <= box[1] and box[2] <= tj <= box[3] for ti, tj in self.nonfinite
        )

    def z_M(self, box: tuple[int, int, int, int]) -> FloatArray:
        """The ground's z_M [m] on tiles ``box = (ti0, ti1, tj0, tj1)`` (inclusive), (y, x)."""
        return np.vstack([np.hstack(row) for row in self.mosaic(box)])


@dataclasses.dataclass
class PoseGround:
    """One pose's ground rise above its support plane, on the lattice in M (module text).

    Args:
        tiles: the ground's samples (shared by a route's poses).
        M_T_B: the resting body pose in M (4, 4).
        cells: half-width of the squares the rise's max is taken over [lattice steps].
    """

    tiles: GroundTiles
    M_T_B: FloatArray
    cells: int
    reach: tuple[FloatArray, float] = (np.zeros(3), 0.0)  # arm within this ball in B [m]
    box: tuple[int, int, int, int] = (0, -1, 0, -1)  # tile index range (ti0, ti1, tj0, tj1)
    peak: FloatArray = dataclasses.field(default_factory=lambda: np.zeros((0, 0)))
    top: float = 0.0  # the peak's max [m]
    backend: Backend = "numpy"  # who computes the peak map and the heights

    @functools.cached_property
    def cos_tilt(self) -> float:
        """Cosine of the angle between B's z and M's z."""
        return float(self.M_T_B[2, 2])

    def _build(self, box: tuple[int, int, int, int]) -> None:
        """The rise's max over squares about every sample of tiles ``box``."""
        x = np.asarray((box[0] * TILE + np.arange((box[1] - box[0] + 1) * TILE)) * LATTICE, float)
        y = np.asarray((box[2] * TILE + np.arange((box[3] - box[2] + 1) * TILE)) * LATTICE, float)
        self.box, half = box, -(-self.cells // BLOCK)
        if self.backend == "c" and isinstance(self.tiles, GroundTiles):
            mosaic = self.tiles.mosaic(box)  # the tiles unstacked
            if self.tiles.finite(box) and np.isfinite(self.M_T_B).all():
                from mmstab.planner.ground.kernel import peak_map_kernel

                # the same values: the same rise, and a max is exact in any order
                origin = (box[0] * TILE, box[2] * TILE)
                _, self.peak, self.top = peak_map_kernel(
                    mosaic, origin, LATTICE, self.M_T_B, BLOCK, half
                )
                return
        rise = self.tiles.z_M(box) - plane_z(self.M_T_B, x[None, :], y[:, None])
        # the max over blocks of BLOCK x BLOCK samples, then over the squares of blocks that
        # hold every sample's square (module text): the squares widened by < BLOCK steps
        blocks = rise[::BLOCK, ::BLOCK].copy()
        for dj, di in np.ndindex(BLOCK, BLOCK):
            np.maximum(blocks, rise[dj::BLOCK, di::BLOCK], out=blocks)
        self.peak = maximum_filter(blocks, size=2 * half + 1, mode="nearest")
        self.top = float(blocks.max())

    def _cover(self, need: tuple[int, int, int, int] | None = None) -> None:
        """Build the tiles ``need`` (default: the arm's reach) with those built before."""
        b = self.box
        if not self.peak.size:  # first use: the whole arm's reach, one build
            c = self.M_T_B[:3, :3] @ self.reach[0] + self.M_T_B[:3, 3]
            r = self.reach[1] / LATTICE + self.cells + 2 * BLOCK
            lo, hi = np.floor((c[:2] / LATTICE - r) / TILE), np.floor((c[:2] / LATTICE + r) / TILE)
            b = (int(lo[0]), int(hi[0]), int(lo[1]), int(hi[1]))
        elif need is None or (
            need[0] >= b[0] and need[1] <= b[1] and need[2] >= b[2] and need[3] <= b[3]
        ):
            return
        n = b if need is None else need
        self._build((min(n[0], b[0]), max(n[1], b[1]), min(n[2], b[2]), max(n[3], b[3])))

    @property
    def highest(self) -> float:
        """The ground's largest rise above the support plane within the arm's reach [m]."""
        self._cover()
        return self.top

    def heights(
        self, body: PiecesB | KeptRows, above: float = -np.inf, plane: bool = False
    ) -> FloatArray:
        """Each posture's least height above the ground under the arm (n,) [m] (module text).

        A lower bound: a piece is ``z_low / c − max(r, 0)`` up. Pieces at least ``above``
        [m] over the highest ground in reach are not looked at closer (where the answer is
        ``above`` or more it is only that). ``plane``: the pieces over ground not above the
        support plane are left to the plane check (+inf; a move's samples, module text).
        ``body``: the postures' pieces, or their rows where they are kept (the C kernel
        reads them there; the same values).
        """
        self._cover()
        rows = body.at if isinstance(body, KeptRows) else None
        if self.backend == "c" and len(body.low) and (rows is None or len(rows)):
            from mmstab.planner.ground.kernel import heights_kernel

            h_c = heights_kernel(
                body.low, body.centre, self.M_T_B, self.top, above, plane, self.peak,
                (self.box[0] * TILE, self.box[2] * TILE), BLOCK, self.cells + 2 * BLOCK,
                LATTICE, SLACK, rows,
            )  # fmt: skip
            if h_c is not None:
                return h_c  # else a square leaves the map: widened below, as NumPy does
        if isinstance(body, KeptRows):
            body = body.pieces()
        lowest = body.low / self.cos_tilt
        h = lowest - max(self.top, 0.0)
        look = np.flatnonzero(h.ravel() < above)
        c_M = body.centre.reshape(-1, 3)[look] @ self.M_T_B[:3, :3].T + self.M_T_B[:3, 3]
        peak = self._peak_at(*np.floor(c_M[:, :2].T / LATTICE).astype(int))
        off = np.inf if plane else lowest.ravel()[look]  # where the plane check decides
        h.ravel()[look] = np.where(peak > SLACK, lowest.ravel()[look] - peak, off)
        return np.asarray(h.min(axis=1)) if h.size else np.zeros(len(h))

    def _peak_at(self, i: NDArray[np.intp], j: NDArray[np.intp]) -> FloatArray:
        """The rise's max over the squares about lattice samples (i, j) (m,) [m]."""
        if i.size:
            m = self.cells + 2 * BLOCK  # every square's blocks inside, not the filter's edge
            lo, hi = (int(i.min()) - m) // TILE, (int(i.max()) + m) // TILE
            self._cover((lo, hi, (int(j.min()) - m) // TILE, (int(j.max()) + m) // TILE))
        return self.peak[(j - self.box[2] * TILE) // BLOCK, (i - self.box[0] * TILE) // BLOCK]


class GroundUnderArm:
    """The ground under the arm at each of a route's poses (module text).

    Args:
        robot: the robot.
        terrain: the ground (its interface only).
        poses: base poses (K, 3) in M [m, m, rad].
        M_T_B: their resting body poses in M (K, 4, 4), if known (else rested here).
        margin: the body's tilt in motion the arm must clear the ground through [rad]
            (``planner.attitude_margin``,
            :func:`mmstab.model.plane_clearance.tilted_height`); 0: none.
        backend: ``c``: the pieces and heights by the C kernel
            (:mod:`mmstab.planner.ground.kernel`); ``numpy``: its twin, here.
    """

    def __init__(
        self,
        robot: Robot,
        terrain: Terrain,
        poses: ArrayLike,
        M_T_B: FloatArray | None = None,
        margin: float = 0.0,
        backend: Backend = "c",
    ) -> None:
        self.robot, self.margin, self.backend = robot, float(margin), backend
        self.pieces = arm_pieces(robot)
        p = np.atleast_2d(np.asarray(poses, dtype=float))
        T = terrain.M_T_B(p) if M_T_B is None else np.asarray(M_T_B, dtype=float)
        T = T.reshape(-1, 4, 4)
        tiles = GroundTiles(terrain)
        # one square for every piece: the largest ball and a sweep, one step more (module text)
        cells = int(np.ceil((float(self.pieces.ball.max()) + SWEEP) / LATTICE)) + 1
        reach = arm_reach(robot, self.pieces)
        self.poses = [PoseGround(tiles, T[k], cells, reach, backend=backend) for k in range(len(T))]

    def __len__(self) -> int:
        return len(self.poses)

    def body(self, postures: ArrayLike) -> PiecesB:
        """The arm's pieces in B for postures (n, 4) [rad] (pose-independent)."""
        return pieces_in_body(self.robot, self.pieces, postures, self.margin, self.backend)

    def heights(self, k: int, postures: ArrayLike, body: PiecesB | None = None) -> FloatArray:
        """Least height [m] above the ground under the arm at pose ``k``, per posture (n,)."""
        b = self.body(postures) if body is None else body
        return self.poses[k].heights(b, np.inf)

    def surely_clear(self, k: int, lowest: FloatArray, ground: float) -> NDArray[np.bool_]:
        """Whether arms whose pieces' least z_B is ``lowest`` (n,) [m] surely clear pose k.

        ``lowest``: the least over the pieces of their lowest points over the tilts
        (:meth:`body`; a roadmap's nodes': :func:`mmstab.planner.grounded.node_lowest`).
        :meth:`heights` takes a piece at least ``z_low / c − max(top, 0)`` up, ``top`` the
        ground's highest rise within the arm's reach (each step rounded the same way), so
        these arms pass :meth:`clear` without a closer look.
        """
        pose = self.poses[k]
        return np.asarray(lowest / pose.cos_tilt - max(pose.highest, 0.0) >= ground - SLACK)

    def clear(
        self, k: int, postures: ArrayLike, ground: float, body: PiecesB | KeptRows | None = None
    ) -> NDArray[np.bool_]:
        """Whether each posture (n, 4) [rad] keeps the arm ``ground`` [m] up at pose ``k``."""
        b = self.body(postures) if body is None else body
        return np.asarray(self.poses[k].heights(b, ground) >= ground - SLACK)

    def sweep_clear(
        self,
        ks: tuple[int, ...],
        q: ArrayLike,
        reach: FloatArray,
        ground: float,
        memo: dict[Any, Any] | None = None,
    ) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
        """Whether the polyline of postures q (n, 4) [rad] keeps the arm ``ground`` [m] up.

        At every pose of ``ks``; sampled so that no arm point moves more than :data:`SWEEP`
        between samples (``reach`` (4,) [m]: the bound Σ_j reach_j |Δq_j|). Returns per
        posture (n,) and per segment (n − 1,) whether it does. With a ``margin`` the
        pieces over the plane are checked here too (the plane check does not know it).
        ``memo``: the answers of earlier calls with the same ``ks`` and ``ground`` (the
        caller's, kept between them): a segment seen before is not sampled again. A
        posture's answer is its segment's last sample's, so the answers are the same.
        """
        qa = np.atleast_2d(np.asarray(q, dtype=float))
        memo = {} if memo is None else memo
        keys = [qa[0].tobytes()] + [
            (a.tobytes(), b.tobytes()) for a, b in zip(qa[:-1], qa[1:], strict=True)
        ]
        todo = [i for i, key in enumerate(keys) if key not in memo]
        if todo:
            parts = []
            for i in todo:  # 0: the first posture; i: segment i - 1, ending at posture i
                if i == 0:
                    parts.append(qa[:1])
                    continue
                a, b = qa[i - 1], qa[i]
                n = max(int(np.ceil(float(reach @ np.abs(b - a)) / SWEEP)), 1)
                parts.append(a + np.linspace(0.0, 1.0, n + 1)[1:, None] * (b - a))
            body = self.body(np.vstack(parts))
            plane = self.margin == 0.0
            ok = np.all(
                [self.poses[k].heights(body, ground, plane) >= ground - SLACK for k in ks],
                axis=0,
            )
            ends = np.cumsum([len(x) for x in parts])
            whole = np.logical_and.reduceat(ok, np.r_[0, ends[:-1]])  # every part non-empty
            for j, i in enumerate(todo):  # (the whole segment clears, its end clears)
                memo[keys[i]] = (bool(whole[j]), bool(ok[ends[j] - 1]))
        answers = [memo[key] for key in keys]
        node_ok = np.array([a[1] for a in answers], dtype=bool)  # posture 0's: its own sample
        seg_ok = np.array([a[0] for a in answers[1:]], dtype=bool)
        return node_ok, seg_ok


class KeptPieces:
    """The pieces in B of postures (N, 4) [rad], each computed once (pose-independent).

    Args:
        under: the ground under the arm (its robot and pieces).
        postures: the postures rows index (N, 4) [rad].
    """

    def __init__(self, under: GroundUnderArm, postures: FloatArray) -> None:
        self.under, self.postures = under, postures
        self.slot = np.full(len(postures), -1, dtype=np.intp)
        self.size, P = 0, len(under.pieces.link)  # rows kept; the arrays grow by doubling
        self.low, self.centre = np.zeros((0, P)), np.zeros((0, P, 3))

    def add(self, rows: NDArray[np.intp]) -> None:
        """Compute the pieces of ``rows`` not kept yet, in one batch."""
        new = np.unique(rows[self.slot[rows] < 0])  # those not kept, ascending
        if new.size:
            # by their joint angles, the first first: postures sharing their first joints
            # come together and the kernel reuses those links' pieces (the same values)
            new = new[np.lexsort(self.postures[new].T[::-1])]
            body = self.under.body(self.postures[new])
            end = self.size + len(new)
            if end > len(self.low):  # the kept rows copied, the new room left untouched
                # room for FIRST_ROWS at once: pages are only taken as rows are written
                size = max(end, 2 * len(self.low), min(len(self.postures), FIRST_ROWS))
                grown = [np.empty((size, *a.shape[1:])) for a in (self.low, self.centre)]
                for g, a in zip(grown, (self.low, self.centre), strict=True):
                    g[: self.size] = a[: self.size]
                self.low, self.centre = grown
            self.slot[new] = self.size + np.arange(len(new))  # (a copy per doubling only)
            self.low[self.size : end], self.centre[self.size : end] = body.low, body.centre
            self.size = end

    def __call__(self, rows: NDArray[np.intp]) -> PiecesB:
        """The pieces of ``rows`` (n,)."""
        return self.view(rows).pieces()

    def view(self, rows: NDArray[np.intp]) -> KeptRows:
        """The pieces of ``rows`` (n,) where they are kept (no copy)."""
        at = self.slot[rows]
        if (at < 0).any():
            self.add(rows)
            at = self.slot[rows]
        return KeptRows(self.low, self.centre, at)
