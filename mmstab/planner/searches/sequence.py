"""``method: sequence``: the whole path at once, Eq. 6 summed along it over V's postures.

The per-pose planner chooses a CoM; the arm must then move between the chosen CoMs, and
two good CoMs at neighbouring poses can lie on either side of a flipper or of the turret's
end stop, which no arm motion between them avoids. ``method: sequence`` chooses one of V's
samples per pose (each the CoM of a collision-free grid posture, so the posture comes with
it) to maximise the sum of Eq. 6 along the path,

    Σ_k  w_stability μ_k(g_k) / μ_max − w_motion |g_k − g_{k−1}|² / d²

(g_{−1}: the stowed arm on an open path, the last pose's choice on a closed one),

subject to, between consecutive poses (and, on a closed path, from the last to the first):
the turret moving at most ``turret_window`` [rad] (when set), and the straight joint-space
move between the two postures being collision-free. It is Eq. 6 with the previous CoM
being the path's own choice, solved exactly over each pose's ``sequence_candidates`` best
samples by dynamic programming (Viterbi). Collision checks are lazy: the best sequence's
moves are checked, colliding ones are forbidden, and the search repeats (as lazy PRM).

**Ground.** V knows the robot's body only, and a low arm CoM maximises μ: without a check
the ramp's plan put the arm 7.9 cm below the plane the tracks rest on, and in MuJoCo the
arm touched the ground. With ``planner.ground_clearance`` [m] (None: not checked), a
candidate's arm keeps that height above the support plane z_B = 0
(:func:`mmstab.model.plane_clearance.arm_ground_clearance`), and a move that dips below it is
forbidden like a colliding one, sampled by the roadmap's rule
(:func:`mmstab.model.plane_clearance.lowest_along_moves`, ``CLEARANCE_STEP``).
"""

from __future__ import annotations

import time
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from mmstab.core.files import PlanningError
from mmstab.model.collision import CollisionChecker
from mmstab.model.plane_clearance import arm_ground_clearance, lowest_along_moves
from mmstab.model.reach import sampled_reach
from mmstab.model.robot import FloatArray, Robot
from mmstab.planner.fitness import Fitness, pose_fitness
from mmstab.planner.regions import CoMRegion, PlanningRegion, as_region
from mmstab.planner.searches.base import PathChoice, PathTask, PoseChoice, PoseTask
from mmstab.planner.searches.exhaustive import ExhaustiveSearch
from mmstab.planner.settings import PlannerSettings
from mmstab.planner.wrench import with_tool_wrench
from mmstab.workspace.roadmap import CLEARANCE_STEP, MOVE_CLEARANCE, move_keeps_clearance

#: Postures checked along each straight joint-space move between consecutive poses.
SEGMENT_STEPS = 24
#: Rounds of "search, check the chosen moves, forbid the colliding ones" at most.
MAX_ROUNDS = 400
#: First-pose candidates tried as the start of a closed path (best first).
CLOSED_STARTS = 4
#: Turret-angle bins over which each pose's candidates are spread.
TURRET_BINS = 24


class SequenceResult(NamedTuple):
    """The chosen samples along the path.

    Attributes:
        rows: the chosen sample per pose, rows of V's samples (K,).
        fitness: Eq. 6 per pose, with the previous pose's choice as previous CoM (K,).
        mu: force-angle measure per pose [N rad] (K,).
        total: the sum of ``fitness``.
        rounds: search rounds (one more than the times colliding moves were found).
        forbidden: moves found colliding and forbidden.
        seconds: wall time [s].
    """

    rows: NDArray[np.intp]
    fitness: FloatArray
    mu: FloatArray
    total: float
    rounds: int
    forbidden: int
    seconds: float


def segments_collide(
    checker: CollisionChecker, q_from: FloatArray, q_to: FloatArray
) -> NDArray[np.bool_]:
    """Whether straight joint-space moves q_from -> q_to (N, n) [rad] collide anywhere.

    Checked at ``SEGMENT_STEPS`` interior postures of each move in one batch (the ends are
    V's collision-free postures): the quick first sieve of :meth:`MoveCheck.refused`.
    """
    a, b = np.broadcast_arrays(np.atleast_2d(q_from), np.atleast_2d(q_to))
    u = (np.arange(1, SEGMENT_STEPS + 1) / (SEGMENT_STEPS + 1))[None, :, None]
    q = (a[:, None, :] * (1 - u) + b[:, None, :] * u).reshape(-1, a.shape[1])
    hit = np.asarray(checker.collides(q), dtype=bool).reshape(len(a), SEGMENT_STEPS)
    return np.asarray(hit.any(axis=1), dtype=bool)


class MoveCheck(NamedTuple):
    """What forbids a straight joint-space move between consecutive poses' postures.

    Attributes:
        checker: the collision checker (a move colliding anywhere is refused).
        robot: the robot.
        reach: per joint, the bound on an arm point's distance from its axis (n,) [m]
            (:func:`mmstab.model.reach.sampled_reach`).
        ground: least height of the arm above z_B = 0 along the move [m]; None: not checked.
    """

    checker: CollisionChecker
    robot: Robot
    reach: FloatArray
    ground: float | None = None

    def refused(self, q_from: FloatArray, q_to: FloatArray) -> NDArray[np.bool_]:
        """Whether moves q_from -> q_to (N, n) [rad] pass too near the robot or the ground.

        Too near the robot: within :data:`MOVE_CLEARANCE` [m]; the ground: below ``ground``.
        The roadmap's moves' rule (:func:`~mmstab.workspace.roadmap.move_keeps_clearance`):
        the tracked arm follows the move within a few millimetres, and a tracking run keeps
        1 mm. Checked at the moves' length (no arm point moves more than ``CLEARANCE_STEP``
        between two checked postures): a 5.4 rad turret swing checked at 24 postures passed
        0.2 mm from the body between two of them.
        """
        hit = segments_collide(self.checker, q_from, q_to)
        if self.ground is not None:
            low = lowest_along_moves(self.robot, self.reach, q_from, q_to, CLEARANCE_STEP)
            hit |= low < self.ground
        for i in np.flatnonzero(~hit):
            hit[i] = not move_keeps_clearance(
                self.checker, self.reach, q_from[i], q_to[i], MOVE_CLEARANCE
            )
        return hit


def move_check(
    robot: Robot, region: PlanningRegion, ground: float | None, checker: CollisionChecker
) -> MoveCheck:
    """The moves' check on V's postures, with the roadmap's reach of them (kept by V)."""
    reach = region.view(
        ("reach", robot.source_hash), lambda: sampled_reach(robot, region.root.valid_q)
    )
    return MoveCheck(checker, robot, reach, ground)


def above_ground(robot: Robot, region: PlanningRegion, ground: float | None) -> NDArray[np.bool_]:
    """Which of V's samples keep the arm ``ground`` [m] above z_B = 0 (all when None) (M,)."""
    postures = region.postures
    if ground is None:
        return np.ones(len(postures), dtype=bool)
    low = region.view(
        ("arm_ground", robot.source_hash), lambda: arm_ground_clearance(robot, postures)
    )
    return np.asarray(low >= ground)


def _viterbi(
    value: FloatArray, motion: list[FloatArray], allowed: list[NDArray[np.bool_]]
) -> tuple[NDArray[np.intp], float]:
    """Best candidate per pose: max Σ value[k][c_k] − motion[k][c_{k−1}, c_k] over allowed moves.

    Args:
        value: (K, M) per-pose values of each candidate (the first pose's motion included).
        motion: K−1 matrices (M, M): cost of the move from candidate a to b.
        allowed: K−1 boolean matrices (M, M).

    Returns:
        (candidate per pose (K,), total); total is -inf when no sequence is allowed.
    """
    K, M = value.shape
    score = value[0].copy()
    back = np.zeros((K, M), dtype=np.intp)
    for k in range(1, K):
        total = np.where(allowed[k - 1], score[:, None] - motion[k - 1], -np.inf)
        back[k] = np.argmax(total, axis=0)
        score = total[back[k], np.arange(M)] + value[k]
    last = int(np.argmax(score))
    path = np.empty(K, dtype=np.intp)
    path[-1] = last
    for k in range(K - 1, 0, -1):
        path[k - 1] = back[k, path[k]]
    return path, float(score[last])


def solve_sequence(
    robot: Robot,
    gravity_body: FloatArray,
    region: CoMRegion,
    settings: PlannerSettings,
    mu_max: float,
    closed: bool,
    checker: CollisionChecker | None = None,
) -> SequenceResult:
    """Choose one of V's samples per pose (module text).

    Args:
        robot: the robot.
        gravity_body: gravity in the body frame at each pose (K, 3) [m/s^2].
        region: the workspace V (its samples and their postures).
        settings: planner settings (weights, ``turret_window``, ``sequence_candidates``).
        mu_max: Eq. 6's normaliser [N rad].
        closed: the path is a loop: the move from the last pose to the first is checked too.
        checker: collision checker (default: the robot's).

    Raises:
        PlanningError: no sequence satisfies the constraints among the candidates.
    """
    t0 = time.perf_counter()
    checker = CollisionChecker(robot) if checker is None else checker
    region = as_region(region)
    g = np.atleast_2d(np.asarray(gravity_body, dtype=float))
    graph = _candidate_graph(robot, g, region, settings, mu_max, closed)
    moves = move_check(robot, region, settings.ground_clearance, checker)
    path, rounds, forbidden = _search_lazily(graph, region.postures, moves, closed)
    K = len(g)
    rows = graph.cand[np.arange(K), path]
    fitness = graph.value[np.arange(K), path].copy()
    for i, (a, b) in enumerate(graph.pairs):
        fitness[b] -= graph.motion[i][path[a], path[b]]
    samples = region.index.samples
    mu = np.array([graph.fits[k].mu(samples[rows[k]])[0] for k in range(K)])
    return SequenceResult(
        rows=rows,
        fitness=fitness,
        mu=mu,
        total=float(fitness.sum()),
        rounds=rounds,
        forbidden=forbidden,
        seconds=time.perf_counter() - t0,
    )


class _Graph(NamedTuple):
    """The candidates per pose and the moves between consecutive poses' candidates.

    Attributes:
        cand: each pose's candidate rows of V's samples (K, M).
        value: their Eq. 6 stability term (the first pose's move from stowed included) (K, M).
        fits: each pose's Eq. 6 (its ``mu`` gives the reported μ).
        pairs: the (from, to) poses of each move (the closing one on a closed path).
        motion: per move, Eq. 6's motion term between the candidates (M, M).
        allowed: per move, which candidate pairs may follow (turret window, no collision,
            the arm kept above the ground).
    """

    cand: NDArray[np.intp]
    value: FloatArray
    fits: list[Fitness]
    pairs: list[tuple[int, int]]
    motion: list[FloatArray]
    allowed: list[NDArray[np.bool_]]


def _candidate_graph(
    robot: Robot,
    g: FloatArray,
    region: PlanningRegion,
    settings: PlannerSettings,
    mu_max: float,
    closed: bool,
) -> _Graph:
    """Each pose's candidates, spread over turret bins, and the moves between them.

    Only samples whose arm keeps ``settings.ground_clearance`` above the plane are candidates.

    Raises:
        PlanningError: no sample of V keeps the arm that far above the plane.
    """
    samples = region.index.samples
    postures = region.postures
    diameter = float(region.diameter)
    above = above_ground(robot, region, settings.ground_clearance)
    if not above.any():
        raise PlanningError(
            f"planner: no posture of V keeps the arm planner.ground_clearance "
            f"({settings.ground_clearance} m) above the plane the tracks rest on"
        )
    K, M = len(g), min(settings.sequence_candidates, int(above.sum()))
    stowed = robot.arm_com(robot.stowed)
    stab = settings._replace(w_motion=0.0)
    cand = np.empty((K, M), dtype=np.intp)
    value = np.empty((K, M))
    bins = _turret_bins(postures[:, 0], TURRET_BINS)
    members = [np.flatnonzero((bins == b) & above) for b in range(TURRET_BINS)]
    fits = []
    for k in range(K):  # each pose's best samples by Eq. 6's stability term, per turret bin
        fits.append(
            with_tool_wrench(pose_fitness(robot, g[k], stowed, stab, mu_max, diameter), region)
        )
        v = fits[k].linear()(samples)
        cand[k] = _diverse_top(v, bins, M, members)
        value[k] = v[cand[k]]
    w = settings.w_motion / diameter**2
    if not closed:  # open path: the first pose moves from the stowed arm; closed: from the last
        value[0] -= w * np.sum((samples[cand[0]] - stowed) ** 2, axis=1)
    motion, allowed = [], []
    pairs = [(k, k + 1) for k in range(K - 1)] + ([(K - 1, 0)] if closed and K > 1 else [])
    for a, b in pairs:
        ca, cb = samples[cand[a]], samples[cand[b]]
        motion.append(w * np.sum((ca[:, None, :] - cb[None, :, :]) ** 2, axis=2))
        ok = np.ones((M, M), dtype=bool)
        if settings.turret_window is not None:
            d0 = postures[cand[a], 0][:, None] - postures[cand[b], 0][None, :]
            ok &= np.abs(d0) <= settings.turret_window + 1e-9
        allowed.append(ok)
    return _Graph(cand, value, fits, pairs, motion, allowed)


def _search_lazily(
    graph: _Graph, postures: FloatArray, moves: MoveCheck, closed: bool
) -> tuple[NDArray[np.intp], int, int]:
    """Best sequence, its moves checked and refused ones forbidden until none is refused.

    Returns:
        (candidate per pose, rounds, moves forbidden); ``graph.allowed`` is updated.

    Raises:
        PlanningError: no sequence is allowed, or it did not settle in ``MAX_ROUNDS``.
    """
    cand, pairs, allowed = graph.cand, graph.pairs, graph.allowed
    checked: set[tuple[int, int, int]] = set()
    forbidden, rounds = 0, 0
    while rounds < MAX_ROUNDS:
        rounds += 1
        path, total = _best(graph.value, graph.motion, allowed, closed)
        if not np.isfinite(total):
            raise PlanningError(
                "planner: no sequence of V's postures has collision-free moves within the "
                "turret window that keep the arm planner.ground_clearance above the plane "
                "(raise planner.sequence_candidates or turret_window)"
            )
        chosen = [(i, path[a], path[b]) for i, (a, b) in enumerate(pairs)]
        todo = [m for m in chosen if m not in checked]
        if not todo:
            break
        qa = np.array([postures[cand[pairs[i][0], x]] for i, x, _ in todo])
        qb = np.array([postures[cand[pairs[i][1], y]] for i, _, y in todo])
        hit = moves.refused(qa, qb)
        checked.update(todo)
        for (i, x, y), h in zip(todo, hit, strict=True):
            if h:
                allowed[i][x, y] = False
                forbidden += 1
        if not hit.any():
            break
    else:
        raise PlanningError(f"planner: sequence search did not settle in {MAX_ROUNDS} rounds")
    return path, rounds, forbidden


def _turret_bins(turret: FloatArray, count: int) -> NDArray[np.intp]:
    """Bin of each sample's turret angle: ``count`` equal bins over its range."""
    lo, hi = float(turret.min()), float(turret.max())
    width = max(hi - lo, 1e-12) / count
    return np.minimum(((turret - lo) / width).astype(np.intp), count - 1)


def _diverse_top(
    values: FloatArray,
    bins: NDArray[np.intp],
    count: int,
    members: list[NDArray[np.intp]] | None = None,
) -> NDArray[np.intp]:
    """``count`` rows: the best of every turret bin in turn (round robin), best first.

    The best samples of a pose crowd into one basin; the sequence needs good ones at every
    turret angle so that a neighbour pose's choice has candidates within the window.
    ``members``: the rows of each bin (ascending), to look only at each bin's ``count``
    best (the same answer as sorting every row, far cheaper).
    """
    if members is not None:  # only a bin's `count` best can be chosen: sort those alone
        keep = []
        for rows in members:
            if len(rows) > count:
                rows = rows[np.argpartition(-values[rows], count - 1)[:count]]
            keep.append(rows)
        subset = np.sort(np.concatenate(keep))
        chosen = _diverse_top(values[subset], bins[subset], count)
        return subset[chosen]
    order = np.argsort(-values, kind="stable")
    b = bins[order]
    rank = np.empty(len(order), dtype=np.intp)  # rank of each sample within its bin
    for k in np.unique(b):
        at = np.flatnonzero(b == k)
        rank[at] = np.arange(len(at))
    chosen = order[np.lexsort((-values[order], rank))][:count]
    return chosen[np.argsort(-values[chosen], kind="stable")]


def best_sequence(
    value: FloatArray,
    motion: list[FloatArray],
    allowed: list[NDArray[np.bool_]],
    closed: bool,
    starts: NDArray[np.intp] | None = None,
) -> tuple[NDArray[np.intp], float]:
    """Exact max of Σ value[k][c_k] − motion[k][c_{k−1}, c_k] over allowed moves.

    Open: Viterbi. Closed (``motion``/``allowed`` have K entries, the last closing the loop):
    Viterbi from each first candidate of ``starts`` in turn (default: every feasible one),
    the closing move folded into the last pose's values; the first best wins a tie. Total
    -inf when no sequence is allowed.
    """
    K = len(value)
    if not closed or K == 1:
        return _viterbi(value, motion[: K - 1], allowed[: K - 1])
    if starts is None:
        starts = np.flatnonzero(np.isfinite(value[0]))
    best_path, best_total = np.zeros(K, dtype=np.intp), -np.inf
    for start in starts:
        v = value.copy()
        v[0] = -np.inf
        v[0, start] = value[0, start]
        # the closing move ends at the start: fold it into the last pose's values
        close = np.where(allowed[K - 1][:, start], -motion[K - 1][:, start], -np.inf)
        v[K - 1] = v[K - 1] + close
        path, total = _viterbi(v, motion[: K - 1], allowed[: K - 1])
        if total > best_total:
            best_path, best_total = path, total
    return best_path, best_total


def _best(
    value: FloatArray, motion: list[FloatArray], allowed: list[NDArray[np.bool_]], closed: bool
) -> tuple[NDArray[np.intp], float]:
    """The best sequence; on a closed path, over the first pose's ``CLOSED_STARTS`` best starts."""
    starts = np.argsort(-value[0], kind="stable")[:CLOSED_STARTS]
    return best_sequence(value, motion, allowed, closed, starts)


class SequenceSearch:
    """One of V's samples per pose, Eq. 6 summed along the path, collision-free moves.

    Per pose (a caller planning one pose) it is the exhaustive reference.
    """

    def choose(self, task: PoseTask) -> PoseChoice:
        """The exhaustive answer at a single pose."""
        return ExhaustiveSearch().choose(task)

    def choose_path(self, task: PathTask) -> PathChoice:
        """The chosen samples and their grid postures."""
        seq = solve_sequence(
            task.robot, task.gravity_body, task.region, task.settings, task.mu_max, task.closed
        )
        region = task.region
        return PathChoice(
            target_com=region.index.samples[seq.rows],
            postures=region.postures[seq.rows],
            fitness=seq.fitness,
            mu=seq.mu,
        )
