"""The planner's search interface, its registry and the path protocol."""

from __future__ import annotations

import numpy as np
import pytest
from test_planner_reference import _settings, coarse  # noqa: F401  (module fixture)

from mmstab.core.files import MmstabError
from mmstab.core.schema import PLANNER_METHODS
from mmstab.paths.base import BasePath
from mmstab.paths.circle import CirclePath
from mmstab.planner import (
    SEARCHES,
    PathChoice,
    PathSearch,
    PathTask,
    PoseChoice,
    PoseSearch,
    PoseTask,
    gravity_body_at,
    planning_region,
    pose_fitness,
    solve_path,
    solve_route,
)
from mmstab.stability.static import mu_max

STRIDE = 7  # the trivial search scores every 7th sample


class EveryKth:
    """A trivial per-pose search: the best of every ``STRIDE``-th candidate sample."""

    def choose(self, task: PoseTask) -> PoseChoice:
        pts = task.region.samples[::STRIDE]
        values = task.fitness(pts)
        k = int(np.argmax(values))
        return PoseChoice(pts[k].copy(), float(values[k]))


class SameSample:
    """A trivial whole-path search: one fixed sample (and its grid posture) at every pose."""

    row = 3

    def choose(self, task: PoseTask) -> PoseChoice:
        com = task.region.samples[self.row]
        return PoseChoice(com, float(task.fitness(com)[0]))

    def choose_path(self, task: PathTask) -> PathChoice:
        K = len(task.gravity_body)
        com = np.tile(task.region.index.samples[self.row], (K, 1))
        q = np.tile(task.region.postures[self.row], (K, 1))
        return PathChoice(com, q, np.zeros(K), np.zeros(K))


def test_the_registry_holds_the_schemas_methods():
    assert set(SEARCHES) == set(PLANNER_METHODS)
    assert all(isinstance(s, PoseSearch) for s in SEARCHES.values())
    assert isinstance(SEARCHES["sequence"], PathSearch)
    assert not isinstance(SEARCHES["cmaes"], PathSearch)


def test_a_registered_per_pose_search_plans_a_path(coarse, monkeypatch):  # noqa: F811
    problem, ws = coarse
    robot = problem.robot
    monkeypatch.setitem(SEARCHES, "every_kth", EveryKth())
    s = _settings(problem, ws, method="every_kth", poses=4)
    poses = problem.circle.poses(4)
    plan = solve_path(robot, problem.terrain, ws, poses, s, closed=True)
    # by hand: Eq. 6 at each pose from the previous target (the stowed arm first)
    samples = ws.valid_com_in_V[::STRIDE]
    previous = robot.arm_com(robot.stowed)
    g = gravity_body_at(problem.terrain, poses)
    for k, t in enumerate(plan.targets):
        f = pose_fitness(robot, g[k], previous, s, mu_max(robot), ws.diameter)
        values = f(samples)
        np.testing.assert_array_equal(t.target_com, samples[np.argmax(values)])
        assert t.fitness == values.max()
        assert t.mu == pytest.approx(f.mu(t.target_com)[0], abs=1e-12)
        previous = t.target_com
    assert np.isnan(plan.postures).all()  # no IK given


def test_a_registered_whole_path_search_plans_a_circle_and_a_route(coarse, monkeypatch):  # noqa: F811
    problem, ws = coarse
    robot = problem.robot
    monkeypatch.setitem(SEARCHES, "same", SameSample())
    s = _settings(problem, ws, method="same", poses=3)
    region = planning_region(ws, "hull_difference")
    plan = solve_path(robot, problem.terrain, region, problem.circle.poses(3), s, closed=True)
    q = ws.valid_q[ws.valid_in_V][SameSample.row]
    np.testing.assert_array_equal(plan.postures, np.tile(q, (3, 1)))
    np.testing.assert_allclose(plan.target_com, np.tile(robot.arm_com(q), (3, 1)), atol=1e-12)
    assert plan.collision_free.all() and plan.realised_com_error.max() < 1e-12
    poses = problem.circle.poses(5)[:3]
    route = solve_route(robot, problem.terrain, region, [0.0, 1.0, 2.0], poses, s)
    np.testing.assert_array_equal(route.postures, plan.postures)
    assert not route.warm.any()


def test_an_unknown_search_is_a_clear_error(coarse):  # noqa: F811
    problem, ws = coarse
    s = _settings(problem, ws, method="nowhere")
    with pytest.raises(MmstabError, match="no search 'nowhere'"):
        solve_path(problem.robot, problem.terrain, ws, problem.circle.poses(2), s)


def _paths(problem):
    from mmstab.paths.geometry import route_from_waypoints
    from mmstab.paths.route import RoutePath
    from mmstab.paths.speed import SpeedLimits, speed_profile

    route = route_from_waypoints(np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0]]), 0.5)
    limits = SpeedLimits(0.3, 0.3, 0.3, 1.0, 0.4)
    return problem.circle, RoutePath(route, speed_profile(route, limits))


def test_the_circle_and_a_route_are_both_base_paths(coarse):  # noqa: F811
    problem, _ = coarse
    circle, route = _paths(problem)
    for path, closed, length in [(circle, True, 2 * np.pi * circle.radius), (route, False, None)]:
        p: BasePath = path
        assert p.closed is closed
        if length is not None:
            assert p.length == pytest.approx(length)
        u, h = np.linspace(0.05, 0.6, 7), 1e-6
        sample = p.pose_rate(u)
        np.testing.assert_array_equal(sample.value, p.pose_at(u))
        central = (p.pose_at(u + h) - p.pose_at(u - h)) / (2 * h)  # d pose / du
        np.testing.assert_allclose(sample.rate, central, atol=1e-5 * max(1.0, p.length))
    assert isinstance(circle, CirclePath)
