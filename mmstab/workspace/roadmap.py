"""The posture roadmap: the arm's collision-free configuration space as a lattice graph.

Nodes are V's collision-free grid postures (the workspace build labels them:
``Workspace.valid_q``), edges join grid neighbours (one step along one joint) whose
straight move is collision-free, checked with FCL
(:class:`mmstab.model.collision.CollisionChecker`) at interior postures spaced so that no
point of the arm moves more than ``resolution`` [m] between two checked postures
(``docs/workspace.md``, "Posture roadmap"). Connected components say which postures the arm
can reach from another; shortest paths (``scipy.sparse.csgraph``) give the motion.

Every edge's interior postures along joint j at fraction u of a step form the grid shifted
by u steps along j, so the collision checker's reuse of answers across postures of equal
relevant joints applies as in V's build: the roadmap costs a few V builds.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import os
import sys
import time
from collections.abc import Generator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components, dijkstra
from scipy.spatial import cKDTree
from tqdm import tqdm

from mmstab.core.files import MmstabError, write_npz
from mmstab.core.locks import build_lock, file_stamp
from mmstab.core.steps import drain
from mmstab.model.collision import CollisionChecker
from mmstab.model.reach import sampled_reach
from mmstab.model.robot import FloatArray, Robot
from mmstab.workspace.cache import default_cache_dir
from mmstab.workspace.grid import joint_grid
from mmstab.workspace.kept import SOURCE_ATTR, kept_arrays, kept_beside
from mmstab.workspace.region import Workspace
from mmstab.workspace.roadmap_checks import (  # noqa: F401 (MOVE_CLEARANCE: its name here too)
    CHECK_CHUNK,
    COARSE_STRIDE,
    MOVE_CLEARANCE,
    coarse_first,
    free_moves,
    grid_index,
    node_arrays,
)

#: Largest motion of any point of the arm between two checked postures of an edge [m].
DEFAULT_RESOLUTION = 0.02
#: Largest motion of any arm point between two postures whose clearance is measured [m].
CLEARANCE_STEP = 0.004


def move_keeps_clearance(
    checker: CollisionChecker, reach: FloatArray, qa: FloatArray, qb: FloatArray, clearance: float
) -> bool:
    """Whether the straight move qa -> qb (n,) [rad] keeps ``clearance`` [m] everywhere.

    Checked at postures between which no arm point moves more than :data:`CLEARANCE_STEP`
    (the bound Σ_j reach_j |Δq_j|, ``reach`` (n,) [m]), ends included: at least
    ``clearance + CLEARANCE_STEP / 2`` at each bounds it by ``clearance`` between them
    (clearance is 1-Lipschitz in point motion), so the move is also free.
    """
    d = np.asarray(qb, dtype=float) - qa
    n = int(np.ceil(float(reach @ np.abs(d)) / CLEARANCE_STEP)) + 1
    q = qa + np.linspace(0.0, 1.0, n + 1)[:, None] * d
    need, stride = clearance + CLEARANCE_STEP / 2, COARSE_STRIDE
    # every stride-th posture first: a move that fails is mostly rejected there
    if not checker.keeps_clearance(q[::stride], need, CLEARANCE_STEP * stride):
        return False
    return checker.keeps_clearance(q, need, CLEARANCE_STEP)


@dataclass(frozen=True, eq=False)
class Roadmap:
    """The posture lattice graph.

    Attributes:
        grid: samples per joint (V's grid).
        nodes_q: node postures (N, 4) [rad], collision-free grid postures.
        edges: node pairs (E, 2) joined by a collision-free straight move.
        lengths: joint-space length of each edge (E,) [rad].
        component: connected component of each node (N,).
        reach: per joint, the bound on the distance of any arm point from that joint's
            axis (4,) [m].
        steps: interior postures checked per edge along each joint (4,).
        resolution: the largest point motion between checked postures [m].
        node_com: each node's arm CoM, body frame (N, 3) [m].
        node_ground: each node's arm's lowest point above the support plane z_B = 0 (N,)
            [m] (:func:`mmstab.model.plane_clearance.arm_ground_clearance`).
        node_clearance: each node's FCL clearance from the robot (N,) [m], exact below
            :data:`MOVE_CLEARANCE` (a lower bound above it).
        build_seconds: wall time of the build [s].
    """

    grid: tuple[int, ...]
    nodes_q: FloatArray
    edges: NDArray[np.int64]
    lengths: FloatArray
    component: NDArray[np.int64]
    reach: FloatArray
    steps: NDArray[np.int64]
    resolution: float
    node_com: FloatArray
    node_ground: FloatArray
    node_clearance: FloatArray
    build_seconds: float = 0.0

    @functools.cached_property
    def graph(self) -> csr_matrix:
        """The symmetric sparse adjacency matrix, edge weights = lengths [rad]."""
        n = len(self.nodes_q)
        a, b = self.edges[:, 0], self.edges[:, 1]
        w = np.concatenate([self.lengths, self.lengths])
        return csr_matrix((w, (np.concatenate([a, b]), np.concatenate([b, a]))), shape=(n, n))

    @functools.cached_property
    def _tree(self) -> cKDTree:
        q = self.nodes_q
        return cKDTree(np.column_stack([np.cos(q[:, 0]), np.sin(q[:, 0]), q[:, 1:]]))

    def nearest(self, q: ArrayLike) -> NDArray[np.intp]:
        """The node nearest to each posture (turret as an angle) (N,).

        Args:
            q: postures (N, 4) or (4,) [rad].
        """
        qa = np.atleast_2d(np.asarray(q, dtype=float))
        _, idx = self._tree.query(np.column_stack([np.cos(qa[:, 0]), np.sin(qa[:, 0]), qa[:, 1:]]))
        return np.asarray(idx, dtype=np.intp)

    def connect(self, q: ArrayLike, robot: Robot, candidates: int = 16) -> int:
        """A node joined to posture q (4,) [rad] by a collision-free straight move.

        The nearest of the ``candidates`` nearest nodes whose move from q, checked at the
        roadmap's resolution, is free (a grid posture q is its own node).

        Raises:
            MmstabError: none is (q collides, or is boxed in at this grid's spacing).
        """
        qa = np.asarray(q, dtype=float).reshape(len(self.grid))
        if np.array_equal(qa, robot.stowed):  # every plan's start: kept beside the file
            tag = hashlib.sha256(qa.tobytes()).hexdigest()[:12]

            def node() -> dict[str, NDArray[np.int64]]:
                return {"node": np.array(self._connect(qa, robot, candidates), dtype=np.int64)}

            return int(kept_arrays(self, f"connect-{tag}-{candidates}", node)["node"])
        return self._connect(qa, robot, candidates)

    def _connect(self, qa: FloatArray, robot: Robot, candidates: int) -> int:
        """:meth:`connect` itself."""
        _, idx = self._tree.query(
            np.r_[np.cos(qa[0]), np.sin(qa[0]), qa[1:]], k=min(candidates, len(self.nodes_q))
        )
        checker = CollisionChecker(robot)
        for node in np.atleast_1d(idx):
            d = self.nodes_q[node] - qa  # the turret's range ends at a stop: no wrap
            if self.move_is_free(checker, qa, qa + d):
                return int(node)
        raise MmstabError(f"roadmap: the posture {np.round(qa, 3).tolist()} rad reaches no node")

    def move_is_free(self, checker: CollisionChecker, qa: FloatArray, qb: FloatArray) -> bool:
        """Whether the straight move qa -> qb (4,) [rad] is free at the roadmap's resolution.

        Checked postures are spaced so that no arm point moves more than ``resolution``
        between two (the bound Σ_j reach_j |Δq_j|); the ends included.
        """
        d = np.asarray(qb, dtype=float) - qa
        n = int(np.ceil(float(self.reach @ np.abs(d)) / self.resolution)) + 1
        for u in coarse_first(n):
            if np.asarray(checker.collides(qa + u[:, None] * d), dtype=bool).any():
                return False
        return True

    def move_is_clear(
        self, checker: CollisionChecker, qa: FloatArray, qb: FloatArray, clearance: float
    ) -> bool:
        """Whether the straight move qa -> qb (4,) [rad] keeps ``clearance`` [m] everywhere.

        The clearance at postures between which no arm point moves more than
        :data:`CLEARANCE_STEP`: at least ``clearance + CLEARANCE_STEP / 2`` at each of
        them bounds it by ``clearance`` between them (clearance is 1-Lipschitz in point
        motion), so the move is also free (:meth:`CollisionChecker.keeps_clearance`).
        """
        return move_keeps_clearance(checker, self.reach, qa, qb, clearance)

    def shortcut(
        self, checker: CollisionChecker, q: ArrayLike, clearance: float = MOVE_CLEARANCE
    ) -> FloatArray:
        """A posture path (n, 4) [rad] with its corners cut where free and clear.

        Greedy: from each kept posture, the farthest later one joined by a straight move
        that keeps ``clearance`` [m] (:meth:`move_is_clear`; 0: free at the roadmap's
        resolution, :meth:`move_is_free`); the lattice's staircase becomes straight moves.
        The ends are kept; the result is never longer (triangle inequality). A cut never
        passes closer to the robot than ``clearance``, so it never takes the arm nearer
        than the lattice path it replaces when that path keeps ``clearance`` itself.
        """
        return drain(self.shortcut_steps(checker, q, clearance))

    def shortcut_steps(
        self,
        checker: CollisionChecker,
        q: ArrayLike,
        clearance: float = MOVE_CLEARANCE,
        memo: dict[Any, bool] | None = None,
    ) -> Generator[None, None, FloatArray]:
        """:meth:`shortcut`, a step at a time: it yields after each cut it tests.

        Returns the same path; a caller may spread the tests over time (:func:`drain`).
        ``memo``: the straight moves tested by earlier calls with the same ``checker``
        (the caller's; paths that share postures test the same cuts).
        """
        qa = np.atleast_2d(np.asarray(q, dtype=float))
        memo = {} if memo is None else memo

        def ok(a: FloatArray, b: FloatArray) -> bool:
            key = (a.tobytes(), b.tobytes(), clearance)
            if key not in memo:
                if clearance <= 0:
                    memo[key] = self.move_is_free(checker, a, b)
                else:
                    memo[key] = self.move_is_clear(checker, a, b, clearance)
            return memo[key]

        keep, i = [0], 0
        while i < len(qa) - 1:
            j = len(qa) - 1
            while j > i + 1 and not ok(qa[i], qa[j]):
                yield
                j = (i + 1 + j) // 2 if j - i > 8 else j - 1
            yield
            keep.append(j)
            i = j
        return qa[keep].copy()

    def path(self, a: int, b: int) -> NDArray[np.intp]:
        """Shortest roadmap path from node a to node b, both included.

        Raises:
            MmstabError: a and b lie in different components.
        """
        if a == b:
            return np.array([a], dtype=np.intp)
        if self.component[a] != self.component[b]:
            raise MmstabError(f"roadmap: nodes {a} and {b} are not connected")
        _, pred = dijkstra(self.graph, indices=a, return_predecessors=True)
        out = [b]
        while out[-1] != a:
            out.append(int(pred[out[-1]]))
        return np.array(out[::-1], dtype=np.intp)

    def path_postures(self, a: int, b: int) -> FloatArray:
        """The postures of the shortest path a -> b (n, 4) [rad]."""
        return self.nodes_q[self.path(a, b)].copy()

    def path_length(self, q: ArrayLike) -> float:
        """Joint-space length of a posture path (n, 4) [rad]."""
        qa = np.atleast_2d(np.asarray(q, dtype=float))
        return float(np.linalg.norm(np.diff(qa, axis=0), axis=1).sum())


def build_roadmap(
    robot: Robot, ws: Workspace, resolution: float = DEFAULT_RESOLUTION, progress: bool = False
) -> Roadmap:
    """The lattice roadmap over V's collision-free grid postures (module text).

    Args:
        robot: the robot (the one V was built for).
        ws: the workspace V (its grid and its collision-free postures).
        resolution: largest point motion between checked postures of an edge [m].
        progress: show a progress bar (on a terminal): the edges' checked postures.
    """
    if ws.samples:
        raise MmstabError(
            f"the roadmap joins grid neighbours: it needs a whole-grid workspace, not "
            f"{ws.samples} postures drawn from the {ws.grid} grid (a smaller workspace.grid)"
        )
    t0 = time.perf_counter()
    jg = joint_grid(robot, ws.grid)
    shape = np.array(jg.shape)
    nodes_q = np.asarray(ws.valid_q, dtype=float)
    idx = grid_index(jg, nodes_q)
    flat = np.ravel_multi_index(tuple(idx.T), tuple(shape))
    lookup = np.full(jg.size, -1, dtype=np.int64)
    lookup[flat] = np.arange(len(nodes_q))
    reach = sampled_reach(robot, nodes_q)
    steps = np.maximum(np.ceil(reach * jg.step / resolution).astype(np.int64) - 1, 0)
    checker = CollisionChecker(robot)
    edges, lengths = [], []
    bar = tqdm(
        total=int(steps.sum()) + 1, unit="check", desc="roadmap", disable=None if progress else True
    )
    for j in range(robot.arm_joints):
        # no edge wraps the turret's full turn: its range ends at a stop (the posture at
        # 2 pi is the one at 0, but the joint cannot move through the stop between them)
        nxt = idx.copy()
        nxt[:, j] += 1
        inside = nxt[:, j] < shape[j]
        rows = np.flatnonzero(inside)
        other = lookup[np.ravel_multi_index(tuple(nxt[rows].T), tuple(shape))]
        rows, other = rows[other >= 0], other[other >= 0]
        free = free_moves(checker, nodes_q[rows], j, float(jg.step[j]), int(steps[j]), bar)
        edges.append(np.column_stack([rows[free], other[free]]))
        lengths.append(np.full(int(free.sum()), float(jg.step[j])))
    e = np.concatenate(edges).astype(np.int64) if edges else np.zeros((0, 2), np.int64)
    w = np.concatenate(lengths)
    n = len(nodes_q)
    g = csr_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n))
    _, component = connected_components(g, directed=False)
    arrays = node_arrays(robot, nodes_q)
    bar.update(1)
    bar.close()
    return Roadmap(
        grid=tuple(int(x) for x in ws.grid),
        nodes_q=nodes_q,
        edges=e,
        lengths=w,
        component=component.astype(np.int64),
        reach=reach,
        steps=steps,
        resolution=float(resolution),
        **arrays,
        build_seconds=time.perf_counter() - t0,
    )


def roadmap_key(robot: Robot, grid: tuple[int, ...], resolution: float, version: int) -> str:
    """Cache key: robot description, base collision boxes (flipper setting), grid, resolution."""
    boxes = robot.base.collision_boxes()
    geo = np.concatenate([np.r_[b.frame_T_shape.ravel(), b.size] for b in boxes.values()])
    text = (
        f"roadmap{version}|{robot.source_hash}|{[int(n) for n in grid]}|{resolution!r}|"
        f"{np.round(geo, 9).tobytes().hex()}"
    )
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def roadmap_arrays(rm: Roadmap) -> dict[str, object]:
    """The roadmap's fields as arrays (for ``.npz``)."""
    return {f.name: getattr(rm, f.name) for f in dataclasses.fields(rm)}


# ---------------------------------------------------------------------------------- cache
#: Bump when the roadmap's construction or file format changes.
ROADMAP_VERSION = 2
_MEMORY: dict[str, Roadmap] = {}


def load_or_build_roadmap(
    robot: Robot,
    ws: Workspace,
    resolution: float = DEFAULT_RESOLUTION,
    cache_dir: str | os.PathLike[str] | None = None,
    progress: bool = True,
) -> Roadmap:
    """The roadmap of a robot and its V: from memory, from the cache file, else built.

    The file is ``roadmap-<key>.npz`` (:func:`roadmap_key`) in the cache folder (default
    :func:`mmstab.workspace.cache.default_cache_dir`, shared by every working folder),
    written atomically by one process at a time (:mod:`mmstab.core.locks`); an unreadable
    one is rebuilt; one written before the nodes' CoMs and ground heights and clearances
    were kept in it gets them added (the graph is the same).
    A build says where the file goes (one line on stderr) and, with ``progress`` on a
    terminal, shows a progress bar. The arrays are read from an uncompressed copy beside
    the file (``roadmap-<key>/arrays/``, memory-mapped, :mod:`mmstab.workspace.kept`).
    """
    key = roadmap_key(robot, ws.grid, resolution, ROADMAP_VERSION)
    if key in _MEMORY:
        return _MEMORY[key]
    folder = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    path = folder / f"roadmap-{key}.npz"
    seen = file_stamp(path)  # before reading: a file published after it is seen below
    rm, missing = _read_roadmap(robot, path)
    if missing:
        with build_lock(path):  # one builder per file: another process may be building it
            if file_stamp(path) not in (None, seen):  # it did, while we waited
                rm, missing = _read_roadmap(robot, path)
            if rm is None:
                if progress:
                    print(
                        f"mmstab: building the posture roadmap of the {list(ws.grid)} grid, "
                        f"once per robot and grid (seconds) -> {path}",
                        file=sys.stderr,
                    )
                rm = build_roadmap(robot, ws, resolution, progress)
            if missing:
                try:
                    write_npz(path, **roadmap_arrays(rm))
                except OSError:  # a read-only cache folder: built in every process
                    pass
    assert rm is not None
    if path.is_file():  # what plans derive from it is kept beside it (mmstab.workspace.kept)
        object.__setattr__(rm, SOURCE_ATTR, path)
    _MEMORY[key] = rm
    return rm


def _read_roadmap(robot: Robot, path: Path) -> tuple[Roadmap | None, bool]:
    """The roadmap in ``path`` (None: absent or unreadable) and whether to (re)write the file."""
    if not path.is_file():
        return None, True
    try:

        def read() -> dict[str, np.ndarray]:
            with np.load(path) as z:
                return {f.name: z[f.name] for f in dataclasses.fields(Roadmap) if f.name in z}

        kw: dict[str, Any] = kept_beside(path, "arrays", read)  # uncompressed: read fast
        kw["grid"] = tuple(int(n) for n in kw["grid"])
        kw["resolution"] = float(kw["resolution"])
        kw["build_seconds"] = float(kw["build_seconds"])
        missing = not {"node_com", "node_ground", "node_clearance"} <= kw.keys()
        return Roadmap(**{**kw, **(node_arrays(robot, kw["nodes_q"]) if missing else {})}), missing
    except Exception:  # noqa: BLE001 - any unreadable cache: rebuild
        return None, True
