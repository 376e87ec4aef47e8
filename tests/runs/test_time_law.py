"""A route's turns slowed where they would slide (mmstab.runs.time_law, docs/routes.md).

An analytic case (a pivot on a plane ramp: the cap is the budget over the model's slide
per radian, found here on a heading grid of its own), level ground (nothing slowed), the
profile unchanged without caps, and the slowed law the one MuJoCo's reference follows.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
import pytest
from test_pivot import small_problem

from mmstab.control.reference import circle_pose
from mmstab.core.problem import problem_from_dict
from mmstab.paths import route_from_waypoints, speed_profile
from mmstab.paths.route import RoutePath, speed_limits
from mmstab.paths.speed import TurnLimit
from mmstab.runs.along import path_timing
from mmstab.runs.time_law import MIN_YAW_RATE, slowed_route, turn_limits
from mmstab.runs.verdict import robot_turn_check, turn_slip
from mmstab.runs.verdict_settings import VerdictSettings
from mmstab.stability.skid import track_patch, turn_slide
from mmstab.terrain import Ramp

#: A pivot of 90 deg left at (1, 0): heading +x (across the ramp, which rises along +y) to +y.
CORNER = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]
SETTINGS = VerdictSettings(slide_budget=0.8)  # slip_distance 5 cm within 1 s, 0.8 of it


def ramp_route(robot, waypoints, turn_radius: float = 0.0, speed: float = 0.25) -> RoutePath:
    limits = speed_limits(robot, {"speed": speed})
    route = route_from_waypoints(waypoints, turn_radius, robot.base.tracks.separation / 2)
    return RoutePath(route, speed_profile(route, limits), limits)


def stowed(robot, route: RoutePath):
    """The planned poses' arc lengths (2,) and the stowed arm's CoM at each (2, 3)."""
    return np.array([0.0, route.length]), np.tile(robot.arm_com(robot.stowed), (2, 1))


def verdict(robot, terrain, route: RoutePath) -> dict:
    """The plan's turn verdict on the route's own time law (what route_verdicts runs)."""
    poses, _, times = path_timing(route, 0.05)
    com = robot.arm_com(robot.stowed)
    return turn_slip(terrain, poses, robot_turn_check(robot, SETTINGS, com, times))


def test_a_pivot_on_a_ramp_turns_at_the_budget_over_the_slide_per_radian(robot):
    ramp = Ramp(np.radians(15.0))
    route = ramp_route(robot, CORNER)
    s_plan, com = stowed(robot, route)
    caps, records = turn_limits(robot, ramp, route, s_plan, com, SETTINGS)
    # the model's slide per radian on a heading grid of its own, pivot belts at 1 rad/s
    heading = np.linspace(0.0, np.pi / 2, 361)
    poses = np.c_[np.ones_like(heading), np.zeros_like(heading), heading]
    per_radian = turn_slide(track_patch(robot), ramp.gravity_body(poses),
                            robot.overall_com(com[0]), np.zeros_like(heading),
                            np.ones_like(heading), ramp.friction, 1.0,
                            SETTINGS.shear_modulus).per_radian  # fmt: skip
    p = float(np.max(per_radian))
    # the uniform-track closed form (L/2) tan(alpha) / mu bounds it from below: the robot's
    # CoM stands above the belts, the floor on the model's yaw rate prices more
    t = robot.base.tracks
    assert p > t.length / 2 * np.tan(ramp.slope) / ramp.friction * 0.9
    budget = 0.8 * 0.05
    assert [r["waypoint"] for r in records] == [1] and records[0]["kind"] == "pivot"
    assert records[0]["slide_per_rad_m"] == pytest.approx(p, rel=0.01)
    (cap,) = caps
    assert cap.yaw_rate == pytest.approx(max(budget / (p * 1.0), MIN_YAW_RATE), rel=0.01)
    assert cap.yaw_rate < route.yaw_rate_max(cap.start_s, cap.end_s)
    slowed, law = slowed_route(robot, ramp, route, s_plan, com, SETTINGS)
    # the pivot reaches its cap (a 90 deg pivot is long enough) and no more
    assert slowed.yaw_rate_max(cap.start_s, cap.end_s) == pytest.approx(cap.yaw_rate, rel=1e-9)
    assert law["corners"][0]["yaw_rate_after"] == pytest.approx(cap.yaw_rate, rel=1e-9)
    assert law["duration_s"] > law["duration_before_s"] + np.pi / 2 / cap.yaw_rate * 0.5
    # the same verdict: the turn slid on the speeds' law, it holds on the slowed one
    before, after = verdict(robot, ramp, route), verdict(robot, ramp, slowed)
    assert before["sliding_turns"] and before["sliding_turns"][0]["slide_in_window_m"] > 0.05
    assert after["sliding_turns"] == []
    # the lines keep their speed: the slowed law differs only in and next to the pivot
    p0, p1 = route.profile, slowed.profile
    np.testing.assert_array_equal(p0.s, p1.s)
    away = (p0.s < cap.start_s - 0.2) | (p0.s > cap.end_s + 0.2)
    np.testing.assert_array_equal(p0.v[away], p1.v[away])


def test_on_level_ground_nothing_is_slowed(robot):
    flat = Ramp(0.0)
    route = ramp_route(robot, CORNER)
    s_plan, com = stowed(robot, route)
    assert turn_limits(robot, flat, route, s_plan, com, SETTINGS) == ((), [])
    slowed, law = slowed_route(robot, flat, route, s_plan, com, SETTINGS)
    assert slowed is route and law["corners"] == []


def test_no_budget_and_a_turn_that_does_not_slide_keep_today_s_timing(robot):
    ramp = Ramp(np.radians(15.0))
    route = ramp_route(robot, CORNER)
    s_plan, com = stowed(robot, route)
    off = VerdictSettings(slide_budget=None)
    assert VerdictSettings().slide_budget is None  # the default: nothing slowed
    assert slowed_route(robot, ramp, route, s_plan, com, off)[0] is route
    # a 3 deg pivot slides less than the budget in all: kept
    small = ramp_route(robot, [[0.0, 0.0], [1.0, 0.0], [2.0, 0.05]])
    assert turn_limits(robot, ramp, small, *stowed(robot, small), SETTINGS)[0] == ()
    # no caps, or a cap on a line: the profile bit for bit
    rebuilt = route.with_turn_limits(())
    on_line = route.with_turn_limits((TurnLimit(0.1, 0.5, 0.01),))
    for other in (rebuilt, on_line):
        for a, b in zip(route.profile, other.profile, strict=True):
            np.testing.assert_array_equal(a, b)


def test_an_arc_is_capped_at_yaw_rate_times_its_radius(robot):
    route = ramp_route(robot, [[0.0, 0.0], [2.0, 0.0], [2.0, 2.0]], turn_radius=0.8)
    (corner, s0, s1), = route.route.turn_spans  # fmt: skip
    assert not corner.pivot and s1 - s0 == pytest.approx(0.8 * np.pi / 2)
    capped = route.with_turn_limits((TurnLimit(s0, s1, 0.1),))
    inside = (capped.profile.s > s0 + 0.01) & (capped.profile.s < s1 - 0.01)
    assert route.profile.v[inside].min() > 0.1 * 0.8 + 0.05  # faster before
    np.testing.assert_allclose(capped.profile.v[inside], 0.1 * 0.8, rtol=1e-12)
    assert capped.yaw_rate_max(s0, s1) == pytest.approx(0.1, rel=1e-12)
    with pytest.raises(ValueError, match="yaw rate must be > 0"):
        route.with_turn_limits((TurnLimit(s0, s1, 0.0),))


def test_the_simulated_reference_turns_on_the_plan_s_law(robot, tmp_path):
    """``Problem.following`` puts the plan's slowed route under MuJoCo's reference.

    The closed loop's reference is ``circle_pose(problem.base_path, t / lap_time)`` with the
    controller's lap time of that path (:func:`mmstab.outputs.simulate.controller_settings`):
    at the plan's time for the pivot's end it stands at the pivot's end.
    """
    from mmstab.outputs.simulate import controller_settings

    data = small_problem()
    data["terrain"]["generate"].update(slope=np.radians(12.0))
    problem = problem_from_dict(data, tmp_path / "p.yaml")
    route = problem.route
    s_plan, com = stowed(robot, route)
    slowed, law = slowed_route(robot, problem.terrain, route, s_plan, com, SETTINGS)
    (corner,) = law["corners"]
    assert corner["slowed"] and slowed is not route
    plan = namedtuple("Plan", "route")(slowed)
    assert problem.following(namedtuple("Plan", "route")(None)) is problem
    following = problem.following(plan)
    assert following.base_path is slowed and following.route is slowed
    assert problem.following(namedtuple("PathPlan", "path")(slowed)).base_path is slowed
    cs = controller_settings(following)
    assert cs.lap_time == slowed.lap_time and cs.duration == slowed.duration
    t_end = corner["end_t_s"]  # the plan's time at the pivot's end
    yaw_end = route.route.sample(corner["end_s"] - 1e-9).pose[0, 2]
    ref = circle_pose(following.base_path, np.array([t_end]) / cs.lap_time).value[0]
    assert ref[2] == pytest.approx(yaw_end, abs=1e-6)
    # the speeds' law would have been well past it, on the next leg
    old = circle_pose(route, np.array([t_end]) / route.lap_time).value[0]
    assert np.hypot(*(old[:2] - ref[:2])) > 0.1
