"""The roadmap search's rounds: the candidates chosen, the path searched, searched again.

:class:`Rounds` holds what one route's searches share (the candidates' clearance, the
branch-and-bound's memo, the moves found, the one μ of the postures rested): a first
search, then again where the one μ of a chosen posture falls below its rank
(:class:`OneMu`) or where a turn slides (:func:`mmstab.planner.turning.slide_exclusions`).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from mmstab.core.files import PlanningError
from mmstab.model.collision import CollisionChecker
from mmstab.model.robot import FloatArray, Robot
from mmstab.planner.candidates import Candidates, NodeClearance, SearchMemo, route_candidates
from mmstab.planner.fitness import LinearFitness
from mmstab.planner.ground.under_arm import GroundUnderArm
from mmstab.planner.motion import transitions
from mmstab.planner.searches.roadmap.moves import ground_move, start_tree
from mmstab.planner.searches.sequence import best_sequence
from mmstab.planner.settings import PlannerSettings
from mmstab.stability.support import loaded_mu
from mmstab.terrain import Terrain
from mmstab.workspace.roadmap import Roadmap

#: How far [N rad] a chosen posture's μ on its own loaded support may fall below the μ it
#: was ranked with (the stowed arm's support) before its pose is ranked on the one μ.
ONE_MU_SLACK = 1.0

#: Candidates rested at once at a pose whose choice fell below its rank.
ONE_MU_BLOCK = 32


class NoPlanError(PlanningError):
    """No sequence of reachable stable postures exists; ``pose`` is the first without one."""

    def __init__(self, message: str, pose_index: int):
        super().__init__(message)
        self.pose_index = pose_index


class OneMu:
    """The candidates' one μ, rested lazily where the search's ranking was optimistic.

    The search ranks a pose's candidates on the stowed arm's support (one polygon for all:
    fast). Each chosen posture is rested on its own (:func:`mmstab.stability.support.loaded_mu`,
    the μ the plan reports); where that falls more than :data:`ONE_MU_SLACK` below both
    its rank and the stowed arm's μ, the pose's :data:`ONE_MU_BLOCK` best candidates not
    rested yet are rested too, every rested candidate is ranked on its one μ, and the path
    is searched again; a pose whose choice falls a second time has all its candidates
    rested. Each (pose, node) is rested once, so the rounds end: no choice is more than
    :data:`ONE_MU_SLACK` below the lower of its rank and the stowed arm's μ.
    """

    def __init__(
        self, robot: Robot, terrain: Terrain | None, poses: FloatArray, samples: FloatArray,
        weight: float, stowed: FloatArray,
    ) -> None:  # fmt: skip
        self.robot, self.terrain, self.samples, self.weight = robot, terrain, samples, weight
        self.stowed = np.asarray(stowed, dtype=float)  # the stowed arm's μ per pose [N rad]
        self.poses = np.atleast_2d(np.asarray(poses, dtype=float))
        self.known: dict[tuple[int, int], float] = {}  # (pose, reach row): one μ [N rad]
        self.at: dict[int, set[int]] = {}  # pose: its rested rows
        self.blocked: set[int] = set()  # the poses whose best block was rested

    def mu(self, pairs: list[tuple[int, int]]) -> FloatArray:
        """One μ [N rad] of (pose, reach row) pairs, NaN where the robot has no rest."""
        todo = sorted({p for p in pairs if p not in self.known})
        if todo:
            assert self.terrain is not None
            k, r = np.array(todo, dtype=np.intp).T
            mu = loaded_mu(self.robot, self.terrain, self.poses[k], self.samples[r], strict=False)
            self.known.update(zip(todo, mu.tolist(), strict=True))
            for kk, rr in todo:
                self.at.setdefault(kk, set()).add(rr)
        return np.array([self.known[p] for p in pairs], dtype=float)

    def revalue(
        self, cand: NDArray[np.intp], value: FloatArray, mu: FloatArray,
        start: FloatArray | None = None,
    ) -> None:  # fmt: skip
        """Rank the rested candidates on their one μ (``value``, ``mu`` updated in place).

        ``start``: the first pose's motion cost from the start posture per candidate (an
        open path), or None.
        """
        for k, rows in self.at.items():
            live = np.flatnonzero(np.isfinite(value[k]) & np.isin(cand[k], list(rows)))
            one = self.mu([(k, int(r)) for r in cand[k, live]])
            new = self.weight * one - (start[live] if k == 0 and start is not None else 0.0)
            value[k, live] = np.where(np.isfinite(one), new, -np.inf)
            mu[k, live] = one

    def worse(
        self, cand: NDArray[np.intp], value: FloatArray, mu: FloatArray, path: NDArray[np.intp]
    ) -> NDArray[np.intp]:
        """The poses whose choice, rested now, falls below its rank (their block rested)."""
        K = len(path)
        fresh = [k for k in range(K) if (k, int(cand[k, path[k]])) not in self.known]
        if not fresh:
            return np.zeros(0, dtype=np.intp)
        one = self.mu([(k, int(cand[k, path[k]])) for k in fresh])
        ranked = np.array([mu[k, path[k]] for k in fresh])
        floor = np.minimum(ranked, self.stowed[fresh]) - ONE_MU_SLACK
        out = np.array(fresh, dtype=np.intp)[~(one >= floor)]
        block = []
        for k in out.tolist():
            order = np.argsort(-value[k], kind="stable")
            rows = [int(r) for r in cand[k, order[np.isfinite(value[k, order])]]]
            new = [(k, r) for r in rows if (k, r) not in self.known]
            block += new if k in self.blocked else new[:ONE_MU_BLOCK]  # twice: all of them
            self.blocked.add(k)
        self.mu(block)
        return out


def _first_dead_pose(value: FloatArray, allowed: list[NDArray[np.bool_]]) -> int:
    """The first pose that no allowed sequence of finite values reaches."""
    alive = np.isfinite(value[0])
    for k in range(len(value)):
        if k:
            alive = (allowed[k - 1] & alive[:, None]).any(axis=0) & np.isfinite(value[k])
        if not alive.any():
            return k
    return len(value) - 1


def _no_plan(
    value: FloatArray,
    allowed: list[NDArray[np.bool_]],
    poses: FloatArray,
    settings: PlannerSettings,
) -> NoPlanError:
    """The error naming the first pose no allowed sequence reaches."""
    k = _first_dead_pose(value, allowed)
    x, y, h = np.asarray(poses, dtype=float)[k]
    ground, margin = settings.ground_clearance, settings.attitude_margin
    tilted = "" if not margin else (
        f" through {np.degrees(margin):.0f} deg of body tilt (planner.attitude_margin "
        f"{margin:g} rad)"
    )  # fmt: skip
    return NoPlanError(
        f"planner: no plan on the posture roadmap: at pose {k} (x {x:.2f} m, y {y:.2f} m, "
        f"heading {np.degrees(h):.0f} deg) no stable posture reachable from the arm's start"
        + (" within the turret window" if settings.turret_window is not None else "")
        + ("" if ground is None else f" with the arm {ground:g} m above the ground{tilted}"),
        k,
    )


class Mover:
    """The arm's moves into each chosen node (:func:`~.roadmap.moves.ground_move`).

    From the start node (an open path) or the last pose's node (a loop); each move kept
    per pair of nodes and the poses it joins, so a plan chosen again reuses them.
    """

    def __init__(
        self, robot: Robot, roadmap: Roadmap, start: int, ground: float | None,
        under: GroundUnderArm | None,
    ) -> None:  # fmt: skip
        self.robot, self.roadmap, self.start, self.ground, self.under = (
            robot, roadmap, start, ground, under,
        )  # fmt: skip
        self.checker = CollisionChecker(robot)  # the staircase's corners cut where free
        self.tree = start_tree(roadmap, start, ground)
        self.kept: dict[tuple[int, int, tuple[int, ...]], FloatArray | None] = {}
        self.low: dict[tuple[int, ...], set[int]] = {}  # nodes found too low, per pair of poses

    def moves(self, nodes: NDArray[np.intp], closed: bool) -> tuple[list[FloatArray], list[int]]:
        """The moves into ``nodes`` (K,), and the pairs with none (-1: the first, from start)."""
        K = len(nodes)
        loop = closed and K > 1
        before = [nodes[-1] if loop else self.start, *nodes[:-1]]
        moves: list[FloatArray] = []
        failed: list[int] = []
        for k, (a, b) in enumerate(zip(before, nodes, strict=True)):
            ks = ((K - 1 if loop else 0), 0) if k == 0 else (k - 1, k)
            key = (int(a), int(b), ks)
            if key not in self.kept:
                poses = tuple(sorted(set(ks)))
                self.kept[key] = ground_move(
                    self.robot, self.roadmap, self.checker, int(a), int(b), self.ground,
                    self.under, poses, self.tree, known=self.low.setdefault(poses, set()),
                )  # fmt: skip
            move = self.kept[key]
            if move is None:
                failed.append(K - 1 if loop and k == 0 else k - 1)
            else:
                moves.append(move)
        return moves, failed


def _forbid_low_ends(
    clear: NodeClearance,
    cand: NDArray[np.intp],
    value: FloatArray,
    allowed: list[NDArray[np.bool_]],
    pairs: list[tuple[int, int]],
) -> None:
    """Forbid the moves one of whose ends is too low above the other pose's ground.

    The arm moves while the base drives between the two poses: each end posture must
    clear both poses' ground (measured for the stable candidates only).
    """
    for i, (ka, kb) in enumerate(pairs):
        fa, fb = np.isfinite(value[ka]), np.isfinite(value[kb])
        allowed[i][fa] &= clear.at(kb, cand[ka, fa])[:, None]
        allowed[i][:, fb] &= clear.at(ka, cand[kb, fb])[None, :]


def _choose(
    value: FloatArray,
    motion: list[FloatArray],
    allowed: list[NDArray[np.bool_]],
    pairs: list[tuple[int, int]],
    closed: bool,
    cand: NDArray[np.intp],
    reach: NDArray[np.intp],
    mover: Mover,
    best: NDArray[np.intp] | None = None,
) -> tuple[NDArray[np.intp], NDArray[np.intp] | None, list[FloatArray]]:
    """The best sequence whose moves all clear the ground: the choice (K,), its nodes, moves.

    A move with no path clear of the ground at the poses it joins is forbidden and the
    choice made again (``value`` and ``allowed`` updated in place); nodes None: no plan.
    ``best``: the best sequence over these values, if known.
    """
    K = len(value)
    while True:
        if best is not None:
            path, total, best = best, 0.0, None
        else:
            path, total = best_sequence(value, motion, allowed, closed)
        if not np.isfinite(total):
            return path, None, []
        nodes = reach[cand[np.arange(K), path]]
        moves, failed = mover.moves(nodes, closed)
        if not failed:
            return path, nodes, moves
        for i in failed:  # -1: the open path's first move, from the start
            if i < 0:
                value[0, path[0]] = -np.inf
            else:
                allowed[i][path[pairs[i][0]], path[pairs[i][1]]] = False


class Searched(NamedTuple):
    """One search's answer and what choosing again needs.

    Attributes:
        cand: each pose's candidates, reach rows (K, M).
        value: their Eq. 6 stability terms, the first move's cost taken off (K, M).
        mu: their μ on the basis each is ranked on [N rad] (K, M).
        motion: the motion cost of each pair of poses' candidates (M, M) each.
        allowed: the moves allowed between them (M, M) each.
        start: the first pose's motion cost from the start posture (M,), None on a loop.
        path: the chosen candidate per pose (K,).
        nodes: the chosen roadmap nodes (K,).
        moves: the roadmap paths into them.
    """

    cand: NDArray[np.intp]
    value: FloatArray
    mu: FloatArray
    motion: list[FloatArray]
    allowed: list[NDArray[np.bool_]]
    start: FloatArray | None
    path: NDArray[np.intp]
    nodes: NDArray[np.intp]
    moves: list[FloatArray]


class Rounds:
    """One route's searches over the roadmap's candidates (module text).

    Args:
        fits: Eq. 6's stability term per pose (``w_motion`` 0).
        view: the roadmap component's view (:func:`mmstab.planner.searches.roadmap.component_view`).
        count: candidates per pose.
        clear: the candidates' clearance test.
        cost: the motion cost (:func:`mmstab.planner.motion.motion_cost`).
        closed: the path is a loop.
        mover: the moves into the chosen nodes.
        one: the one μ of the postures rested.
        start_point: the start posture's point of the motion cost (an open path).
        joint0: the reach rows' turret angles (N,) [rad].
        settings: the planner settings (``turret_window``).
        poses: the base poses (K, 3) [m, m, rad], for messages.
    """

    def __init__(
        self, fits: list[LinearFitness], view: Any, count: int, clear: NodeClearance, cost: Any,
        closed: bool, mover: Mover, one: OneMu, start_point: Any, joint0: FloatArray,
        settings: PlannerSettings, poses: FloatArray,
    ) -> None:  # fmt: skip
        self.fits, self.view, self.count, self.clear, self.cost = fits, view, count, clear, cost
        self.closed, self.mover, self.one, self.start_point = closed, mover, one, start_point
        self.joint0, self.settings, self.poses = joint0, settings, poses
        K = len(fits)
        self.pairs = [(k, k + 1) for k in range(K - 1)] + ([(K - 1, 0)] if closed and K > 1 else [])
        self.memo = SearchMemo()  # what the searches share: the clusters' bounds, rows valued
        self.first: Candidates | None = None  # the first search's candidates, as chosen
        self.touched: set[int] = set()  # the poses whose candidates were chosen again

    def search(self, changed: NDArray[np.intp] | None = None) -> Searched:
        """Choose the candidates (again at ``changed`` and every pose changed before), search."""
        if changed is not None:
            self.touched.update(int(k) for k in changed)
            changed = np.array(sorted(self.touched), dtype=np.intp)
        v = self.view
        found = route_candidates(self.fits, v.samples, v.bins, v.clusters, self.count,
                                 self.clear, self.first, changed, self.memo)  # fmt: skip
        if self.first is None:
            self.first = found._replace(value=found.value.copy(), mu=found.mu.copy())
        cand, value, mu = found
        start = None
        if not self.closed:
            start = self.cost.from_point(cand[0], self.start_point)
            value[0] -= start
        motion, allowed = transitions(
            self.cost.points, self.joint0, cand, self.pairs, self.cost.weight,
            self.settings.turret_window, self.cost.metric,
        )  # fmt: skip
        return self.choose(cand, value, mu, motion, allowed, start)

    def choose(
        self, cand: NDArray[np.intp], value: FloatArray, mu: FloatArray,
        motion: list[FloatArray], allowed: list[NDArray[np.bool_]], start: FloatArray | None,
    ) -> Searched:  # fmt: skip
        """The best sequence over these candidates, those rested ranked on the one μ."""
        self.one.revalue(cand, value, mu, start)
        _forbid_low_ends(self.clear, cand, value, allowed, self.pairs)
        held = self._held(cand, value, mu, motion, allowed, start)
        path, nodes, moves = _choose(value, motion, allowed, self.pairs, self.closed, cand,
                                     self.view.reach, self.mover, held)  # fmt: skip
        if nodes is None:
            raise _no_plan(value, allowed, self.poses, self.settings)
        return Searched(cand, value, mu, motion, allowed, start, path, nodes, moves)

    def _held(
        self, cand: NDArray[np.intp], value: FloatArray, mu: FloatArray,
        motion: list[FloatArray], allowed: list[NDArray[np.bool_]], start: FloatArray | None,
    ) -> NDArray[np.intp] | None:  # fmt: skip
        """The best sequence, chosen again without its moves until the one μ holds along it.

        The moves (the costliest step) are found for this sequence only, not for the ones
        the one μ turns down. None: no sequence (the caller says where).
        """
        path, total = best_sequence(value, motion, allowed, self.closed)
        if not np.isfinite(total):
            return None
        return self._dry(cand, value, mu, motion, allowed, start, path)[0]

    def _dry(
        self, cand: NDArray[np.intp], value: FloatArray, mu: FloatArray,
        motion: list[FloatArray], allowed: list[NDArray[np.bool_]], start: FloatArray | None,
        path: NDArray[np.intp],
    ) -> tuple[NDArray[np.intp], bool]:  # fmt: skip
        """From ``path``, the sequence chosen again (no moves) until the one μ holds along it.

        Returns it and whether every round found a sequence (False: a guard, as only values
        change; the last sequence found is returned).
        """
        if self.one.terrain is None:
            return path, True
        while len(self.one.worse(cand, value, mu, path)):
            self.one.revalue(cand, value, mu, start)
            again, total = best_sequence(value, motion, allowed, self.closed)
            if not np.isfinite(total):
                return path, False
            path = again
        return path, True

    def on_one_mu(self, got: Searched) -> Searched:
        """Search again while a chosen posture's one μ falls below its rank (:class:`OneMu`).

        The sequence is chosen again without its moves until the one μ holds along it; then
        its moves are found (a move not clear of the ground chooses again, checked again).
        """
        if self.one.terrain is None:
            return got
        path = got.path
        while True:
            path, found = self._dry(got.cand, got.value, got.mu, got.motion, got.allowed,
                                    got.start, path)  # fmt: skip
            if not found:  # the answer before stands
                return got
            if np.array_equal(path, got.path):  # (its values updated in place)
                return got
            path, nodes, moves = _choose(got.value, got.motion, got.allowed, self.pairs,
                                         self.closed, got.cand, self.view.reach, self.mover,
                                         path)  # fmt: skip
            if nodes is None:  # no moves clear of the ground: the answer before stands
                return got
            got = got._replace(path=path, nodes=nodes, moves=moves)
