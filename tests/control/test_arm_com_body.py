"""The arm-CoM task in the body frame (``controller.arm_com_frame: body``).

The task tracks g_a^B(q_arm) instead of its placement in M (:class:`ArmCoMBodyTask`); the
setting swaps it into the controller's task list and the run's references carry the body-frame
CoM of the posture reference (:func:`mmstab.control.posture.body_frame_reference`).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_tracking import posture_plan

from mmstab.codegen.build import generate
from mmstab.codegen.functions import STEP_NAME
from mmstab.control.approach import run_reference
from mmstab.control.controller import ControllerSettings, build_controller
from mmstab.control.layout import StepReference
from mmstab.control.reference import PathSample, place_on_path
from mmstab.control.tasks import (
    ArmCoMBodyTask,
    BasePointTask,
    TaskModel,
    controller_task_names,
    task_map,
)
from mmstab.runs.online.follow import step_target
from mmstab.runs.tracking.simulation import simulate
from mmstab.terrain import place_local


@pytest.fixture(scope="module")
def settings(problem):
    """The problem's controller settings, box solver, both frames."""
    base = ControllerSettings.from_section(problem.section("controller"))
    box = dataclasses.replace(base, plugin="box")
    return {f: dataclasses.replace(box, arm_com_frame=f) for f in ("map", "body")}


def random_state(robot, rng):
    """A state anywhere (pose, sprockets, arm within its limits) (5 + n,)."""
    q = rng.uniform(robot.joint_lower, robot.joint_upper)
    return np.r_[rng.uniform(-2, 2, 2), rng.uniform(-np.pi, np.pi), rng.uniform(-3, 3, 2), q]


def test_the_body_task_is_the_arm_com_in_b_and_its_jacobian_its_rate(problem, rng):
    """Value g_a^B(q) whatever the pose and ground; J q̇ equals the rate along the plant."""
    robot = problem.robot
    model = TaskModel(robot, task_map([BasePointTask(0.2), ArmCoMBodyTask()]))
    h, worst = 1e-6, 0.0
    for _ in range(50):
        s, ground = random_state(robot, rng), rng.normal(0.0, 0.2, 3)
        np.testing.assert_allclose(model.task(s, ground)[3:], robot.arm_com(s[5:]), atol=1e-15)
        J = model.jacobian(s, ground)[3:]
        assert np.all(J[:, :2] == 0.0)  # the tracks do not move the CoM in B
        qdot = rng.normal(0.0, 1.0, J.shape[1])
        ahead = model.task(model.integrate(s, qdot, h), ground)[3:]
        behind = model.task(model.integrate(s, -qdot, h), ground)[3:]
        worst = max(worst, float(np.max(np.abs((ahead - behind) / (2 * h) - J @ qdot))))
    assert worst < 1e-7


def test_the_setting_swaps_the_arm_com_task(problem, settings):
    assert controller_task_names(settings["map"]) == ("base_point", "arm_com", "posture")
    assert controller_task_names(settings["body"]) == ("base_point", "arm_com_body", "posture")
    ctrl = build_controller(problem.robot, settings["body"])
    assert [t.name for t in ctrl.tasks] == ["base_point", "arm_com_body", "posture"]
    with pytest.raises(ValueError, match="arm_com_frame 'world'"):
        controller_task_names(dataclasses.replace(settings["map"], arm_com_frame="world"))


def test_the_body_reference_is_the_map_reference_seen_from_the_reference_pose(problem, settings):
    """Placed with the reference pose, the B rows are the M rows (approach and lap alike)."""
    robot, cs = problem.robot, settings["body"]
    t = np.arange(0.0, 6.0, 0.01)  # the 1 s approach, then the lap
    q0 = robot.stowed
    body = run_reference(robot, problem.circle, problem.terrain, posture_plan(robot), q0, cs, t)
    s = t / cs.lap_time
    com = PathSample(body.control.xi_des[:, 3:], body.control.xi_dot_ref[:, 3:] * cs.lap_time)
    placed = place_on_path(problem.circle, problem.terrain, s, com)
    np.testing.assert_allclose(placed.value, body.step.xi_des[:, 3:], atol=1e-12)
    np.testing.assert_allclose(placed.rate / cs.lap_time, body.step.xi_dot_ref[:, 3:], atol=1e-12)
    np.testing.assert_allclose(body.control.xi_des[:, 3:], robot.arm_com(body.step.q_ref))
    for field in ("q_ref", "q_dot_ref", "ground"):
        assert np.array_equal(getattr(body.control, field), getattr(body.step, field))
    assert np.array_equal(body.control.xi_des[:, :3], body.step.xi_des[:, :3])
    plain = run_reference(
        robot, problem.circle, problem.terrain, posture_plan(robot), q0, settings["map"], t
    )
    assert plain.control is plain.step  # the default: the M reference, as before


def test_the_online_step_target_is_in_the_frame_of_the_setting(settings):
    pose, ground, com = np.array([[1.0, -0.5, 0.7]]), np.array([[0.1, 0.2, -0.1]]), [0.3, 0.1, 0.4]
    body, plain = (step_target(settings[f], pose, ground, np.array(com)) for f in ("body", "map"))
    placed = place_local(pose, ground, np.array([com])).points[0]
    np.testing.assert_array_equal(body[3:], com)
    np.testing.assert_allclose(plain[3:], placed, atol=1e-15)
    assert np.linalg.norm(placed - com) > 0.5  # the two frames differ here
    np.testing.assert_array_equal(body[:3], plain[:3])


def test_a_kinematic_run_in_b_tracks_as_the_run_in_m(problem, settings):
    """No base error to speak of on the kinematic plant: both frames give the same run.

    Measured on this lap: the M-frame arm-CoM error peaks at 0.86 mm (map) and 0.88 mm (body),
    the runs differ by at most 0.24 mm in base position and 7.2 mrad in the joints.
    """
    plan = posture_plan(problem.robot)
    runs = {f: simulate(problem, plan, progress=False, settings=cs) for f, cs in settings.items()}
    m, b = runs["map"], runs["body"]
    assert not m.failures and not b.failures
    assert m.state.shape == b.state.shape == (30001, 9)
    assert b.arm_com_error.max() < 1.5e-3  # reported in M
    assert np.abs(b.arm_com_error - m.arm_com_error).max() < 5e-4
    assert b.base_error.max() < 1e-3 and m.base_error.max() < 1e-3
    assert np.abs(b.state[:, :2] - m.state[:, :2]).max() < 1e-3
    assert np.abs(b.state[:, 5:] - m.state[:, 5:]).max() < 0.02
    assert np.abs(b.state[:, 5:] - m.state[:, 5:]).max() > 1e-4  # yet not the same controller


def test_a_base_behind_its_reference_moves_the_arm_in_m_and_not_in_b(problem, settings):
    """The base 20 cm behind its reference as the lap drives on (0.31 m/s), the arm on its
    posture reference: the tracks' command reaches their speed limit, and in M the CoM row
    takes the rest from the arm, off the posture the plan checked (dem.yaml's arm, so
    tracked, grazed a bump in MuJoCo with its base that far behind); in B the arm holds its
    posture and the base rows alone take the error back."""
    robot = problem.robot
    q = np.asarray(posture_plan(robot).postures[0], dtype=float)
    reference = np.r_[0.0, 0.0, 0.0, 0.0, 0.0, q]
    behind = reference.copy()
    behind[0] -= 0.2  # heading 0: 20 cm behind along the path
    speed = 2 * np.pi * 1.5 / 30.0  # the lap's [m/s]
    arm = {}
    for frame, cs in settings.items():
        ctrl = build_controller(robot, cs)
        xi = ctrl.model.task(reference)  # the reference state's task, in the frame's rows
        rate = np.r_[speed, 0.0, 0.0, speed if frame == "map" else 0.0, 0.0, 0.0]
        r = ctrl.solve(behind, xi, rate, q_ref=q, q_dot_ref=np.zeros(len(q)))
        assert r.success
        arm[frame] = r.qdot[2:]
        limit = robot.base.tracks.velocity_limit  # [rad/s]
        np.testing.assert_allclose(r.qdot[:2], [limit, limit], rtol=1e-6)  # at the limit
    assert np.abs(arm["body"]).max() < 1e-6  # the posture the plan checked, held
    assert np.abs(arm["map"]).max() > 0.5  # reaching [rad/s]
    J = np.asarray(robot.kinematics.f_arm_com_jac(q))  # d g_a^B / d q (3, n)
    assert (J @ arm["map"])[0] > 0.05  # the CoM pushed forward, toward the map point [m/s]


@pytest.mark.slow
def test_the_generated_c_of_the_body_variant_equals_the_interpreted_step(
    problem, settings, rng, tmp_path
):
    """The setting reaches the generated step: C and interpreted agree, and differ from M."""
    robot, cs = problem.robot, settings["body"]
    gen = generate((robot, cs), tmp_path / "body", "box")
    assert "task arm_com_body (3 rows)" in gen.layout.read_text()
    ext = gen.load(STEP_NAME)
    body, plain = build_controller(robot, cs), build_controller(robot, settings["map"])
    p = body.params.pack()
    worst, moved = 0.0, 0
    for _ in range(200):
        s = random_state(robot, rng)
        s[3:5] = 0.0
        q = s[5:] + rng.normal(0.0, 0.1, 4)
        xi = np.r_[plain.model.task(s)[:3], robot.arm_com(q)] + rng.normal(0.0, 0.02, 6)
        ref = StepReference(xi, np.zeros(6), q, np.zeros(4), np.zeros(3)).pack()
        a = [np.asarray(v) for v in body.step(s, ref, p)]
        b = [np.asarray(v) for v in ext(s, ref, p)]
        assert a[1].item() == b[1].item() == 0.0  # SUCCESS
        worst = max(worst, max(float(np.max(np.abs(x - y))) for x, y in zip(a, b, strict=True)))
        moved += not np.allclose(a[0], np.asarray(plain.step(s, ref, p)[0]), atol=1e-9)
    assert worst <= 1e-10
    assert moved == 200  # the frame changed every step's answer
