"""The controller in the loop on the whole robot in MuJoCo (``mmstab simulate``)."""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, assert_committed_has_the_keys

import mmstab
from mmstab import app
from mmstab.control.plant import build_plant
from mmstab.control.reference import initial_state
from mmstab.outputs.simulate import controller_settings, loop_settings, stowed_plan
from mmstab.physics.closed_loop import run_closed_loop
from mmstab.physics.loop_checks import TipCheck, downhill_drift, support_lost
from mmstab.physics.robot_model import ModelSettings

pytestmark = pytest.mark.mujoco


@pytest.fixture(scope="module")
def ramp() -> tuple[mmstab.Problem, object]:
    problem = mmstab.load_problem(ROOT / "problems" / "ramp.yaml")
    return problem, app.plan(problem)


def _run(problem: mmstab.Problem, plan: object, duration: float, backend: str = "interpreted"):
    cs = controller_settings(problem)
    loop = dataclasses.replace(loop_settings(problem), duration=duration, backend=backend)
    if backend == "generated":
        cs = dataclasses.replace(cs, plugin=problem.section("codegen")["plugin"])
        step = app.generated_step(problem).function
    else:
        step = mmstab.control.controller.build_controller(problem.robot, cs).step
    state0 = initial_state(problem.base_path, problem.robot.stowed)
    return run_closed_loop(problem, plan, step, cs, loop, state0)


def test_the_ramp_lap_tracks_in_mujoco(ramp) -> None:
    problem, plan = ramp
    run = _run(problem, plan, 4.0)
    assert run.tipped is None and run.slid is None
    assert int(np.sum(run.status != 0)) == 0
    assert run.base_error.max() < 0.05  # the 10 cm; 3.1 cm
    assert run.base_error[-1] < 0.03 and run.arm_com_error[-1] < 0.03  # settling onto the lap
    # after the arm's start-up move the simulated contacts' μ is mmstab's: every check within
    # 1 % (0.03 % at most); the plan keeps the arm above the ramp and the servos' speed
    # feed-forward keeps the moving arm on its targets, so no link touches the ground
    late = (run.t > 2.5) & np.isfinite(run.mu_simulated)
    diff = (run.mu_simulated[late] - run.mu_predicted[late]) / run.mu_predicted[late]
    assert late.sum() > 20 and np.abs(diff).max() < 0.01
    assert np.nansum(run.arm_ground == 1) == 0
    assert np.nanmax(run.tilt_error) < 0.1 and run.real_time_factor > 0
    # the body origin against the path's pose at the same time (the lap's fraction t / T)
    cs = controller_settings(problem)
    ref = problem.base_path.pose_at(run.t / cs.lap_time)
    origin = np.linalg.norm(run.state[:, :2] - ref[:, :2], axis=1)
    assert run.base_origin_error == pytest.approx(origin, abs=1e-12)
    # the control point 0.2 m ahead turns with the heading: the two errors differ, by at
    # most the offset times the heading error (and the ramp's tilt of that offset)
    heading = np.abs(np.angle(np.exp(1j * (run.state[:, 2] - ref[:, 2]))))
    gap = np.abs(run.base_error - run.base_origin_error)
    assert gap.max() > 1e-3 and np.all(gap <= cs.base_offset * heading + 1e-3)
    assert run.base_origin_error.max() < 0.05


def test_the_generated_c_step_drives_the_same_run(ramp) -> None:
    problem, plan = ramp
    a, b = _run(problem, plan, 0.4), _run(problem, plan, 0.4, "generated")
    # the box QP's C code against its interpreted form: the same commands, the same physics
    assert np.abs(a.qdot - b.qdot).max() < 1e-6
    assert np.abs(a.state - b.state).max() < 1e-6


def test_downhill_drift_by_hand() -> None:
    robot = mmstab.load_robot(ROOT / "problems" / "robots" / "cameleon.yaml")
    plant, dt, n = build_plant(robot), 0.01, 200
    com = [0.05, -0.002]  # the CoM's x, y in B: the heading is constant here, it moves with B
    states = np.zeros((n + 1, 9))
    states[:, 2] = 0.3  # heading; the tracks commanded nothing
    gravity = np.tile([0.0, -1.0, -9.0], (n, 1))  # downhill = -y_B
    c, s = np.cos(0.3), np.sin(0.3)
    down = np.array([s, -c])  # -y_B in M
    states[:, :2] = np.arange(n + 1)[:, None] * 0.0005 * down  # 0.05 m/s downhill
    drift = downhill_drift(plant, gravity, states, np.zeros((n, 6)), dt, 100, com)
    assert drift[100] == pytest.approx(0.05) and drift[-1] == pytest.approx(0.05)
    uphill = downhill_drift(plant, gravity, states[::-1].copy(), np.zeros((n, 6)), dt, 100, com)
    assert uphill[-1] == pytest.approx(-0.05)
    # driving as commanded is no drift
    qd = np.tile([2.0, 2.0, 0, 0, 0, 0], (n, 1))
    driven = [np.zeros(9)]
    for k in range(n):
        driven.append(np.array(plant(driven[-1], qd[k], dt)).ravel())
    driven_drift = downhill_drift(plant, gravity, np.array(driven), qd, dt, 100, com)
    assert np.abs(driven_drift).max() < 1e-12
    # tracks commanded uphill at 0.05 m/s that slip and climb at half of it: no slide
    c_, s_ = np.cos(0.3 + np.pi / 2), np.sin(0.3 + np.pi / 2)  # +y_B = uphill, in M
    climb = states.copy()
    climb[:, :2] = np.arange(n + 1)[:, None] * 0.00025 * np.array([c_, s_])
    climb[:, 2] = 0.3 + np.pi / 2  # heading uphill: x_B = +y_B of the first case
    up = np.tile([-1.0, 0.0, -9.0], (n, 1))  # downhill = -x_B
    qd_up = np.tile([0.05 / robot.base.tracks.sprocket_radius] * 2 + [0.0] * 4, (n, 1))
    slipping = downhill_drift(plant, up, climb, qd_up, dt, 100, com)
    assert slipping[-1] == pytest.approx(-0.025)  # moved 2.5 cm uphill: A, not A - C
    # the same tracks sliding back at 0.05 m/s while commanded uphill: the 5 cm it slid
    back = climb.copy()
    back[:, :2] = -back[:, :2] * 2
    assert downhill_drift(plant, up, back, qd_up, dt, 100, com)[-1] == pytest.approx(0.05)


@pytest.mark.slow
def test_cli_simulate(tmp_path: Path) -> None:
    env = {**os.environ, "MPLBACKEND": "Agg"}
    r = subprocess.run(
        [sys.executable, "-m", "mmstab", "simulate", str(ROOT / "problems" / "ramp.yaml"),
         "-o", str(tmp_path), "--duration", "1"],
        capture_output=True, text=True, env=env, cwd=ROOT, timeout=600,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["duration_s"] == pytest.approx(1.0) and s["tipped"] is None and s["qp_failures"] == 0
    assert "x real time" in r.stdout and (tmp_path / "physics.png").is_file()
    assert s["arm"] == "planned" and s["model"] == {"wheel": "sphere", "timestep_s": 0.004}
    assert s["real_time_factor_cpu"] > 0
    assert "body origin" in r.stdout and 0 < s["base_origin_error_max_m"] < 0.05
    assert s["base_origin_error_max_where_no_slip_predicted_m"] == s["base_origin_error_max_m"]
    # a 5.7 deg ramp: mmstab's slip check flags no pose, so the bar covers the whole run
    assert s["slip_predicted_fraction"] == 0.0 and s["no_slip_predicted_fraction"] == 1.0
    assert s["base_error_max_where_no_slip_predicted_m"] == s["base_error_max_m"]
    # nor does its turns' slide (1.7 cm/s at most) or a chassis on the ground (a plane)
    assert s["path_slip_predicted_fraction"] == 0.0
    assert s["high_centred"]["high_centred"] is False and s["high_centred"]["samples"] > 100
    assert "high-centred" not in r.stderr
    assert_committed_has_the_keys(s, "results/physics/summary.json")  # `make physics`'s lap


def _ramp_arm_in_the_ground(tmp_path: Path) -> Path:
    """The ramp planned on the roadmap with no ground check: the arm dives into the ramp."""
    from conftest import write_problem

    def edit(prob, rob):
        prob["planner"].update(method="roadmap", ground_clearance=None)

    return write_problem(tmp_path, edit)


@pytest.mark.slow
def test_cli_simulate_arm_on_the_ground_is_exit_5(tmp_path: Path) -> None:
    """An arm link touching the ground in MuJoCo is a verdict: exit 5 unless allowed."""
    env, problem = {**os.environ, "MPLBACKEND": "Agg"}, _ramp_arm_in_the_ground(tmp_path)
    cmd = [sys.executable, "-m", "mmstab", "simulate", str(problem), "--duration", "0.8"]
    r = subprocess.run([*cmd, "-o", str(tmp_path / "a")], capture_output=True, text=True,
                       env=env, cwd=ROOT, timeout=600)  # fmt: skip
    assert r.returncode == 5, r.stderr
    assert r.stderr.count("\n") == 1 and "mmstab: arm collision: the arm touches" in r.stderr
    s = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert s["tipped"] is None and 0.3 < s["arm_ground_contact"]["first_time_s"] < 0.8
    # the body then on its predicted rest (the arm dives into the ramp, the body holds)
    assert 0.0 <= s["arm_ground_contact"]["tilt_off_rest_rad"] < 0.05
    allow = [*cmd, "-o", str(tmp_path / "b"), "--allow-collision"]
    allowed = subprocess.run(allow, capture_output=True, text=True, env=env, cwd=ROOT, timeout=600)
    assert allowed.returncode == 0 and "mmstab: warning: the arm touches" in allowed.stderr


def test_servo_feed_forward_removes_the_lag_of_a_moving_target() -> None:
    """The arm's servo with the speed fed forward tracks a ramp in the target, without it lags.

    A position servo damped against rest lags a target moving at q̇ by kv q̇ / kp (0.05 s
    of motion at the model's gains); the feed-forward ``kv q̇`` removes it.
    """
    from mmstab.physics.robot_sim import RobotSim

    robot = mmstab.load_robot(ROOT / "problems" / "robots" / "cameleon.yaml")
    lags = []
    for feed in (False, True):
        sim = RobotSim(robot, arm_q=robot.stowed)
        sim.step((0.0, 0.0), robot.stowed, 0.3)
        qdot, target, dt = np.array([0.5, 0.0, 0.0, 0.0]), robot.stowed.copy(), 0.004
        for _ in range(200):  # 0.8 s: the turret turns 0.4 rad
            target = target + qdot * dt
            sim.advance((0.0, 0.0), target, 1, qdot if feed else None)
        lags.append(float(target[0] - sim.data.qpos[sim.arm_qpos[0]]))
    s = ModelSettings()
    assert lags[0] == pytest.approx(s.arm_kv * 0.5 / s.arm_kp, rel=0.1)  # 25 mrad
    assert abs(lags[1]) < 0.1 * lags[0]


def test_tilt_off_rest_is_a_disagreement_and_overturning_a_tip() -> None:
    """Records evaluated 4 at a time: a tilt off the rest stops nothing, an overturn does.

    The chassis tilted 0.5 rad (29 deg) off its rest about x from the 6th record: recorded
    as the tilt (the disagreement), the run goes on. Rolled 1.4 rad with the CoM 0.3 m above
    the footprint's centre, the vertical through the CoM lands outside the footprint (the
    tracks' half width is 0.30 m or less, 0.3 tan(1.4) = 1.7 m): overturned, the run stops
    at that record, its pending tilts evaluated first.
    """
    problem = mmstab.load_problem(ROOT / "problems" / "kerb.yaml")  # a 6 m heightmap
    checks = TipCheck(problem, batch=4)
    poses = np.array([[-2.0 + 0.1 * k, 0.0, 0.0] for k in range(10)])
    rest = problem.terrain.G_T_B(poses)

    def rolled(T: np.ndarray, angle: float) -> np.ndarray:
        c, s_ = np.cos(angle), np.sin(angle)
        out = T.copy()
        out[:3, :3] = T[:3, :3] @ np.array([[1, 0, 0], [0, c, -s_], [0, s_, c]])
        return out

    def com_above(T: np.ndarray) -> np.ndarray:
        return T[:3, 3] + 0.3 * T[:3, 2]

    stops = [
        checks.record(10 * k, poses[k], rolled(rest[k], 0.5 * (k >= 5)), False,
                      com_above(rolled(rest[k], 0.5 * (k >= 5))))
        for k in range(9)
    ]  # fmt: skip
    assert stops == [False] * 9 and checks.end is None
    assert np.allclose(checks.tilt[:5], 0.0, atol=1e-9)
    assert np.allclose(checks.tilt[5:8], 0.5) and len(checks.tilt) == 8  # the 9th pending
    over = rolled(rest[9], 1.4)
    assert checks.record(90, poses[9], over, False, com_above(over)) is True
    assert checks.end == (90, 90, "tipped") and len(checks.tilt) == 10
    assert checks.tilt[9] == pytest.approx(1.4)
    off = TipCheck(problem, batch=2)
    outside = np.array([[2.0, 0.0, 0.0], [9.0, 0.0, 0.0]])  # the second off the map
    assert off.record(0, outside[0], rest[0], False) is False
    assert off.record(7, outside[1], rest[0], False) is True
    assert off.end == (0, 7, "left_map") and off.index == [0] and len(off.tilt) == 1


def test_support_lost_needs_the_hold_time() -> None:
    """μ ≤ 0 (or no contact, NaN) for ``hold`` seconds is a tip; shorter dips are not."""
    t = np.arange(20) * 0.02
    mu = np.full(20, 500.0)
    mu[2:6] = -1.0  # 0.06 s: a dip
    assert support_lost(t, mu, 0.1) is None
    mu[10:13], mu[13:17] = np.nan, 0.0  # lost from 0.20 s, 0.10 s later at check 15
    assert support_lost(t, mu, 0.1) == (10, 15)
    assert support_lost(t, mu, 0.06) == (2, 5)
    assert support_lost(t, np.full(20, 1.0), 0.0) is None


def test_stowed_plan_holds_the_arm_stowed(ramp) -> None:
    problem, plan = ramp
    stowed = stowed_plan(problem.robot, plan)
    k = len(plan.fractions)
    assert np.array_equal(stowed.postures, np.tile(problem.robot.stowed, (k, 1)))
    com = problem.robot.arm_com(problem.robot.stowed)
    assert np.allclose(stowed.target_com, com) and np.array_equal(stowed.fractions, plan.fractions)


def test_an_older_problem_files_tip_angle_is_the_disagreement_angle(tmp_path) -> None:
    """Problem files written before the rename (``physics.tip_angle``) still load and run."""
    from conftest import write_problem

    from mmstab.core.problem import load_problem
    from mmstab.outputs.simulate import loop_settings

    path = write_problem(tmp_path, lambda p, r: p.setdefault("physics", {}).update(tip_angle=0.5))
    assert loop_settings(load_problem(path)).disagreement_angle == 0.5
    path = write_problem(tmp_path, lambda p, r: p.setdefault("physics", {}).update(tip_angle=30))
    with pytest.raises(Exception, match="rad"):
        load_problem(path)  # degrees refused, as for the new name


def test_a_replay_draws_the_robot_where_mujoco_had_it(ramp, tmp_path: Path) -> None:
    import copy

    from PIL import Image

    from mmstab.outputs.simulate_figure import write_run_gif

    problem, plan = ramp
    run = _run(problem, plan, 1.0)
    at = np.flatnonzero(np.isfinite(run.body_G_T_B[:, 0, 0]))
    assert len(at) > 5 and np.array_equal(at, np.flatnonzero(np.isfinite(run.tilt_error)))
    # the recorded frames are MuJoCo's attitude: their tilt off the terrain's rest is the run's
    z_rest = np.asarray(problem.terrain.G_T_B(run.state[at, :3])).reshape(-1, 4, 4)[:, :3, 2]
    tilt = np.arccos(np.clip(np.einsum("ni,ni->n", z_rest, run.body_G_T_B[at, :3, 2]), -1, 1))
    assert tilt == pytest.approx(run.tilt_error[at], abs=1e-9)
    M_T_B = np.linalg.inv(problem.terrain.G_T_M()) @ run.body_G_T_B[at]
    assert M_T_B[:, :2, 3] == pytest.approx(run.state[at, :2], abs=1e-9)  # B's origin in M
    short = copy.deepcopy(problem)
    short.data.setdefault("animation", {}).update(frames=6, width=240, height=160)
    info = write_run_gif(tmp_path / "physics.gif", short, run)
    with Image.open(info.path) as gif:
        assert gif.n_frames == info.frames == 6
