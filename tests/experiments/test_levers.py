"""Stability levers: the payload section, the tool wrench and the flippers in the planner, the
dynamic measure along a lap, and ``python -m experiments levers`` end to end (small settings)."""

from __future__ import annotations

import dataclasses
import json
import math
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest
from conftest import PROBLEMS, write_problem

from experiments import levers as L
from mmstab.core.files import MmstabError
from mmstab.core.problem import load_problem
from mmstab.model.payload import Payload, attach_payload
from mmstab.paths.circle import CirclePath
from mmstab.planner import PlannerSettings, plan_path, pose_fitness, solve_pose
from mmstab.planner.levers import (
    flipper_candidates,
    flipper_ground_angle,
    solve_path_flippers,
    solve_pose_flippers,
    with_flipper_angle,
)
from mmstab.planner.wrench import tool_map as tool_map_of
from mmstab.planner.wrench import tool_points, with_tool_wrench
from mmstab.stability.dynamic import dynamic_force_angle, net_wrench, robot_mu
from mmstab.stability.static import base_polygon, mu_max, robot_force_angle
from mmstab.terrain import Ramp

SMALL_GRID = [10, 8, 8, 8]


def _small(p, r):
    p["workspace"]["grid"] = SMALL_GRID


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    from mmstab.workspace import load_or_build_workspace

    tmp = tmp_path_factory.mktemp("levers")
    problem = load_problem(write_problem(tmp, _small))
    ws = load_or_build_workspace(problem, progress=False, cache_dir=tmp / "cache")
    return problem, ws


def _exhaustive(problem, **changes):
    s = PlannerSettings.from_section(problem.section("planner"))
    return s._replace(method="exhaustive", **changes)


# ------------------------------------------------------------------------ payload section
def test_payload_section_loads_into_the_robot(tmp_path, problem):
    def edit(p, r):
        p["payload"] = {"mass": 2.0, "com": [0.05, 0.0, 0.0], "wrench": [0, 0, -50, 0, 0, 0]}

    loaded = load_problem(write_problem(tmp_path, edit))
    assert loaded.robot.arm_mass == pytest.approx(problem.robot.arm_mass + 2.0)
    assert loaded.robot.source_hash != problem.robot.source_hash  # another V
    np.testing.assert_array_equal(loaded.robot.tool_wrench, [0, 0, -50, 0, 0, 0])
    assert problem.robot.tool_wrench is None  # no section: the file's robot
    # the wrench alone changes no cached V (it loads the measure, not the arm)
    only_wrench = load_problem(
        write_problem(
            tmp_path,
            lambda p, r: p.update(payload={"mass": 0.0, "com": [0, 0, 0], "wrench": [1] * 6}),
            "w.yaml",
        )
    )
    assert only_wrench.robot.source_hash == problem.robot.source_hash


@pytest.mark.parametrize(
    ("payload", "field"),
    [
        ({"mass": -1.0, "com": [0, 0, 0]}, "payload.mass"),
        ({"mass": float("nan"), "com": [0, 0, 0]}, "payload.mass"),
        ({"mass": 1.0, "com": [0, 0, 0], "wrench": [0, 0, 0, 0, 0]}, "payload.wrench"),
        ({"mass": 1.0, "com": [0, 0, 0], "wrench": [0, 0, 0, 0, 0, 0, 0]}, "payload.wrench"),
        ({"mass": 1.0, "com": [0, 0]}, "payload.com"),
    ],
)
def test_bad_payload_is_one_line_and_exit_2(tmp_path, payload, field):
    path = write_problem(tmp_path, lambda p, r: p.update(payload=payload))
    proc = subprocess.run(
        [sys.executable, "-m", "mmstab", "plan", str(path)],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=120,
    )
    assert proc.returncode == 2, proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and f"{field}:" in lines[0] and str(path.name) in lines[0], lines
    assert "Traceback" not in proc.stderr


# -------------------------------------------------------------------------- tool wrench
def test_zero_wrench_is_the_static_fitness(small):
    problem, ws = small
    robot = problem.robot
    g = Ramp(0.3).gravity_body(np.array([0.0, 0.0, 0.4]))[0]
    f = pose_fitness(robot, g, robot.arm_com(robot.stowed), _exhaustive(problem), 500.0, 0.9)
    loaded = attach_payload(robot, Payload(0.0, np.zeros(3), np.zeros(6)))
    fw = with_tool_wrench(f._replace(robot=loaded), ws)
    assert fw is not f and with_tool_wrench(f, ws) is f
    x = ws.valid_com_in_V
    np.testing.assert_allclose(fw.mu(x), f.mu(x), atol=1e-9)
    np.testing.assert_allclose(fw.linear()(x), f.linear()(x), atol=1e-12)


def test_weight_at_the_tool_tips_where_a_payload_at_the_wrist_tips(small):
    """A force m_p g at the tool and a point mass m_p at the wrist: two code paths.

    The two measures differ in angle (the wrench keeps the robot's CoM and adds a couple,
    the payload moves the CoM) but not in the tipping moment about any axis, so the mass
    at which mu crosses zero is the same.
    """
    problem, ws = small
    robot = problem.robot
    g = Ramp(0.25).gravity_body(np.array([0.0, 0.0, 0.0]))[0]  # left side uphill
    q = ws.valid_q[ws.valid_q[:, 0] == ws.valid_q[ws.valid_q[:, 0] > 4.0, 0].min()]
    q = q[np.argsort(tool_points(robot, q)[:, 1])[:5]]  # reaching furthest to the right
    settings = _exhaustive(problem)

    def mu_wrench(mass: float, k: int) -> float:
        pulled = attach_payload(robot, Payload(0.0, np.zeros(3), np.r_[mass * g, 0, 0, 0]))
        f = pose_fitness(pulled, g, robot.arm_com(robot.stowed), settings, 500.0, 0.9)
        return float(with_tool_wrench(f, ws).mu(robot.arm_com(q[k]))[0])

    def mu_mass(mass: float, k: int) -> float:
        carried = attach_payload(robot, Payload(mass, np.zeros(3)))
        return robot_force_angle(carried, g, carried.arm_com(q[k])).mu  # one pose: a float

    for k in range(len(q)):
        assert mu_wrench(0.0, k) == pytest.approx(mu_mass(0.0, k), rel=1e-12)
        assert mu_wrench(0.0, k) > 0 and mu_wrench(500.0, k) < 0 and mu_mass(500.0, k) < 0
        edges = [
            L.bisect_largest(lambda m, fn=fn, k=k: fn(m, k) > 0, 0.0, 500.0, 50)
            for fn in (mu_wrench, mu_mass)
        ]
        assert edges[0] == pytest.approx(edges[1], rel=1e-9)
    # the tool map is exact on V's samples
    np.testing.assert_allclose(
        tool_map_of(robot, ws)(robot.arm_com(q)), tool_points(robot, q), atol=1e-12
    )


def test_planner_with_a_wrench_plans_for_it(small):
    """Pulling a handle hard to the right: the exhaustive plan moves and beats the old one."""
    problem, ws = small
    robot = problem.robot
    pose = np.array([0.0, 0.0, 0.0])  # across the ramp, left side uphill
    settings = _exhaustive(problem)
    rng = np.random.default_rng(0)
    plain = solve_pose(robot, problem.terrain, ws, pose, robot.arm_com(robot.stowed), settings, rng)
    pulled = attach_payload(robot, Payload(0.0, np.zeros(3), np.array([0, -150.0, 0, 0, 0, 0])))
    loaded = solve_pose(
        pulled, problem.terrain, ws, pose, robot.arm_com(robot.stowed), settings, rng
    )
    g = problem.terrain.gravity_body(pose)[0]
    f = with_tool_wrench(
        pose_fitness(pulled, g, robot.arm_com(robot.stowed), settings, mu_max(robot), ws.diameter),
        ws,
    )
    assert loaded.mu == pytest.approx(float(f.mu(loaded.target_com)[0]))
    assert loaded.mu < plain.mu  # the pull costs stability ...
    assert loaded.fitness >= float(f(plain.target_com)[0])  # ... and the plan accounts for it
    assert np.linalg.norm(loaded.target_com - plain.target_com) > 1e-3


# ----------------------------------------------------------------------------- flippers
def test_flipper_candidates_and_ground_angle(robot):
    lim = robot.base.flippers.limits
    assert lim is not None and lim.lower < robot.base.flippers.angle < lim.upper
    a0 = flipper_ground_angle(robot)
    low = with_flipper_angle(robot, a0).base.flippers.box("left").corners()[:, 2].min()
    assert abs(low) < 1e-9  # the tip just touches the track plane
    assert len(with_flipper_angle(robot, a0).base.support_points()) > 4  # flipper contacts
    c = flipper_candidates(robot, 5, 0.6)
    assert c.min() >= lim.lower and c.max() <= lim.upper and 0.6 in c and a0 in c
    c = flipper_candidates(robot, 5, 0.6, max_step=0.1)
    assert np.all(np.abs(c - 0.6) <= 0.1 + 1e-12)


def test_flippers_lowered_where_the_front_axis_is_critical(small):
    problem, ws = small
    robot, ramp = problem.robot, Ramp(0.35)
    pose = np.array([0.0, 0.0, -math.pi / 2])  # facing straight downhill: the front axis
    s = _exhaustive(problem, flipper_angles=5)
    prev = robot.arm_com(robot.stowed)
    rng = np.random.default_rng(1)
    arm_only = solve_pose(robot, ramp, ws, pose, prev, s, rng)
    both = solve_pose_flippers(robot, ramp, ws, pose, prev, 0.6, s, rng, mu_max(robot))
    assert both.flipper_angle == pytest.approx(flipper_ground_angle(robot))
    assert both.target.mu > arm_only.mu + 1.0
    # the answer is the arm planner's with the robot's flippers there
    lowered = with_flipper_angle(robot, both.flipper_angle)
    g = ramp.gravity_body(pose)
    mu = robot_force_angle(lowered, g, both.target.target_com).mu[0]
    assert both.target.mu == pytest.approx(mu, rel=1e-12)
    # the ramp refuses flippers that reach into it: those angles are skipped, not chosen
    assert np.isinf(both.fitness[both.tried < both.flipper_angle - 1e-9]).all()
    # rate-limited: from raised flippers, 0.1 rad per step cannot reach the ground
    slow = solve_pose_flippers(robot, ramp, ws, pose, prev, 0.6, s, rng, mu_max(robot), None, 0.1)
    assert abs(slow.flipper_angle - 0.6) <= 0.1 + 1e-12
    assert slow.target.mu == pytest.approx(arm_only.mu)  # off the ground: the same polygon


def test_flipper_path_and_refusals(small, tmp_path):
    problem, ws = small
    s = _exhaustive(problem, flipper_angles=3)
    poses = CirclePath((0.0, 0.0), 1.5, -math.pi / 2).poses(4)
    plan = solve_path_flippers(problem.robot, Ramp(0.3), ws, poses, s, dt=0.5)
    steps = np.abs(np.diff(np.r_[problem.robot.base.flippers.angle, plan.flipper_angles]))
    assert np.all(steps <= problem.robot.base.flippers.limits.rate * 0.5 + 1e-12)
    with pytest.raises(MmstabError, match="flipper_angles is 0"):
        solve_path_flippers(problem.robot, Ramp(0.3), ws, poses, _exhaustive(problem), 0.5)
    r = problem.robot
    flippers = dataclasses.replace(r.base.flippers, limits=None)
    no_limits = dataclasses.replace(r, base=dataclasses.replace(r.base, flippers=flippers))
    with pytest.raises(MmstabError, match="needs base.flippers.limits"):
        solve_path_flippers(no_limits, Ramp(0.3), ws, poses, s, 0.5)
    with_flippers = load_problem(
        write_problem(tmp_path, lambda p, r: p["planner"].update(flipper_angles=3))
    )
    with pytest.raises(MmstabError, match="controller does not move"):
        plan_path(with_flippers, workspace=ws)


# ----------------------------------------------------------------------- dynamic measure
def test_lap_measure_static_part_is_the_static_measure(small):
    problem, ws = small
    robot = problem.robot
    q = robot.stowed + np.array([0.7, 0.3, -0.2, 0.1])
    motion = L.lap_motion(
        robot, problem.terrain, problem.circle, lambda s: np.tile(q, (np.size(s), 1)), 90
    )
    m = L.lap_measure(robot, problem.terrain, motion, 30.0)
    g = problem.terrain.gravity_body(motion.poses)
    static = robot_force_angle(robot, g, np.broadcast_to(robot.arm_com(q), g.shape)).mu
    np.testing.assert_allclose(m.static, static, rtol=1e-12)
    slow = L.lap_measure(robot, problem.terrain, motion, 1e7)  # accelerations ~ 0
    np.testing.assert_allclose(slow.dynamic, static, rtol=1e-9)
    assert m.peak_joint_speed.max() == 0.0


def test_lap_measure_turning_rigidly_by_hand(robot):
    """The stowed robot on a flat circle: every body accelerates omega^2 rho to the centre."""
    circle, flat, n, lap = CirclePath((0.0, 0.0), 1.5, 0.0), Ramp(0.0), 720, 4.0
    motion = L.lap_motion(robot, flat, circle, lambda s: np.tile(robot.stowed, (np.size(s), 1)), n)
    m = L.lap_measure(robot, flat, motion, lap)
    omega = 2 * math.pi / lap
    expected = []
    polygon = base_polygon(robot).vertices
    for i in (0, 100, 400):
        p = motion.positions[i]
        acc = -(omega**2) * np.c_[p[:, :2], np.zeros(len(p))]  # to the centre, in the plane
        w = net_wrench(motion.masses, p, acc, [0.0, 0.0, -9.81])
        R, t = motion.M_T_B[i, :3, :3], motion.M_T_B[i, :3, 3]
        fa = dynamic_force_angle(polygon, R.T @ (w.com - t), R.T @ w.force, R.T @ w.moment)
        expected.append(fa.mu[0])
    # second differences of a circle: omega^2 (1 - (omega h)^2 / 12), h = lap / n
    np.testing.assert_allclose(m.dynamic[[0, 100, 400]], expected, rtol=1e-4)
    assert np.all(m.dynamic < m.static)  # turning throws the CoM outward, over the right axis
    assert m.peak_acceleration == pytest.approx(
        omega**2 * np.linalg.norm(motion.positions[0, :, :2], axis=1).max(), rel=1e-4
    )


def test_posture_spline_closes_the_lap():
    q = np.array([[0.1, 0.2, 0.3, 0.4], [3.0, 0.5, 0.1, 0.0], [6.2, 0.4, 0.2, 0.1]])
    f = L.posture_spline(q)
    np.testing.assert_allclose(f(np.arange(3) / 3)[:, 1:], q[:, 1:], atol=1e-12)
    turret = np.mod(f(np.arange(3) / 3)[:, 0], 2 * math.pi)
    np.testing.assert_allclose(turret, np.mod(q[:, 0], 2 * math.pi), atol=1e-12)
    lap = f(np.array([1.0]))[0] - f(np.array([0.0]))[0]  # one lap: whole turns only
    np.testing.assert_allclose(lap[1:], 0.0, atol=1e-12)
    assert lap[0] == pytest.approx(2 * math.pi * round(lap[0] / (2 * math.pi)), abs=1e-9)


def test_bisect_largest():
    assert L.bisect_largest(lambda x: x <= 2.5, 0.0, 10.0, 40) == pytest.approx(2.5)
    assert L.bisect_largest(lambda x: True, 0.0, 10.0, 5) == 10.0
    assert math.isnan(L.bisect_largest(lambda x: False, 0.0, 10.0, 5))


# ------------------------------------------------------------------ python -m experiments levers
@pytest.mark.slow
def test_levers_subprocess_small(tmp_path):
    def edit(p, r):
        p["workspace"]["grid"] = SMALL_GRID
        p["planner"]["poses"] = 4
        p["controller"]["lap_time"] = p["controller"]["duration"] = 6.0  # short runs
        p["levers"] = {
            "margin": 300.0,
            "speeds": [1.0, 4.0],
            "samples": 60,
            "side_slope": 0.35,
            "max_payload": 30.0,
            "payload_com": [0.0, 0.0, 0.0],
            "payload_reach": 0.2,
            "bisection_steps": 8,
            "max_slope": 1.2,
            "robots": ["robots/cameleon.yaml"],
            "variant_grid": [8, 8, 6, 6],
            "flipper_angles": 2,
            "rough_problem": "rough.yaml",
        }

    path = write_problem(tmp_path, edit)
    shutil.copy(PROBLEMS / "rough.yaml", tmp_path / "rough.yaml")
    out = tmp_path / "out"
    env = {**os.environ, "MPLBACKEND": "Agg"}
    proc = subprocess.run(
        [sys.executable, "-m", "experiments", "levers", str(path), "-o", str(out)],
        capture_output=True,
        text=True,
        cwd=PROBLEMS.parent,  # the repository's workspace and roadmap caches (rough.yaml's)
        env=env,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    s = json.loads((out / "summary.json").read_text())
    for name in ("dynamic.png", "payload.png", "variants.png", "flippers.png", "variants.md"):
        assert (out / name).stat().st_size > 0
    d = s["dynamic"]["planned"]
    assert d["by_speed"]["4x"]["mu_dynamic_min"] < d["by_speed"]["1x"]["mu_dynamic_min"]
    assert s["dynamic"]["stowed"]["fastest_safe_speed_factor"] > 1.0
    sim = s["dynamic"]["simulated_planned"]
    assert not sim["1x"]["tipped"] and sim["4x"]["peak_acceleration_m_s2"] > 0
    fixed = s["payload"]["front"]["fixed"]["heaviest_kg"]
    assert 0.0 < fixed < 30.0
    assert s["variants"]["robots"]["cameleon"]["steepest_side_slope_planned_deg"] > 0
    assert (
        s["flippers"]["ramp"]["mu_arm_flippers_mean"] >= s["flippers"]["ramp"]["mu_arm_only_mean"]
    )
    assert "levers: fastest safe lap" in proc.stdout
    v = s["variants"]["robots"]["cameleon"]
    assert v["rough_mu_stowed_min"] < v["lap_mu_stowed_min"]  # rough ground is harder
    assert "rough lap" in (out / "variants.md").read_text()
    # along the rough route: a closed-loop run, static vs dynamic, arm planned and stowed
    route = s["dynamic"]["rough_route"]
    assert not route["tipped"] and (out / "dynamic_route.png").stat().st_size > 0
    for arm in ("planned", "stowed"):
        assert 0 < route[arm]["peak_acceleration_m_s2"] < 20.0
        assert route[arm]["mu_dynamic_min"] != route[arm]["mu_static_min"]
    assert route["planned"]["mu_static_min"] > route["stowed"]["mu_static_min"]
    # flippers along the rough route: within their limits, never worse at a pose
    f = s["flippers"]["rough_route"]
    assert f["mu_arm_flippers_mean"] >= f["mu_arm_only_mean"]
    assert all(-0.8 - 1e-9 <= a <= 1.2 + 1e-9 for a in f["flipper_angles_rad"])
    # bad input: a levers section without its keys is one line, exit 2
    bad = write_problem(tmp_path, lambda p, r: p.update(levers={"margin": 1.0}), "bad.yaml")
    proc = subprocess.run(
        [sys.executable, "-m", "experiments", "levers", str(bad), "-o", str(tmp_path / "o2")],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env=env,
        timeout=120,
    )
    assert proc.returncode == 2 and "levers" in proc.stderr and "Traceback" not in proc.stderr


def test_verdict_measure_agrees_with_the_planner_on_V_samples(small):
    """robot_mu (plan and tracking verdicts) = the planner's WrenchFitness where exact."""
    problem, ws = small
    robot = problem.robot
    pulled = attach_payload(robot, Payload(1.5, np.zeros(3), np.array([20.0, -40, 10, 1, 2, 3])))
    g = Ramp(0.3).gravity_body(np.array([0.0, 0.0, 2.0]))[0]
    q = ws.valid_q[::53]
    f = pose_fitness(pulled, g, robot.arm_com(robot.stowed), _exhaustive(problem), 500.0, 0.9)
    planner_mu = with_tool_wrench(f, ws).mu(pulled.arm_com(q))
    np.testing.assert_allclose(robot_mu(pulled, g, q), planner_mu, rtol=1e-12)
    static = robot_force_angle(robot, g, robot.arm_com(q)).mu
    np.testing.assert_array_equal(robot_mu(robot, g, q), static)  # no wrench: the old path


@pytest.mark.parametrize(
    ("limits", "field"),
    [
        ({"lower": 1.0, "upper": -1.0, "rate": 0.5}, "base.flippers.limits"),
        ({"lower": -0.8, "upper": 0.5, "rate": 0.5}, "base.flippers.angle"),  # 0.6 outside
        ({"lower": -0.8, "upper": 1.2, "rate": 0.0}, "base.flippers.limits.rate"),
        ({"lower": -0.8, "upper": 1.2}, "base.flippers.limits.rate"),
    ],
)
def test_bad_flipper_limits(tmp_path, limits, field):
    from mmstab.core.files import ConfigError

    def edit(p, r):
        r["base"]["flippers"]["limits"] = limits

    with pytest.raises(ConfigError, match=f"{field}:"):
        load_problem(write_problem(tmp_path, edit))


def test_flipper_limits_are_not_hashed(tmp_path, problem):
    def edit(p, r):
        r["base"]["flippers"]["limits"] = {"lower": -0.5, "upper": 1.0, "rate": 2.0}

    other = load_problem(write_problem(tmp_path, edit))
    assert other.robot.base.flippers.limits.rate == 2.0
    assert other.robot.source_hash == problem.robot.source_hash  # the same cached V
    lowered = with_flipper_angle(problem.robot, -0.2)
    assert lowered.source_hash != problem.robot.source_hash  # but not a moved flipper
    assert with_flipper_angle(problem.robot, problem.robot.base.flippers.angle) is problem.robot


def test_controller_com_task_carries_the_payload(robot):
    """The CoM task's value and Jacobian are those of the loaded arm (placed in M)."""
    from mmstab.control.tasks import build_task_model

    loaded = attach_payload(robot, Payload(3.0, np.array([0.05, 0.0, 0.0])))
    state = np.array([0.3, -0.2, 0.4, 0.0, 0.0, 0.5, 0.6, -0.7, 0.3])  # pose, sprockets, arm
    plain, heavy = build_task_model(robot, 0.2), build_task_model(loaded, 0.2)
    c, s = math.cos(0.4), math.sin(0.4)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    for model, r in ((plain, robot), (heavy, loaded)):
        expected = np.r_[0.3, -0.2, 0.0] + R @ r.arm_com(state[5:])
        np.testing.assert_allclose(model.task(state)[3:], expected, atol=1e-12)
    assert np.linalg.norm(heavy.task(state)[3:] - plain.task(state)[3:]) > 0.01
    J_arm = heavy.jacobian(state)[3:, 2:]  # the CoM rows, arm columns
    np.testing.assert_allclose(J_arm, R @ loaded.kinematics.arm_com_jacobian(state[5:]), atol=1e-12)


def test_the_route_measure_starts_after_the_approach_as_it_ran():
    """rough.yaml's approach ran 1.75 s (its time law), not the 1.0 s ``approach_time``.

    The dynamic μ along the route starts after it (its minimum had sat in the approach, 1.2 s).
    """
    from types import SimpleNamespace

    from experiments.levers.dynamic import after_approach

    t = np.arange(0, 3.0, 0.004)
    run = SimpleNamespace(t=t, dt=0.004, approach=SimpleNamespace(duration=1.754))
    after = after_approach(run)
    assert t[after][0] == pytest.approx(1.752) and after[t > 1.75].all()  # within dt / 2
    assert not after[t < 1.75].any()
