"""Postures along a path chosen on the posture roadmap (``planner: {method: roadmap}``).

Like ``method: sequence`` (:mod:`mmstab.planner.sequence`) it maximises Eq. 6 summed along
the path, each pose's motion term against the previous pose's choice, by dynamic
programming over poses x candidate postures. The candidates are the roadmap's nodes
(:mod:`mmstab.workspace.roadmap`) in the component of the arm's start posture (the stowed
arm), each pose's ``sequence_candidates`` best by Eq. 6's stability term spread over the
turret, with a stable posture only (μ > 0). Any two nodes of a component are joined by a
roadmap path of checked collision-free moves, so every move the search chooses is
feasible by construction: no lazy check, no round limit; the search is exact on the
candidates. When some pose has no stable candidate (or the turret window leaves no
sequence), :class:`NoPlanError` names the pose. The chosen moves' roadmap paths come with
the answer, for the controller.
"""

from __future__ import annotations

import heapq
import time
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray
from scipy.sparse.csgraph import dijkstra

from mmstab.core.files import MmstabError, PlanningError
from mmstab.model.collision import CollisionChecker
from mmstab.model.robot import FloatArray, Robot
from mmstab.planner.candidates import NodeClearance, NodeClusters, node_clusters, route_candidates
from mmstab.planner.fitness import pose_fitness
from mmstab.planner.grounded import ground_graph, shortcut_above
from mmstab.planner.motion import motion_cost, transitions
from mmstab.planner.sequence import _turret_bins, _viterbi
from mmstab.planner.settings import PlannerSettings
from mmstab.workspace.roadmap import Roadmap

#: Turret-angle bins over which each pose's candidates are spread.
TURRET_BINS = 24
#: Node expansions of an A* query before the whole component is searched instead.
ASTAR_EXPANSIONS = 20000


class NoPlanError(PlanningError):
    """No sequence of reachable stable postures exists; ``pose`` is the first without one."""

    def __init__(self, message: str, pose_index: int):
        super().__init__(message)
        self.pose_index = pose_index


class RoadmapSequence(NamedTuple):
    """The chosen roadmap nodes along the path.

    Attributes:
        nodes: the chosen node per pose (K,).
        postures: their postures (K, 4) [rad].
        com: their arm CoMs, body frame (K, 3) [m].
        fitness: Eq. 6 per pose, the previous pose's choice as previous CoM (K,).
        mu: force-angle measure per pose [N rad] (K,).
        total: the sum of ``fitness``.
        moves: the roadmap path into each pose's posture (K arrays (n, 4) [rad]): from
            the start posture (open path) or from the last pose (closed).
        seconds: wall time [s].
    """

    nodes: NDArray[np.intp]
    postures: FloatArray
    com: FloatArray
    fitness: FloatArray
    mu: FloatArray
    total: float
    moves: tuple[FloatArray, ...]
    seconds: float


def best_sequence(
    value: FloatArray, motion: list[FloatArray], allowed: list[NDArray[np.bool_]], closed: bool
) -> tuple[NDArray[np.intp], float]:
    """Exact max of Σ value[k][c_k] − motion[k][c_{k−1}, c_k] over allowed moves.

    Open: Viterbi. Closed (``motion``/``allowed`` have K entries, the last closing the loop):
    Viterbi from every feasible first candidate in turn, the closing move folded into the
    last pose's values. Total -inf when no sequence is allowed.
    """
    K = len(value)
    if not closed or K == 1:
        return _viterbi(value, motion[: K - 1], allowed[: K - 1])
    best_path, best_total = np.zeros(K, dtype=np.intp), -np.inf
    for start in np.flatnonzero(np.isfinite(value[0])):
        v = np.full_like(value, -np.inf)
        v[1:] = value[1:]
        v[0, start] = value[0, start]
        close = np.where(allowed[K - 1][:, start], -motion[K - 1][:, start], -np.inf)
        v[K - 1] = v[K - 1] + close
        path, total = _viterbi(v, motion[: K - 1], allowed[: K - 1])
        if total > best_total:
            best_path, best_total = path, total
    return best_path, best_total


def _first_dead_pose(value: FloatArray, allowed: list[NDArray[np.bool_]]) -> int:
    """The first pose that no allowed sequence of finite values reaches."""
    alive = np.isfinite(value[0])
    for k in range(len(value)):
        if k:
            alive = (allowed[k - 1] & alive[:, None]).any(axis=0) & np.isfinite(value[k])
        if not alive.any():
            return k
    return len(value) - 1


def _ground_note(ground: float | None) -> str:
    """The ground test in the no-plan message (``planner.ground_clearance`` [m])."""
    return "" if ground is None else f" with the arm {ground:g} m above the ground plane"


def node_coms(robot: Robot, roadmap: Roadmap) -> FloatArray:
    """Arm CoMs of the roadmap's nodes, body frame (N, 3) [m] (kept with the roadmap).

    ``robot`` is the roadmap's own (its cache key holds the robot's hash).
    """
    return np.asarray(roadmap.node_com)


class ComponentView(NamedTuple):
    """What every plan from one roadmap component needs, computed once and kept.

    Attributes:
        reach: the component's nodes (N,).
        samples: their arm CoMs, body frame (N, 3) [m].
        diameter: the CoMs' largest extent along an axis [m] (Eq. 6's ``d_workspace``).
        bins: turret bin of each (N,).
        clusters: the nodes grouped for the candidates' bounds.
        joint_span: the postures' L1 extent, Σ_j (max q_j − min q_j) [rad] (the
            ``motion_cost: joints`` normaliser).
    """

    reach: NDArray[np.intp]
    samples: FloatArray
    diameter: float
    bins: NDArray[np.intp]
    clusters: NodeClusters
    joint_span: float


def component_view(
    robot: Robot, roadmap: Roadmap, start: int, ground: float | None = None
) -> ComponentView:
    """The :class:`ComponentView` of node ``start``'s component (kept with the roadmap).

    With ``ground`` [m]: the component among the nodes whose arm stays that far above the
    support plane (:func:`mmstab.planner.grounded.ground_graph`).
    """
    views = getattr(roadmap, "_views", None)
    if views is None:
        views = {}
        object.__setattr__(roadmap, "_views", views)
    component = ground_graph(roadmap, ground).component
    comp = (int(component[start]), ground)
    if comp not in views:
        reach = np.flatnonzero(component == comp[0])
        samples = node_coms(robot, roadmap)[reach]
        bins = _turret_bins(roadmap.nodes_q[reach, 0], TURRET_BINS)
        views[comp] = ComponentView(
            reach=reach,
            samples=samples,
            diameter=float(np.ptp(samples, axis=0).max()) if len(samples) > 1 else 1.0,
            bins=bins,
            clusters=node_clusters(samples, bins, TURRET_BINS),
            joint_span=max(float(np.ptp(roadmap.nodes_q[reach], axis=0).sum()), 1e-9),
        )
    return views[comp]


def _moves(
    robot: Robot,
    roadmap: Roadmap,
    start: int,
    start_q: FloatArray,
    nodes: NDArray[np.intp],
    closed: bool,
    ground: float | None = None,
) -> list[FloatArray]:
    """The arm's moves into each chosen node: shortest roadmap paths, shortcut where free.

    From the start node (an open path) or the last pose's node (a loop); an open path's
    first move starts at the start posture ``start_q`` [rad] itself. With ``ground`` [m]
    the paths and shortcuts keep the arm that far above the support plane.
    """
    K = len(nodes)
    before = [nodes[-1] if closed and K > 1 else start, *nodes[:-1]]
    checker = CollisionChecker(robot)  # the staircase's corners cut where the cut is free
    tree = start_tree(roadmap, start, ground)
    moves = [
        shortcut_above(
            robot, roadmap, checker, roadmap_move(roadmap, int(a), int(b), tree, ground), ground
        )
        for a, b in zip(before, nodes, strict=True)
    ]
    if not closed or K == 1:  # from the start posture itself onto its node
        first = np.vstack([start_q, moves[0]])
        moves[0] = first if np.linalg.norm(first[1] - first[0]) > 1e-12 else first[1:]
    return moves


def start_tree(
    roadmap: Roadmap, start: int, ground: float | None = None
) -> tuple[int, NDArray[np.int32]]:
    """Shortest-path tree from node ``start`` (its predecessors), kept with the roadmap.

    Every plan's first move leaves the arm's start node (the stowed arm's): one search
    over the whole component, once (on the nodes ``ground`` [m] above the plane, if set).
    """
    trees = getattr(roadmap, "_trees", None)
    if trees is None:
        trees = {}
        object.__setattr__(roadmap, "_trees", trees)
    if (start, ground) not in trees:
        graph = ground_graph(roadmap, ground).graph
        trees[start, ground] = dijkstra(graph, indices=start, return_predecessors=True)[1]
    return start, trees[start, ground]


def astar(roadmap: Roadmap, a: int, b: int, ground: float | None = None) -> NDArray[np.intp] | None:
    """A shortest roadmap path a -> b (nodes), by A* with the lattice (L1) distance to b.

    Every edge changes one joint by its length and never wraps the turret, so the L1
    distance is a consistent lower bound and the path is a shortest one; with ties
    broken towards the deepest node, a free staircase costs about its length in node
    expansions where Dijkstra's search bounded at 1.5 times the distance (the previous
    query) explored a 4-D ball of nodes (16 ms a move on a random route). None when
    ``ASTAR_EXPANSIONS`` nodes did not reach b. With ``ground`` [m]: on the nodes whose
    arm stays that far above the support plane.
    """
    # each expanded node's row as Python lists (the loop's cheapest reads), not the whole
    # graph converted at once (0.5-0.8 s, most of a cold plan's search on kerb.yaml)
    g, nodes_q = ground_graph(roadmap, ground).graph, roadmap.nodes_q
    ptr, nbr, w = g.indptr, g.indices, g.data
    goal = nodes_q[b].tolist()
    q: dict[int, list[float]] = {}

    def h(n: int) -> float:
        if n not in q:
            q[n] = nodes_q[n].tolist()
        return sum(abs(x - y) for x, y in zip(q[n], goal, strict=True))

    best, parent = {a: 0.0}, {a: a}
    heap = [(h(a), 0.0, a)]
    for _ in range(ASTAR_EXPANSIONS):
        if not heap:
            return None
        _, neg_g, n = heapq.heappop(heap)
        if n == b:
            out = [b]
            while out[-1] != a:
                out.append(parent[out[-1]])
            return np.array(out[::-1], dtype=np.intp)
        if -neg_g > best[n]:
            continue  # a stale entry
        lo, hi = ptr[n], ptr[n + 1]
        for m, step in zip(nbr[lo:hi].tolist(), w[lo:hi].tolist(), strict=True):
            cost = best[n] + step
            if cost < best.get(m, np.inf):
                best[m], parent[m] = cost, n
                heapq.heappush(heap, (cost + h(m), -cost, m))
    return None


def roadmap_move(
    roadmap: Roadmap,
    a: int,
    b: int,
    tree: tuple[int, NDArray[np.int32]] | None = None,
    ground: float | None = None,
) -> FloatArray:
    """The shortest roadmap path a -> b as postures (n, 4) [rad].

    From ``tree``'s root (:func:`start_tree`, built with the same ``ground``) along the
    tree; else A* (:func:`astar`), else the whole component; with ``ground`` [m] on the
    nodes whose arm stays that far above the support plane.
    """
    if a == b:
        return roadmap.nodes_q[[a]].copy()
    if tree is not None and tree[0] == a:
        pred = tree[1]
    else:
        path = astar(roadmap, a, b, ground)
        if path is None:
            graph = ground_graph(roadmap, ground).graph
            pred = dijkstra(graph, indices=a, return_predecessors=True)[1]
        else:
            return roadmap.nodes_q[path]
    out = [b]
    while out[-1] != a:
        out.append(int(pred[out[-1]]))
    return roadmap.nodes_q[out[::-1]].copy()


def solve_roadmap_sequence(
    robot: Robot,
    gravity_body: FloatArray,
    roadmap: Roadmap,
    settings: PlannerSettings,
    mu_max: float,
    closed: bool,
    poses: FloatArray,
    start_q: FloatArray | None = None,
) -> RoadmapSequence:
    """Choose one reachable roadmap node per pose (module text).

    Args:
        robot: the robot.
        gravity_body: gravity in the body frame at each pose (K, 3) [m/s^2].
        roadmap: the posture roadmap.
        settings: planner settings (weights, ``turret_window``, ``sequence_candidates``).
        mu_max: Eq. 6's normaliser [N rad].
        closed: the path is a loop (the last pose's choice is the first's previous).
        poses: base poses (K, 3) [m, m, rad], for the message when no plan exists.
        start_q: the arm's start posture (4,) [rad]; default the stowed arm.

    Raises:
        NoPlanError: some pose has no reachable stable posture (the message names it).
    """
    t0 = time.perf_counter()
    if robot.tool_wrench is not None:
        raise MmstabError("planner: method roadmap does not take payload.wrench yet")
    start_q = robot.stowed if start_q is None else np.asarray(start_q, dtype=float)
    start = roadmap.connect(start_q, robot)
    view = component_view(robot, roadmap, start, settings.ground_clearance)
    reach, samples, diameter = view.reach, view.samples, view.diameter
    g = np.atleast_2d(np.asarray(gravity_body, dtype=float))
    K, M = len(g), min(settings.sequence_candidates, len(reach))
    stowed = robot.arm_com(start_q)
    stab = settings._replace(w_motion=0.0)
    fits = [pose_fitness(robot, gk, stowed, stab, mu_max, diameter).linear() for gk in g]
    clear = NodeClearance(roadmap, reach, settings.ground_clearance)
    cand, value, mu = route_candidates(fits, samples, view.bins, view.clusters, M, clear)
    span = (view.diameter, view.joint_span)
    cost = motion_cost(roadmap.nodes_q[reach], samples, span, settings)
    if not closed:
        value[0] -= cost.from_point(cand[0], cost.point_of(robot, start_q))
    pairs = [(k, k + 1) for k in range(K - 1)] + ([(K - 1, 0)] if closed and K > 1 else [])
    motion, allowed = transitions(
        cost.points, roadmap.nodes_q[reach, 0], cand, pairs, cost.weight, settings.turret_window,
        cost.metric,
    )  # fmt: skip
    path, total = best_sequence(value, motion, allowed, closed)
    if not np.isfinite(total):
        k = _first_dead_pose(value, allowed)
        x, y, h = np.asarray(poses, dtype=float)[k]
        raise NoPlanError(
            f"planner: no plan on the posture roadmap: at pose {k} (x {x:.2f} m, y {y:.2f} m, "
            f"heading {np.degrees(h):.0f} deg) no stable posture reachable from the arm's start"
            + (" within the turret window" if settings.turret_window is not None else "")
            + _ground_note(settings.ground_clearance),
            k,
        )
    chosen = cand[np.arange(K), path]
    nodes = reach[chosen]
    fitness = value[np.arange(K), path].copy()
    for i, (a, b) in enumerate(pairs):
        fitness[b] -= motion[i][path[a], path[b]]
    moves = _moves(robot, roadmap, int(start), start_q, nodes, closed, settings.ground_clearance)
    return RoadmapSequence(
        nodes=nodes,
        postures=roadmap.nodes_q[nodes].copy(),
        com=samples[chosen].copy(),
        fitness=fitness,
        mu=mu[np.arange(K), path].copy(),
        total=float(fitness.sum()),
        moves=tuple(moves),
        seconds=time.perf_counter() - t0,
    )
