"""The roadmap search's steps: the best sequence, the moves into it, no plan.

The exact dynamic programming over each pose's candidates (:func:`best_sequence`), the
moves into the chosen nodes (:class:`Mover`), the moves a low arm forbids and the choice
made again until every move clears the ground (:func:`_choose`), and the error naming the
first pose no sequence reaches (:class:`NoPlanError`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from mmstab.core.files import PlanningError
from mmstab.model.collision import CollisionChecker
from mmstab.model.robot import FloatArray, Robot
from mmstab.planner.candidates import NodeClearance
from mmstab.planner.ground.under_arm import GroundUnderArm
from mmstab.planner.searches.roadmap.moves import ground_move, start_tree
from mmstab.planner.searches.sequence import _viterbi
from mmstab.planner.settings import PlannerSettings
from mmstab.workspace.roadmap import Roadmap


class NoPlanError(PlanningError):
    """No sequence of reachable stable postures exists; ``pose`` is the first without one."""

    def __init__(self, message: str, pose_index: int):
        super().__init__(message)
        self.pose_index = pose_index


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


def _no_plan(
    value: FloatArray,
    allowed: list[NDArray[np.bool_]],
    poses: FloatArray,
    settings: PlannerSettings,
) -> NoPlanError:
    """The error naming the first pose no allowed sequence reaches."""
    k = _first_dead_pose(value, allowed)
    x, y, h = np.asarray(poses, dtype=float)[k]
    ground = settings.ground_clearance
    return NoPlanError(
        f"planner: no plan on the posture roadmap: at pose {k} (x {x:.2f} m, y {y:.2f} m, "
        f"heading {np.degrees(h):.0f} deg) no stable posture reachable from the arm's start"
        + (" within the turret window" if settings.turret_window is not None else "")
        + ("" if ground is None else f" with the arm {ground:g} m above the ground"),
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
) -> tuple[NDArray[np.intp], NDArray[np.intp] | None, list[FloatArray]]:
    """The best sequence whose moves all clear the ground: the choice (K,), its nodes, moves.

    A move with no path clear of the ground at the poses it joins is forbidden and the
    choice made again (``value`` and ``allowed`` updated in place); nodes None: no plan.
    """
    K = len(value)
    while True:
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
