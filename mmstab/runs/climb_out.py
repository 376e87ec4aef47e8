"""A route's climbs with the rear down, checked with the CoMs of the arm's planned moves.

:mod:`mmstab.stability.climb_out` follows the pivoted attitude along the path's samples;
here the CoM at each sample is every CoM the arm passes through on its planned move there:
the base drives from planned pose k − 1 to pose k while the arm makes its move k (the
roadmap's joint path, ``RoutePlan.moves``; a straight joint move between the postures
without one), and the arm's time law may shift the move within that stretch. A move that
swings the arm over the rear puts the CoM behind both postures it joins (route 4 of
``make validate-routes``: 7.4 cm behind), which the end postures alone do not see.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from mmstab.core.masks import true_runs
from mmstab.stability.climb_out import climb_out, pivot_rest

if TYPE_CHECKING:
    from mmstab.model.robot import FloatArray, Robot
    from mmstab.planner import RoutePlan
    from mmstab.terrain.base import Terrain

#: Each straight piece of a move is checked at this many points (the turret's swing bends
#: the CoM's path between knots).
PIECES = 4
#: Climbs whose pitch stays below this are the belly on a bump, not listed [rad].
LISTED_PITCH = float(np.radians(5.0))


def move_postures(plan: RoutePlan, k: int) -> FloatArray:
    """The postures (M, n) [rad] the arm passes through on its move into planned pose ``k``."""
    q = np.asarray(plan.postures, dtype=float)
    moves = getattr(plan, "moves", ())
    if k == 0:
        return q[:1]
    knots = (
        np.asarray(moves[k], dtype=float)
        if len(moves) == len(q) and len(moves[k]) > 0
        else q[k - 1 : k + 1]
    )
    if len(knots) < 2:
        return knots
    f = np.arange(PIECES) / PIECES
    inner = knots[:-1, None, :] + f[None, :, None] * np.diff(knots, axis=0)[:, None, :]
    return np.vstack([inner.reshape(-1, knots.shape[1]), knots[-1:]])


def move_coms(robot: Robot, plan: RoutePlan, s: Any) -> FloatArray:
    """The overall CoMs in B (N, M, 3) [m] the arm may pass through at arc lengths s (N,) [m].

    A sample in (s_{k−1}, s_k] gets the CoMs of move k (NaN-padded to M); one at or before
    the first pose, the first posture's; one past the last, the last's. A posture the plan
    did not realise (NaN) counts as its target CoM.
    """
    from mmstab.planner.along_route import planned_com

    s_m = np.asarray(s, dtype=float)
    q = np.asarray(plan.postures, dtype=float)
    ends = robot.overall_com(planned_com(robot, q, plan.target_com))
    per_move = []
    for k in range(len(q)):
        moves = move_postures(plan, k)
        known = np.isfinite(moves).all(axis=1)
        coms = robot.overall_com(np.atleast_2d(robot.arm_com(np.nan_to_num(moves))))[known]
        per_move.append(np.vstack([coms, ends[max(k - 1, 0) : k + 1]]))
    width = max(len(c) for c in per_move)
    table = np.full((len(q), width, 3), np.nan)
    for k, c in enumerate(per_move):
        table[k, : len(c)] = c
    k = np.clip(np.searchsorted(np.asarray(plan.s, dtype=float), s_m, side="left"), 0, len(q) - 1)
    return table[k]


def climb_out_verdict(
    robot: Robot, terrain: Terrain, poses: Any, s: Any, plan: RoutePlan
) -> dict[str, Any]:
    """Where a route's climbs overturn the robot (:mod:`mmstab.stability.climb_out`).

    Args:
        robot: the robot.
        terrain: the ground.
        poses: the path's samples (x [m], y [m], heading [rad]) (N, 3) in M, in driving order.
        s: their arc lengths (N,) [m].
        plan: the route's plan (postures, moves, arc lengths of the planned poses).

    Returns:
        ``overturns`` (any sample does), ``climbs`` (stretches climbing with the rear down
        past :data:`LISTED_PITCH`: arc lengths [m] and the largest pitch [rad]) and
        ``stretches`` (where it overturns: arc lengths [m], the pitch there [rad], and
        ``com_ahead_of_rear_m``: how far the most backward CoM of the arm's move is ahead of
        the rear contact, < 0 behind it).
    """
    s_m = np.asarray(s, dtype=float)
    rest = pivot_rest(robot, terrain, poses)
    co = climb_out(robot, rest, move_coms(robot, plan, s_m))
    climbs = [
        {"start_s": float(s_m[a]), "end_s": float(s_m[b - 1]),
         "pitch_max_rad": float(np.max(co.pitch[a:b]))}
        for a, b in true_runs(co.climbing)
        if np.max(co.pitch[a:b]) > LISTED_PITCH
    ]  # fmt: skip
    stretches = [
        {"start_s": float(s_m[a]), "end_s": float(s_m[b - 1]),
         "pitch_rad": float(co.pitch[a]), "com_ahead_of_rear_m": float(co.ahead_of_rear[a])}
        for a, b in true_runs(co.overturns)
    ]  # fmt: skip
    return {
        "overturns": bool(co.overturns.any()),
        "criterion": "climbing a step with the rear down, the CoM passes the edge before it "
        "falls behind the rear contact or the rear wheel meets the face (quasi-static, the "
        "arm anywhere on its planned move)",
        "climbs": climbs,
        "stretches": stretches,
    }
