"""The turret window: link0 stays near its previous angle between planned poses."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import write_problem
from test_planner_reference import _settings, coarse  # noqa: F401  (module fixture)

from mmstab.core.files import ConfigError
from mmstab.core.problem import load_problem
from mmstab.planner import gravity_body_at, pose_fitness, solve_exhaustive, solve_path
from mmstab.planner.turret import (
    Window,
    sample_postures,
    sample_turret,
    turret_window,
    windowed_region,
)
from mmstab.stability.static import mu_max

COARSE = [10, 8, 8, 8]
WINDOW = 0.8  # [rad]


def _realise(ws):
    def grid(target, previous_q):  # the nearest grid posture: its link0 is the sample's
        return ws.nearest_valid_posture(target), True

    return grid


def test_sample_postures_realise_the_samples(coarse):  # noqa: F811
    problem, ws = coarse
    q = sample_postures(ws)
    assert q.shape == (len(ws.valid_com_in_V), 4)
    np.testing.assert_allclose(problem.robot.arm_com(q), ws.valid_com_in_V, atol=1e-12)
    np.testing.assert_array_equal(sample_turret(ws), q[:, 0])


def test_window_by_hand():
    w = turret_window(1.0, 0.5)
    assert w == Window(0.5, 1.5)
    np.testing.assert_array_equal(w.contains([0.49, 0.5, 1.5, 1.51]), [False, True, True, False])
    np.testing.assert_allclose(w.excess([0.0, 1.0, 2.0]), [0.5, 0.0, 0.5])
    # closing a loop: also within 0.5 of the first pose's link0, where both overlap
    assert turret_window(1.0, 0.5, first=1.3) == Window(0.8, 1.5)
    assert turret_window(1.0, 0.5, first=3.0) == Window(0.5, 1.5)  # no overlap: previous


def test_windowed_exhaustive_is_the_best_allowed_sample(coarse):  # noqa: F811
    problem, ws = coarse
    robot = problem.robot
    s = _settings(problem, ws)
    pose = problem.circle.poses(s.poses)[3]
    fitness = pose_fitness(
        robot,
        gravity_body_at(problem.terrain, pose)[0],
        robot.arm_com(robot.stowed),
        s,
        mu_max(robot),
        ws.diameter,
    )
    region = windowed_region(ws, Window(0.0, 1.0))
    ex = solve_exhaustive(fitness, region.valid_com_in_V)
    values = fitness(ws.valid_com_in_V)  # per sample, then masked by hand
    allowed = (sample_turret(ws) >= 0.0) & (sample_turret(ws) <= 1.0)
    assert ex.best_fitness == pytest.approx(values[allowed].max(), abs=1e-12)
    assert region.contains(ex.best_com[None])[0]
    assert region.violation(ex.best_com[None])[0] == 0.0
    outside = ws.valid_com_in_V[~allowed][:50]
    assert not region.contains(outside).any()
    assert (region.violation(outside) > 0).all()


@pytest.mark.parametrize("method", ["exhaustive", "cmaes"])
def test_turret_moves_at_most_the_window_and_the_lap_closes(coarse, method):  # noqa: F811
    problem, ws = coarse
    robot = problem.robot
    s = _settings(problem, ws, turret_window=WINDOW, method=method)
    poses = problem.circle.poses(s.poses)
    plan = solve_path(robot, problem.terrain, ws, poses, s, _realise(ws), closed=True)
    link0 = plan.postures[:, 0]
    assert np.all(np.abs(np.diff(link0)) <= WINDOW + 1e-9), link0
    assert abs(link0[-1] - link0[0]) <= WINDOW + 1e-9, link0  # the lap closes
    free = solve_path(
        robot, problem.terrain, ws, poses, s._replace(turret_window=None), _realise(ws)
    )
    assert np.abs(np.diff(free.postures[:, 0])).max() > WINDOW  # the window binds here
    assert plan.targets[0].window is None  # the first pose is free (the approach moves it)
    assert all(t.window is not None for t in plan.targets[1:])


def test_the_papers_starts_move_into_each_poses_window(coarse):  # noqa: F811
    """``seeding: starts`` under a window: each pose's starts lie in its window (link0 of
    the starts 2.0 and 5.0 rad lay outside most windows, no CMA-ES sample fell in V)."""
    problem, ws = coarse
    robot = problem.robot
    s = _settings(problem, ws, turret_window=WINDOW, seeding="starts", starts=(2.0, 5.0))
    s = s._replace(sigma0=0.05, sigma0_unit="m", popsize=16, max_iterations=20)
    poses = problem.circle.poses(s.poses)
    plan = solve_path(robot, problem.terrain, ws, poses, s, _realise(ws), closed=True)
    link0 = plan.postures[:, 0]
    assert np.all(np.abs(np.diff(link0)) <= WINDOW + 1e-9), link0
    for t in plan.targets[1:]:
        assert t.window is not None
        starts = np.array([r.start_com for r in t.runs])
        assert windowed_region(ws, t.window).contains(starts).all()


def test_cma_within_half_a_percent_of_the_windowed_exhaustive(coarse):  # noqa: F811
    problem, ws = coarse
    robot = problem.robot
    s = _settings(problem, ws, turret_window=WINDOW)
    poses = problem.circle.poses(s.poses)
    plan = solve_path(robot, problem.terrain, ws, poses, s, _realise(ws), closed=True)
    previous = robot.arm_com(robot.stowed)
    for t in plan.targets:
        fitness = pose_fitness(
            robot,
            gravity_body_at(problem.terrain, t.pose)[0],
            previous,
            s,
            mu_max(robot),
            ws.diameter,
        )
        samples = ws.valid_com_in_V
        if t.window is not None:
            samples = windowed_region(ws, t.window).valid_com_in_V
        best = solve_exhaustive(fitness, samples).best_fitness
        assert t.fitness >= best - 0.005 * abs(best), (t.pose, t.fitness, best)
        previous = t.target_com


def test_bad_turret_window_is_refused(tmp_path):
    path = write_problem(tmp_path, lambda p, r: p["planner"].__setitem__("turret_window", -1.0))
    with pytest.raises(ConfigError, match="turret_window"):
        load_problem(path)
