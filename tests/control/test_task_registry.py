"""Tasks and limits as lists: a new task is one class plus its registration, solved by the QP.

The example task, arm joint centring, is written here as a user would write its module
(``docs/controller.md``, "Adding a controller task"): a :class:`Task` with its name, rows,
value, Jacobian and slots, registered in :data:`TASKS` and built by :func:`build_tasks`.
"""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np
import pytest

from mmstab.codegen.build import generate
from mmstab.codegen.functions import STEP_NAME
from mmstab.control.controller import ControllerParams, ControllerSettings, build_controller
from mmstab.control.controller.qp import slot_notes
from mmstab.control.layout import ARM, SPROCKETS, StepReference, layout_header
from mmstab.control.limits import DEFAULT_LIMITS, LIMITS, build_limits
from mmstab.control.tasks import (
    DEFAULT_TASKS,
    TASKS,
    ArmCoMTask,
    BasePointTask,
    PostureTask,
    Slot,
    Task,
    TaskModel,
    TaskSlots,
    TaskTarget,
    build_tasks,
    task_map,
)


class JointCentringTask(Task):
    """q_arm → the middle of each joint's range, (q_min + q_max)/2 [rad] (the example task)."""

    name = "joint_centring"
    # the target is computed from q_min and q_max (no slot of its own); gains and weights are
    # the posture task's
    slots = TaskSlots(None, None, Slot("posture_gain"), Slot("posture_weight"))

    def rows(self, model: TaskModel) -> int:
        """n: one row per arm joint."""
        return model.layout.arm

    def value(self, model: TaskModel) -> ca.SX:
        """q_arm (n,) [rad]."""
        return model.state[ARM]

    def jacobian(self, model: TaskModel) -> ca.SX:
        """(n, 2 + n): the arm columns of q̇."""
        n = self.rows(model)
        return ca.horzcat(ca.SX.zeros(n, SPROCKETS), ca.SX.eye(n))

    def target(self, reference: StepReference, params: ControllerParams) -> TaskTarget:
        """The middle of the joint ranges, at rest (no feed-forward rate)."""
        return super().target(reference, params)._replace(value=(params.q_min + params.q_max) / 2)


@pytest.fixture
def registered(monkeypatch):
    """The example task's registration line: its class in ``TASKS`` under its name."""
    monkeypatch.setitem(TASKS, JointCentringTask.name, JointCentringTask)


@pytest.fixture(scope="module")
def settings(problem):
    return dataclasses.replace(
        ControllerSettings.from_section(problem.section("controller")), plugin="box"
    )


def test_the_registries_name_the_default_lists(settings):
    assert DEFAULT_TASKS == ("base_point", "arm_com", "posture")
    assert [type(t) for t in build_tasks(settings)] == [BasePointTask, ArmCoMTask, PostureTask]
    assert build_tasks(settings)[0].offset == settings.base_offset  # type: ignore[attr-defined]
    assert DEFAULT_LIMITS == ("joint_velocity", "joint_position", "yaw_rate") == tuple(LIMITS)
    assert [limit.name for limit in build_limits()] == list(DEFAULT_LIMITS)
    with pytest.raises(ValueError, match="joint_centring"):
        build_tasks(settings, (*DEFAULT_TASKS, "joint_centring"))  # not registered here


def test_the_task_map_is_the_tasks_of_xi_in_row_order(settings):
    base, com, posture = build_tasks(settings)
    assert task_map([posture, com, base]) == (base, com)
    with pytest.raises(ValueError, match="do not tile"):
        task_map([base, posture])  # ξ's CoM rows: no task
    with pytest.raises(ValueError, match="do not tile"):
        task_map([base, com, BasePointTask(0.1)])  # rows 0..3 twice
    with pytest.raises(ValueError, match="do not tile"):
        task_map([])


def test_a_task_without_a_value_slot_must_compute_its_target(problem, settings):
    class Unfinished(JointCentringTask):
        name = "unfinished"
        target = Task.target  # the slots' reading alone, which has no value to read

    with pytest.raises(TypeError, match="'unfinished' has no value slot"):
        build_controller(problem.robot, settings, tasks=[*build_tasks(settings), Unfinished()])


def test_a_registered_task_is_summed_into_the_qp_and_solved(problem, settings, registered, rng):
    """The example task adds exactly Sᵀ W_q S to H and −Sᵀ W_q K_q (q_mid − q) to g."""
    robot = problem.robot
    plain = build_controller(robot, settings)
    tasks = build_tasks(settings, (*DEFAULT_TASKS, "joint_centring"))
    centred = build_controller(robot, settings, tasks=tasks)
    assert [t.name for t in centred.tasks] == [*DEFAULT_TASKS, "joint_centring"]
    P = centred.params
    mid = (robot.joint_lower + robot.joint_upper) / 2
    checked = 0
    for _ in range(20):
        q = rng.uniform(robot.joint_lower, robot.joint_upper) * 0.5 + mid * 0.5
        state = np.r_[rng.uniform(-1, 1, 2), rng.uniform(-np.pi, np.pi), 0.0, 0.0, q]
        xi_des = plain.model.task(state) + rng.normal(0, 0.05, 6)
        a, b = plain.qp_data(state, xi_des), centred.qp_data(state, xi_des)
        v = P.posture_gain * (mid - q)  # the centring rate [rad/s]
        dH, dg = np.zeros((6, 6)), np.zeros(6)
        dH[2:, 2:], dg[2:] = np.diag(P.posture_weight), -P.posture_weight * v
        np.testing.assert_allclose(b.H - a.H, dH, atol=1e-12)
        np.testing.assert_allclose(b.g - a.g, dg, atol=1e-12)
        assert b.cost0 - a.cost0 == pytest.approx(0.5 * v @ (P.posture_weight * v), abs=1e-12)
        np.testing.assert_array_equal(b.lbx, a.lbx)
        np.testing.assert_array_equal(b.xi_dot_des, a.xi_dot_des)
        res = centred.solve(state, xi_des)
        assert res.success
        unconstrained = np.linalg.solve(b.H, -b.g)
        if np.all((b.lbx < unconstrained) & (unconstrained < b.ubx)):  # interior: the optimum
            np.testing.assert_allclose(res.qdot, unconstrained, atol=1e-9)
            assert not np.allclose(res.qdot, plain.solve(state, xi_des).qdot, atol=1e-9)
            checked += 1
    assert checked >= 10


def test_the_c_header_names_each_task_s_slots_and_each_limit_s_rows(problem, settings, registered):
    """controller_layout.h's comments: the packed fields each task reads, rows each limit bounds."""
    tasks = build_tasks(settings, (*DEFAULT_TASKS, "joint_centring"))
    ctrl = build_controller(problem.robot, settings, tasks=tasks)
    notes = slot_notes(ctrl.tasks, ctrl.limits, ctrl.model)
    assert notes == [
        "task base_point (3 rows): xi_des[0:3] xi_dot_ref[0:3] kp[0:3] w_a[0:3] feedforward",
        "task arm_com (3 rows): xi_des[3:6] xi_dot_ref[3:6] kp[3:6] w_a[3:6] feedforward",
        "task posture (4 rows): q_ref q_dot_ref posture_gain posture_weight feedforward",
        "task joint_centring (4 rows): - - posture_gain posture_weight feedforward",
        "limit joint_velocity: qdot[0:6]",
        "limit joint_position: qdot[2:6]",
        "limit yaw_rate: qdot[0:2], reads xi_dot_ref[2:3] ground xi_dot_des[0:2] qdot_max[0:2]",
    ]
    plain, header = layout_header(settings.kkt_tol), layout_header(settings.kkt_tol, notes=notes)
    assert [line for line in header.splitlines() if "#define" in line] == [
        line for line in plain.splitlines() if "#define" in line
    ]  # comments only: every macro, and so the packed order, as before
    assert f"/* {notes[3]} */" in header


@pytest.mark.slow
def test_the_generated_c_of_a_registered_task_equals_the_interpreted_step(
    problem, settings, registered, rng, tmp_path
):
    """The new task reaches the generated step: C and interpreted agree, and differ from default."""
    robot = problem.robot
    tasks = build_tasks(settings, (*DEFAULT_TASKS, "joint_centring"))
    gen = generate((robot, settings), tmp_path / "centred", "box", tasks=tasks)
    assert "task joint_centring (4 rows)" in gen.layout.read_text()
    ext = gen.load(STEP_NAME)
    centred, plain = (
        build_controller(robot, settings, tasks=tasks),
        build_controller(robot, settings),
    )
    p = centred.params.pack()
    worst, moved = 0.0, 0
    for _ in range(200):
        q = rng.uniform(robot.joint_lower, robot.joint_upper)
        s = np.r_[rng.uniform(-1, 1, 2), rng.uniform(-np.pi, np.pi), 0.0, 0.0, q]
        ref = StepReference(
            plain.model.task(s) + rng.normal(0, 0.1, 6), np.zeros(6), q, np.zeros(4), np.zeros(3)
        ).pack()
        a = [np.asarray(v) for v in centred.step(s, ref, p)]
        b = [np.asarray(v) for v in ext(s, ref, p)]
        assert a[1].item() == b[1].item() == 0.0  # SUCCESS
        worst = max(worst, max(float(np.max(np.abs(x - y))) for x, y in zip(a, b, strict=True)))
        moved += not np.allclose(a[0], np.asarray(plain.step(s, ref, p)[0]), atol=1e-9)
    assert worst <= 1e-10
    assert moved == 200  # the task changed every step's answer
