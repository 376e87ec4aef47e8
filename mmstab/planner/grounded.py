"""The posture roadmap without the nodes whose arm is in the ground (``planner.ground_clearance``).

The search chooses only nodes whose arm's lowest point is ``ground`` [m] above the support
plane z_B = 0 (:class:`mmstab.planner.candidates.NodeClearance`), but a roadmap path between
two such nodes may pass through others: on 11 of the 20 random routes
(docs/routes.md) the moves dipped below the plane, down to 28.6 cm. Here the graph keeps
only the edges between nodes that clear the plane (their components say what the arm can
reach without touching it), and a shortcut that dips below it is not taken. The ground
under the arm at the poses a move joins is :mod:`mmstab.planner.searches.roadmap.moves`' check.
"""

from __future__ import annotations

import hashlib
from collections.abc import Generator
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from mmstab.core.steps import drain
from mmstab.model.collision import CollisionChecker
from mmstab.model.plane_clearance import lowest_along_moves
from mmstab.model.robot import FloatArray, Robot
from mmstab.planner.ground.under_arm import GroundUnderArm
from mmstab.workspace.kept import kept_arrays
from mmstab.workspace.roadmap import CLEARANCE_STEP, Roadmap


class Graph(NamedTuple):
    """The graph the moves search: the roadmap's own, or that of the nodes above the plane.

    Attributes:
        graph: symmetric adjacency matrix, edge weights = lengths [rad].
        component: connected component of each node in it (N,).
    """

    graph: csr_matrix
    component: NDArray[np.int64]


def ground_graph(roadmap: Roadmap, ground: float | None) -> Graph:
    """The graph of the nodes ``ground`` [m] above the plane (None: the whole roadmap).

    Built once per roadmap and threshold (0.2–0.3 s on the default grid) and kept, in
    memory and beside the roadmap's cache file (:mod:`mmstab.workspace.kept`).
    """
    if ground is None:
        return Graph(roadmap.graph, roadmap.component)
    kept = getattr(roadmap, "_ground_graphs", None)
    if kept is None:
        kept = {}
        object.__setattr__(roadmap, "_ground_graphs", kept)
    if ground not in kept:
        n = len(roadmap.nodes_q)

        def compute() -> dict[str, np.ndarray]:
            keep = np.asarray(roadmap.node_ground >= ground)
            both = keep[roadmap.edges[:, 0]] & keep[roadmap.edges[:, 1]]
            e, w = roadmap.edges[both], roadmap.lengths[both]
            rows, cols = np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]]
            g = csr_matrix((np.r_[w, w], (rows, cols)), shape=(n, n))
            component = connected_components(g, directed=False)[1]  # a dropped node: its own
            return {
                "data": g.data, "indices": g.indices, "indptr": g.indptr,
                "component": np.asarray(component, dtype=np.int64),
            }  # fmt: skip

        a = kept_arrays(roadmap, f"ground-{float(ground)!r}", compute)
        graph = csr_matrix((a["data"], a["indices"], a["indptr"]), shape=(n, n))
        kept[ground] = Graph(graph, a["component"])
    return kept[ground]


#: Postures per batch of :func:`node_lowest` (the pieces of a batch: 1.3 kB a posture).
LOWEST_CHUNK = 16384


def node_lowest(roadmap: Roadmap, under: GroundUnderArm) -> FloatArray:
    """Each node's arm pieces' least z_B over the body's tilts (N,) [m], kept.

    The least of ``under``'s pieces' lowest points (:meth:`GroundUnderArm.body`: the
    tilts up to its ``margin``, the pieces its backend computes) at each node's posture:
    pose-independent, so a route's search knows from it, before measuring, which nodes are
    too low above the ground at a pose, and which surely clear it
    (:class:`mmstab.planner.candidates.NodeClearance`). Computed once per roadmap, margin
    and pieces (0.5 s on the default grid) and kept, in memory and beside the roadmap's
    cache file (:mod:`mmstab.workspace.kept`).
    """
    kept = getattr(roadmap, "_node_lowest", None)
    if kept is None:
        kept = {}
        object.__setattr__(roadmap, "_node_lowest", kept)
    pieces = under.pieces
    digest = hashlib.sha1(usedforsecurity=False)
    for a in (pieces.link, pieces.points, pieces.radius):
        digest.update(np.ascontiguousarray(a).tobytes())
    key = f"lowest-{under.margin!r}-{under.backend}-{digest.hexdigest()[:12]}"
    if key not in kept:
        q = roadmap.nodes_q

        def compute() -> dict[str, np.ndarray]:
            parts = [under.body(q[c : c + LOWEST_CHUNK]).low.min(axis=1, initial=np.inf)
                     for c in range(0, len(q), LOWEST_CHUNK)]  # fmt: skip
            return {"lowest": np.concatenate(parts) if parts else np.zeros(0)}

        kept[key] = kept_arrays(roadmap, key, compute)["lowest"]
    return np.asarray(kept[key])


def stays_above(robot: Robot, roadmap: Roadmap, q: FloatArray, ground: float) -> bool:
    """Whether the polyline of postures q (n, 4) [rad] keeps the arm ``ground`` [m] up.

    Sampled so that no arm point moves more than ``CLEARANCE_STEP`` between two samples
    (the bound Σ_j reach_j |Δq_j|, :func:`mmstab.model.plane_clearance.lowest_along_moves`), the
    ends included.
    """
    qa = np.atleast_2d(np.asarray(q, dtype=float))
    if len(qa) < 2:  # no move (a node's own height is checked with the node)
        return True
    low = lowest_along_moves(robot, roadmap.reach, qa[:-1], qa[1:], CLEARANCE_STEP)
    return bool(low.min() >= ground)


def shortcut_above(
    robot: Robot, roadmap: Roadmap, checker: CollisionChecker, q: FloatArray, ground: float | None
) -> FloatArray:
    """``Roadmap.shortcut`` of the path q (n, 4) [rad], kept only if it stays ``ground`` up.

    Else the lattice path itself (its nodes are all above; a one-joint step between two
    of them may dip by millimetres).
    """
    return drain(shortcut_above_steps(robot, roadmap, checker, q, ground))


def shortcut_above_steps(
    robot: Robot,
    roadmap: Roadmap,
    checker: CollisionChecker,
    q: FloatArray,
    ground: float | None,
    memo: dict[Any, bool] | None = None,
) -> Generator[None, None, FloatArray]:
    """:func:`shortcut_above` of postures q (n, 4) [rad], ``ground`` [m], a cut at a time.

    ``memo``: the cuts tested before (``Roadmap.shortcut_steps``).
    """
    short = yield from roadmap.shortcut_steps(checker, q, memo=memo)
    if ground is None or stays_above(robot, roadmap, short, ground):
        return short
    return np.atleast_2d(np.asarray(q, dtype=float)).copy()
