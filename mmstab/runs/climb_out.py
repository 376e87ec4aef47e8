"""A path's climbs with the rear down, checked with the arm where its reference has it.

:mod:`mmstab.stability.climb_out` follows the pivoted attitude along the path's samples;
here the CoM at each sample is the one of the arm's posture reference at that arc length
(:func:`mmstab.control.posture.build_posture_reference`: the plan's postures joined by its
roadmap moves, timed by the path's time law (a route's profile, a lap's one speed), which
the arm's time law stretches with the base so that the two stay paired): what the closed
loop commands there. A move that swings the arm over the rear puts the CoM behind both
postures it joins (route 4 of ``make validate-routes``: 7.4 cm behind, while the robot
climbs a ditch's far wall), which the postures alone do not see.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from mmstab.core.masks import true_runs
from mmstab.stability.climb_out import climb_out, pivot_rest

if TYPE_CHECKING:
    from mmstab.model.robot import FloatArray, Robot
    from mmstab.paths.circle import CirclePath
    from mmstab.paths.route import RoutePath
    from mmstab.planner import RoutePlan
    from mmstab.runs.along import LapStage
    from mmstab.terrain.base import Terrain

#: Climbs whose pitch stays below this are the belly on a bump, not listed [rad].
LISTED_PITCH = float(np.radians(5.0))


def reference_arm_coms(
    robot: Robot, plan: RoutePlan | LapStage, route: RoutePath | CirclePath, s: Any
) -> FloatArray:
    """The arm CoM in B (N, 3) [m] of the arm's posture reference at arc lengths s (N,) [m].

    The reference is the plan's (its roadmap moves between the postures, no via postures);
    a posture the plan did not realise (NaN) holds its target CoM.
    """
    q = np.asarray(plan.postures, dtype=float)
    if not np.isfinite(q).all():
        from mmstab.planner.along_route import planned_com

        arm = np.asarray(planned_com(robot, q, plan.target_com))
        k = np.clip(np.searchsorted(plan.s, np.asarray(s, dtype=float)), 0, len(q) - 1)
        return arm[k]
    from mmstab.runs.arm_ground import reference_postures

    moving = reference_postures(robot, plan, route, s)
    return np.atleast_2d(np.asarray(robot.arm_com(moving), dtype=float))


def reference_coms(
    robot: Robot, plan: RoutePlan | LapStage, route: RoutePath | CirclePath, s: Any
) -> FloatArray:
    """The overall CoM in B (N, 3) [m] of the arm's posture reference at arc lengths s (N,) [m].

    :func:`reference_arm_coms` with the base's mass.
    """
    return np.asarray(robot.overall_com(reference_arm_coms(robot, plan, route, s)))


def climb_out_verdict(
    robot: Robot,
    terrain: Terrain,
    route: RoutePath | CirclePath,
    poses: Any,
    s: Any,
    plan: RoutePlan | LapStage,
) -> dict[str, Any]:
    """Where a path's climbs overturn the robot (:mod:`mmstab.stability.climb_out`).

    Args:
        robot: the robot.
        terrain: the ground.
        route: the route or lap (its time law places the arm's reference).
        poses: the path's samples (x [m], y [m], heading [rad]) (N, 3) in M, in driving order.
        s: their arc lengths (N,) [m].
        plan: its plan (``s``, postures, moves, fractions).

    Returns:
        ``overturns`` (any sample does), ``climbs`` (stretches climbing with the rear down
        past :data:`LISTED_PITCH`: arc lengths [m] and the largest pitch [rad]) and
        ``stretches`` (where it overturns: arc lengths [m], the pitch there [rad], and
        ``com_ahead_of_rear_m``: how far the CoM of the arm's reference is ahead of the rear
        contact, < 0 behind it; ``com_behind_edge_m``: how far behind the edge; the
        ``cause``: ``com behind the rear`` or ``rear at the face``, the rear wheel meeting
        the step with the CoM still between).
    """
    s_m = np.asarray(s, dtype=float)
    rest = pivot_rest(robot, terrain, poses)
    co = climb_out(robot, rest, reference_coms(robot, plan, route, s_m))
    climbs = [
        {"start_s": float(s_m[a]), "end_s": float(s_m[b - 1]),
         "pitch_max_rad": float(np.max(co.pitch[a:b]))}
        for a, b in true_runs(co.climbing)
        if np.max(co.pitch[a:b]) > LISTED_PITCH
    ]  # fmt: skip
    stretches = [
        {"start_s": float(s_m[a]), "end_s": float(s_m[b - 1]),
         "pitch_rad": float(co.pitch[a]), "com_ahead_of_rear_m": float(co.ahead_of_rear[a]),
         "com_behind_edge_m": float(co.behind_edge[a]),
         "cause": "com behind the rear" if co.ahead_of_rear[a] < 0 else "rear at the face"}
        for a, b in true_runs(co.overturns)
    ]  # fmt: skip
    return {
        "overturns": bool(co.overturns.any()),
        "criterion": "climbing a step with the rear down, the CoM passes the edge before it "
        "falls behind the rear contact or the rear wheel meets the face (quasi-static, the "
        "arm on its posture reference)",
        "climbs": climbs,
        "stretches": stretches,
    }
