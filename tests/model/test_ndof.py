"""An arm of any number of joints: the 6-DoF robot (problems/robots/cameleon_6dof.yaml) end to end.

The arm's joint count comes from the robot file's ``arm.links``; these tests check the
6-joint kinematics, layout, QP, generated C, workspace sampling and the command line on
problems/ramp_6dof.yaml against independent references (finite differences, a second QP
solver, the interpreted step).
"""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
import time

import casadi as ca
import numpy as np
import pytest
import yaml
from conftest import ROOT

from mmstab.codegen import STEP_NAME, generate
from mmstab.control.controller import (
    ControllerParams,
    ControllerSettings,
    QPStatus,
    StepReference,
    build_controller,
)
from mmstab.control.controller.qp import slot_notes
from mmstab.control.layout import Layout, layout_header
from mmstab.control.tasks import ArmCoMTask, BasePointTask, PostureTask, build_task_model
from mmstab.core import sizes
from mmstab.core.files import ConfigError
from mmstab.core.problem import load_problem
from mmstab.workspace import grid_postures, joint_grid

PROBLEM_6DOF = ROOT / "problems" / "ramp_6dof.yaml"
N = 6


@pytest.fixture(scope="module")
def problem6():
    return load_problem(PROBLEM_6DOF)


@pytest.fixture(scope="module")
def robot6(problem6):
    return problem6.robot


def settings_of(problem, plugin: str) -> ControllerSettings:
    settings = ControllerSettings.from_section(problem.section("controller"))
    return dataclasses.replace(settings, plugin=plugin)


def random_states(robot, rng, n):
    q = rng.uniform(robot.joint_lower, robot.joint_upper, (n, robot.arm_joints))
    return np.column_stack(
        [rng.uniform(-2, 2, (n, 2)), rng.uniform(-np.pi, np.pi, n), rng.uniform(-9, 9, (n, 2)), q]
    )


# ------------------------------------------------------------------------------ the robot
def test_the_joint_count_comes_from_the_robot_file(robot6, problem):
    assert (
        robot6.arm_joints
        == N
        == len(
            yaml.safe_load(
                PROBLEM_6DOF.parent.joinpath("robots", "cameleon_6dof.yaml").read_text()
            )["arm"]["links"]
        )
    )
    assert Layout.of(robot6) == Layout(6)
    lay = Layout.of(robot6)
    assert (lay.state, lay.joints, lay.reference, lay.params) == (11, 8, 27, 54)
    # the 4-DoF layout keeps its numbers
    lay4 = Layout.of(problem.robot)
    assert (lay4.state, lay4.joints, lay4.reference, lay4.params) == (9, 6, 23, 42)


def test_com_jacobian_equals_finite_differences(robot6, rng):
    h = 1e-6
    for q in rng.uniform(robot6.joint_lower, robot6.joint_upper, (20, N)):
        jac = np.asarray(robot6.kinematics.f_arm_com_jac(q))
        assert jac.shape == (3, N)
        fd = np.column_stack(
            [(robot6.arm_com(q + h * e) - robot6.arm_com(q - h * e)) / (2 * h) for e in np.eye(N)]
        )
        np.testing.assert_allclose(jac, fd, atol=1e-8)
        # the batched NumPy CoM equals the CasADi one
        np.testing.assert_allclose(
            robot6.arm_com(q), np.asarray(robot6.kinematics.f_arm_com(q)).ravel(), atol=1e-12
        )


@pytest.mark.parametrize("task", [BasePointTask(0.2), ArmCoMTask(), PostureTask()])
def test_task_jacobians_are_the_rates_along_the_plant(robot6, rng, task):
    """(value(s after +h) − value(s after −h)) / 2h = J q̇ for the 6-joint arm."""
    model = build_task_model(robot6, 0.2)
    value = ca.Function("v", [model.state, model.ground], [task.value(model)])
    jac = ca.Function("J", [model.state, model.ground], [task.jacobian(model)])
    h = 1e-6
    for s in random_states(robot6, rng, 10):
        ground, qdot = rng.normal(0, 0.2, 3), rng.uniform(-3, 3, 2 + N)
        fd = (
            np.asarray(value(model.integrate(s, qdot, h), ground))
            - np.asarray(value(model.integrate(s, qdot, -h), ground))
        ).ravel() / (2 * h)
        assert np.asarray(jac(s, ground)).shape == (task.rows(model), 2 + N)
        np.testing.assert_allclose(np.asarray(jac(s, ground)) @ qdot, fd, atol=1e-7)


def test_unpack_reads_the_arm_from_the_length(robot6, problem6):
    params = ControllerParams.from_settings(robot6, settings_of(problem6, "qpoases"))
    packed = params.pack()
    assert packed.shape == (54,)
    back = ControllerParams.unpack(packed)
    np.testing.assert_array_equal(back.q_min, robot6.joint_lower)
    np.testing.assert_array_equal(back.q_max, robot6.joint_upper)
    assert back.qdot_max.shape == (8,)
    ref = StepReference.unpack(np.arange(27.0))
    assert ref.q_ref.tolist() == list(range(12, 18)) and ref.ground.tolist() == [24, 25, 26]
    with pytest.raises(ValueError, match="fits no arm"):
        ControllerParams.unpack(np.zeros(43))


# ------------------------------------------------------------------------------------- QP
def test_qp_solves_within_the_joint_limits(robot6, problem6, rng):
    """Box and qpOASES agree, and q + q̇ dt stays in the limits when the reference pulls out."""
    box = build_controller(robot6, settings_of(problem6, "box"))
    other = build_controller(robot6, settings_of(problem6, "qpoases"))
    dt = box.settings.dt
    lo, hi = robot6.joint_lower, robot6.joint_upper
    active = 0
    for s in random_states(robot6, rng, 200):
        # near a limit, asked beyond it: the position limit must bind
        s[5:] = np.where(rng.random(N) < 0.5, lo + 1e-4, hi - 1e-4)
        q_ref = np.where(s[5:] < 0.5 * (lo + hi), lo - 1.0, hi + 1.0)
        xi_des = np.r_[s[:2] + rng.normal(0, 0.3, 2), s[2], rng.uniform(-1, 1, 3)]
        a = box.solve(s, xi_des, q_ref=q_ref)
        b = other.solve(s, xi_des, q_ref=q_ref)
        assert a.status is QPStatus.SUCCESS and b.status is QPStatus.SUCCESS
        np.testing.assert_allclose(a.qdot, b.qdot, atol=1e-7)
        q_next = s[5:] + a.qdot[2:] * dt
        assert np.all(q_next >= lo - 1e-9) and np.all(q_next <= hi + 1e-9)
        assert np.all(np.abs(a.qdot) <= box.params.qdot_max + 1e-9)
        active += int(np.any(np.isclose(q_next, lo, atol=1e-9) | np.isclose(q_next, hi, atol=1e-9)))
    assert active > 100  # the limits did bind


# ------------------------------------------------------------------------------- codegen
@pytest.mark.slow
def test_generated_step_equals_interpreted(robot6, problem6, rng, tmp_path):
    settings = settings_of(problem6, "box")
    gen = generate((robot6, settings), tmp_path / "box", "box")
    ext = gen.load(STEP_NAME)
    ctrl = build_controller(robot6, settings)
    p = ctrl.params.pack()
    assert [ext.size1_in(i) for i in range(3)] == [11, 27, 54] and ext.size1_out(0) == 8
    worst, statuses = 0.0, []
    for s in random_states(robot6, rng, 300):
        ref = np.r_[
            s[:2] + rng.normal(0, 0.2, 2),
            rng.uniform(-np.pi, np.pi),
            rng.uniform(-1, 1, 3),
            rng.normal(0, 0.3, 6),
            rng.uniform(robot6.joint_lower - 0.1, robot6.joint_upper + 0.1),
            rng.normal(0, 1.0, N),
            rng.normal(0, 0.2, 3),
        ]
        a = [np.asarray(v) for v in ctrl.step(s, ref, p)]
        b = [np.asarray(v) for v in ext(s, ref, p)]
        assert a[1].item() == b[1].item()
        worst = max(worst, max(float(np.max(np.abs(x - y))) for x, y in zip(a, b, strict=True)))
        statuses.append(int(b[1].item()))
    assert worst <= 1e-10
    assert statuses.count(QPStatus.SUCCESS) > 200
    header = gen.layout.read_text()
    assert "#define MMSTAB_N_ARM 6" in header and "#define MMSTAB_N_PARAMS 54" in header
    notes = slot_notes(ctrl.tasks, ctrl.limits, ctrl.model)
    assert header == layout_header(settings.kkt_tol, 6, notes)
    assert (
        "/* task posture (6 rows): q_ref q_dot_ref posture_gain posture_weight feedforward */"
        in header
    )


# ----------------------------------------------------------------------------- workspace
def test_a_six_joint_grid_is_sampled_and_seeded(robot6, problem6):
    ws = problem6.section("workspace")
    grid, samples = ws["grid"], ws["samples"]
    assert np.prod(grid) > sizes.WS_FULL_GRID_MAX
    assert sizes.workspace_postures(grid, samples) == (samples, True)
    assert "sampled" in sizes.workspace_estimate(grid, samples).work
    a, b = joint_grid(robot6, grid, samples, 3), joint_grid(robot6, grid, samples, 3)
    np.testing.assert_array_equal(a.picks, b.picks)
    assert not np.array_equal(a.picks, joint_grid(robot6, grid, samples, 4).picks)
    q = grid_postures(a)
    assert q.shape == (samples, N) and len(np.unique(a.picks)) == samples
    # every drawn posture is a grid posture: on each joint's axis
    for j, axis in enumerate(a.axes):
        assert np.isin(q[:, j], axis).all()
    # the 4-DoF default grid is labelled whole, as before, and so is a large grid without
    # workspace.samples (then refused by the size bounds, naming the setting to use)
    assert sizes.workspace_postures([24, 29, 25, 25], samples) == (24 * 29 * 25 * 25, False)
    assert sizes.workspace_postures(grid) == (int(np.prod(grid)), False)
    assert "set workspace.samples" in sizes.workspace_estimate(grid).work


def test_per_joint_settings_must_match_the_arm(tmp_path):
    data = yaml.safe_load(PROBLEM_6DOF.read_text())
    data["robot"] = str(PROBLEM_6DOF.parent / data["robot"])
    data["controller"]["w_b"] = data["controller"]["w_b"][:6]
    path = tmp_path / "p.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=r"controller\.w_b: has 6 entries, needs 8 for .*6-joint"):
        load_problem(path)


# ----------------------------------------------------------------------------- the CLI
@pytest.mark.slow
def test_cli_runs_the_6dof_problem_end_to_end(tmp_path):
    env = {**os.environ, "MPLBACKEND": "Agg", "PYTHONPATH": str(ROOT)}

    def run(*args: str) -> subprocess.CompletedProcess[str]:
        t0 = time.perf_counter()
        proc = subprocess.run(
            [sys.executable, "-m", "mmstab", *args, str(PROBLEM_6DOF)],
            cwd=tmp_path,
            env=env,
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert proc.returncode == 0, proc.stderr[-2000:]
        assert time.perf_counter() - t0 < 60
        return proc

    out = run("workspace").stdout
    assert "30000 postures sampled of the 24x29x25x25x13x13 grid" in out
    run("plan")
    plan = np.load(tmp_path / "results" / "plan" / "plan.npz")
    assert plan["postures"].shape[1] == N
    run("track")
    summary = json.loads((tmp_path / "results" / "tracking" / "summary.json").read_text())
    names = ["track_left", "track_right", *(f"link{j}" for j in range(N))]
    assert list(summary["qdot_max_abs"]) == names
    assert summary["qp_failures"] == 0
    run("codegen")
    header = (tmp_path / "results" / "codegen_6dof" / "box" / "controller_layout.h").read_text()
    assert "#define MMSTAB_N_ARM 6" in header


def test_a_three_joint_arm_tracks_animates_and_follows_from_a_three_key_problem(tmp_path):
    """Before: ``track`` stopped in its figures (index 3 is out of bounds for axis 1 with size
    3), ``animation`` refused the stored run (state (T, 8), expected (T, 9)) and ``follow``
    stopped at its first controller step."""
    from mmstab.cli import main

    robot = yaml.safe_load((ROOT / "problems" / "robots" / "cameleon.yaml").read_text())
    robot["arm"]["links"] = robot["arm"]["links"][:3]  # no wrist
    robot["arm"]["stowed"] = robot["arm"]["stowed"][:3]
    (tmp_path / "r3.yaml").write_text(yaml.safe_dump(robot))
    problem = {
        "robot": "r3.yaml",
        "terrain": {"slope": 0.1},
        "path": {"waypoints": [[0.0, 0.0], [1.0, 0.0]], "speed": 0.3, "turn_radius": 0.0},
        "animation": {"frames": 3, "fps": 2, "width": 160, "height": 120},
        "workspace": {"grid": [9, 9, 9]},  # V and its roadmap in a fraction of a second
    }
    path = tmp_path / "p3.yaml"
    path.write_text(yaml.safe_dump(problem))
    out = tmp_path / "track"
    assert main(["track", str(path), "-o", str(out)]) == 0
    with np.load(out / "run.npz") as run:
        assert list(run["joint_names"]) == ["track_left", "track_right", "link0", "link1", "link2"]
        assert run["qdot"].shape[1] == 5 and run["state"].shape[1] == 8
        assert list(run["state_names"])[5:] == ["theta_0", "theta_1", "theta_2"]
    assert all((out / f"fig{k}.png").stat().st_size > 0 for k in (9, 10, 11, 12))
    assert main(["animation", str(path), "-o", str(out)]) == 0  # the stored run, 3 joints
    assert (out / "animation.gif").stat().st_size > 0
    # online (before: the arm integrated with the last 4 of q̇'s columns, a track's among them)
    bag = tmp_path / "rec.mcap"
    assert main(["record", str(path), "-o", str(bag)]) == 0
    assert main(["follow", str(path), "--bag", str(bag), "-o", str(tmp_path / "follow")]) == 0
    summary = json.loads((tmp_path / "follow" / "summary.json").read_text())
    assert summary["updates"] > 10 and summary["qp_failures"] == 0


def test_a_one_joint_arm_is_refused_for_its_arm_not_its_grid(tmp_path, capsys):
    """A turret alone moves the arm CoM on a circle: no grid gives it a volume (before: the
    message said to refine the workspace grid). It still rests."""
    from mmstab.cli import main

    robot = yaml.safe_load((ROOT / "problems" / "robots" / "cameleon.yaml").read_text())
    robot["arm"]["links"] = robot["arm"]["links"][:1]
    robot["arm"]["stowed"] = robot["arm"]["stowed"][:1]
    (tmp_path / "r1.yaml").write_text(yaml.safe_dump(robot))
    path = tmp_path / "p1.yaml"
    path.write_text(yaml.safe_dump({
        "robot": "r1.yaml", "terrain": {"slope": 0.1},
        "path": {"waypoints": [[0.0, 0.0], [1.0, 0.0]], "speed": 0.3, "turn_radius": 0.0},
    }))  # fmt: skip
    assert main(["plan", str(path), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "the arm's joints move its CoM in a plane (one joint" in err[0]
    assert "refine the workspace grid" not in err[0] and not (tmp_path / "out").exists()
    assert main(["rest", str(path), "--pose", "0", "0", "0"]) == 0
    # a grid of 2 angles a joint is flat for the grid's sake: refine it
    from mmstab.core.files import MmstabError
    from mmstab.workspace.region import workspace_from_clouds

    q = np.array([[0.0, 0.0], [0.0, 1.0], [1.0, 0.0], [1.0, 1.0]])
    com = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]])
    with pytest.raises(MmstabError, match="no volume; refine the workspace grid$"):
        workspace_from_clouds((2, 2), q, com, np.zeros((0, 2)), np.zeros((0, 3)), 0.0)
