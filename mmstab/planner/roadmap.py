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

import dataclasses
import time
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from mmstab.core.files import MmstabError, PlanningError
from mmstab.model.collision import CollisionChecker
from mmstab.model.robot import FloatArray, Robot
from mmstab.planner.fitness import pose_fitness
from mmstab.planner.sequence import _diverse_top, _turret_bins, _viterbi
from mmstab.planner.settings import PlannerSettings
from mmstab.workspace.roadmap import MOVE_CLEARANCE, Roadmap

#: Turret-angle bins over which each pose's candidates are spread.
TURRET_BINS = 24
#: A shortest-path search first looks this many times the lattice (L1) distance far [rad].
SEARCH_SLACK = 1.5


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


def node_coms(robot: Robot, roadmap: Roadmap) -> FloatArray:
    """Arm CoMs of the roadmap's nodes, body frame (N, 3) [m] (computed once per roadmap)."""
    cached = getattr(roadmap, "_node_com", None)
    if cached is None:
        cached = robot.arm_com(roadmap.nodes_q)
        object.__setattr__(roadmap, "_node_com", cached)
    return np.asarray(cached)


def _clearances(robot: Robot, roadmap: Roadmap) -> FloatArray:
    """The roadmap's per-node clearance cache [m] (NaN: not measured yet)."""
    cached = getattr(roadmap, "_node_clearance", None)
    if cached is None:
        cached = np.full(len(roadmap.nodes_q), np.nan)
        object.__setattr__(roadmap, "_node_clearance", cached)
    return np.asarray(cached)


def nodes_clear(
    robot: Robot, roadmap: Roadmap, reach: NDArray[np.intp], rows: NDArray[np.intp]
) -> NDArray[np.bool_]:
    """Whether the nodes ``reach[rows]`` keep :data:`MOVE_CLEARANCE` [m] from the robot.

    The FCL clearance of a node is measured on first use and kept with the roadmap.
    """
    cached = _clearances(robot, roadmap)
    nodes = reach[rows]
    todo = nodes[np.isnan(cached[nodes])]
    if todo.size:
        cached[todo] = CollisionChecker(robot).clearance(roadmap.nodes_q[todo])
    return np.asarray(cached[nodes] >= MOVE_CLEARANCE)


@dataclasses.dataclass(frozen=True)
class NodeClearance:
    """The reachable nodes' clearance test.

    ``clear(rows)``: whether ``reach[rows]`` keep the clearance; ``too_close()``: the rows
    of ``reach`` already measured too close at earlier poses.
    """

    robot: Robot
    roadmap: Roadmap
    reach: NDArray[np.intp]

    def __call__(self, rows: NDArray[np.intp]) -> NDArray[np.bool_]:
        """Whether ``reach[rows]`` keep :data:`MOVE_CLEARANCE` (measured on first use)."""
        return nodes_clear(self.robot, self.roadmap, self.reach, rows)

    def too_close(self) -> NDArray[np.intp]:
        """Rows of ``reach`` whose clearance, measured at an earlier pose, is too small."""
        return np.flatnonzero(_clearances(self.robot, self.roadmap)[self.reach] < MOVE_CLEARANCE)


def clear_candidates(
    values: FloatArray,
    bins: NDArray[np.intp],
    count: int,
    members: list[NDArray[np.intp]],
    clear: Callable[[NDArray[np.intp]], NDArray[np.bool_]],
) -> tuple[NDArray[np.intp], FloatArray]:
    """A pose's ``count`` candidates spread over the turret, each clear of the robot.

    The best of each turret bin in turn (``_diverse_top``); a chosen row that is not
    ``clear`` gets value -inf and the choice is made again, until every finite choice is
    clear. Returns the rows and the values (-inf where not clear). A ``clear`` with a
    ``too_close()`` (:class:`NodeClearance`) names the rows earlier poses measured too close:
    they are set to -inf first, so the choice is remade only for rows measured here for
    the first time.

    The tracked arm follows the plan's postures within a few millimetres, and a tracking
    run must keep 1 mm (``mmstab.runs.verdict.MIN_CLEARANCE``): on random routes postures
    1.5 mm from the body were chosen and touched it when tracked.
    """
    v = np.array(values, dtype=float)
    if isinstance(clear, NodeClearance):
        v[clear.too_close()] = -np.inf
    while True:
        rows = _diverse_top(v, bins, count, members)
        finite = rows[np.isfinite(v[rows])]
        bad = finite[~clear(finite)]
        if bad.size == 0:
            return rows, v
        v[bad] = -np.inf


def _pose_candidates(
    robot: Robot,
    g: FloatArray,
    samples: FloatArray,
    stowed: FloatArray,
    stab: PlannerSettings,
    mu_max: float,
    diameter: float,
    count: int,
    bins: NDArray[np.intp],
    members: list[NDArray[np.intp]],
    clear: Callable[[NDArray[np.intp]], NDArray[np.bool_]],
) -> tuple[NDArray[np.intp], FloatArray, FloatArray]:
    """Each pose's ``count`` clear candidates among the reachable nodes' CoMs.

    Args: gravity ``g`` in B (K, 3) [m/s^2]; the nodes' CoMs ``samples`` (N, 3) [m]; the
    rest as :func:`solve_roadmap_sequence` builds them. Returns (rows (K, count), Eq. 6
    values with -inf where unstable or not clear, μ (K, count) [N rad]).
    """
    K = len(g)
    cand = np.empty((K, count), dtype=np.intp)
    value, mu = np.empty((K, count)), np.empty((K, count))
    for k in range(K):  # clear: the node keeps MOVE_CLEARANCE from the robot
        fit = pose_fitness(robot, g[k], stowed, stab, mu_max, diameter)
        cand[k], v = clear_candidates(fit.linear()(samples), bins, count, members, clear)
        mu[k] = fit.mu(samples[cand[k]])
        value[k] = np.where(mu[k] > 0, v[cand[k]], -np.inf)
    return cand, value, mu


def _transitions(
    samples: FloatArray,
    turret: FloatArray,
    cand: NDArray[np.intp],
    pairs: list[tuple[int, int]],
    w: float,
    window: float | None,
) -> tuple[list[FloatArray], list[NDArray[np.bool_]]]:
    """Eq. 6's motion term between consecutive poses' candidates, and the allowed moves.

    The term is ``w`` [1/m^2] times the squared CoM distance [m]; a move is allowed when
    link0 (``turret`` [rad] per node) changes by at most ``window`` [rad] (None: any).
    """
    M = cand.shape[1]
    motion, allowed = [], []
    for a, b in pairs:
        ca, cb = samples[cand[a]], samples[cand[b]]
        motion.append(w * np.sum((ca[:, None, :] - cb[None, :, :]) ** 2, axis=2))
        ok = np.ones((M, M), dtype=bool)
        if window is not None:
            ok &= np.abs(turret[cand[a]][:, None] - turret[cand[b]]) <= window + 1e-9
        allowed.append(ok)
    return motion, allowed


def _moves(
    robot: Robot,
    roadmap: Roadmap,
    start: int,
    start_q: FloatArray,
    nodes: NDArray[np.intp],
    closed: bool,
) -> list[FloatArray]:
    """The arm's moves into each chosen node: shortest roadmap paths, shortcut where free.

    From the start node (an open path) or the last pose's node (a loop); an open path's
    first move starts at the start posture ``start_q`` [rad] itself.
    """
    K = len(nodes)
    before = [nodes[-1] if closed and K > 1 else start, *nodes[:-1]]
    checker = CollisionChecker(robot)  # the staircase's corners cut where the cut is free
    moves = [
        roadmap.shortcut(checker, roadmap_move(roadmap, int(a), int(b)))
        for a, b in zip(before, nodes, strict=True)
    ]
    if not closed or K == 1:  # from the start posture itself onto its node
        first = np.vstack([start_q, moves[0]])
        moves[0] = first if np.linalg.norm(first[1] - first[0]) > 1e-12 else first[1:]
    return moves


def roadmap_move(roadmap: Roadmap, a: int, b: int) -> FloatArray:
    """The shortest roadmap path a -> b as postures (n, 4) [rad].

    A first search bounded by ``SEARCH_SLACK`` times the lattice distance (fast: it
    explores a neighbourhood), else the whole component.
    """
    from scipy.sparse.csgraph import dijkstra

    if a == b:
        return roadmap.nodes_q[[a]].copy()
    d = roadmap.nodes_q[b] - roadmap.nodes_q[a]
    limit = SEARCH_SLACK * float(np.abs(d).sum()) + 2 * float(roadmap.lengths.max(initial=0))
    dist, pred = dijkstra(roadmap.graph, indices=a, return_predecessors=True, limit=limit)
    if not np.isfinite(dist[b]):
        return roadmap.path_postures(a, b)
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
    reach = np.flatnonzero(roadmap.component == roadmap.component[start])
    samples = node_coms(robot, roadmap)[reach]
    g = np.atleast_2d(np.asarray(gravity_body, dtype=float))
    K, M = len(g), min(settings.sequence_candidates, len(reach))
    diameter = float(np.ptp(samples, axis=0).max()) if len(samples) > 1 else 1.0
    stowed = robot.arm_com(start_q)
    stab = settings._replace(w_motion=0.0)
    bins = _turret_bins(roadmap.nodes_q[reach, 0], TURRET_BINS)
    clear = NodeClearance(robot, roadmap, reach)
    members = [np.flatnonzero(bins == b) for b in range(TURRET_BINS)]
    cand, value, mu = _pose_candidates(
        robot, g, samples, stowed, stab, mu_max, diameter, M, bins, members, clear
    )
    w = settings.w_motion / diameter**2
    if not closed:
        value[0] -= w * np.sum((samples[cand[0]] - stowed) ** 2, axis=1)
    pairs = [(k, k + 1) for k in range(K - 1)] + ([(K - 1, 0)] if closed and K > 1 else [])
    motion, allowed = _transitions(
        samples, roadmap.nodes_q[reach, 0], cand, pairs, w, settings.turret_window
    )
    path, total = best_sequence(value, motion, allowed, closed)
    if not np.isfinite(total):
        k = _first_dead_pose(value, allowed)
        x, y, h = np.asarray(poses, dtype=float)[k]
        raise NoPlanError(
            f"planner: no plan on the posture roadmap: at pose {k} (x {x:.2f} m, y {y:.2f} m, "
            f"heading {np.degrees(h):.0f} deg) no stable posture reachable from the arm's start"
            + (" within the turret window" if settings.turret_window is not None else ""),
            k,
        )
    chosen = cand[np.arange(K), path]
    nodes = reach[chosen]
    fitness = value[np.arange(K), path].copy()
    for i, (a, b) in enumerate(pairs):
        fitness[b] -= motion[i][path[a], path[b]]
    moves = _moves(robot, roadmap, int(start), start_q, nodes, closed)
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
