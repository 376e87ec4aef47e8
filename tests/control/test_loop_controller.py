"""mmstab.Controller: targets on tasks (pink/mink style) and one step for a robot's own loop."""

from __future__ import annotations

import numpy as np
import pytest

import mmstab
from mmstab.control.controller import QPStatus


@pytest.fixture(scope="module")
def controller(robot):
    return mmstab.Controller(robot)


def test_the_tasks_and_their_defaults(controller, robot):
    assert list(controller.tasks) == ["base_point", "arm_com_body", "posture"]  # body default
    assert controller.tasks["posture"].size == robot.arm_joints
    assert controller.settings == mmstab.Settings().controller  # a file naming none


def test_step_is_the_packed_solve(controller, robot):
    """The named step packs the targets as the simulation does: the same joint speeds."""
    rng = np.random.default_rng(3)
    lo, hi = robot.joint_lower, robot.joint_upper
    pose, arm = np.array([0.3, -0.2, 0.4]), rng.uniform(lo + 0.2 * (hi - lo), hi - 0.2 * (hi - lo))
    base, com, q_ref = [0.6, 0.0, 0.5], [0.02, 0.01, 0.22], robot.stowed
    base_rate = [0.1, 0.05, 0.02]
    controller.tasks["base_point"].set_target(base, rate=base_rate)
    controller.tasks["arm_com_body"].set_target(com)
    controller.tasks["posture"].set_target(q_ref)
    cmd = controller.step(base_pose=pose, arm=arm)
    state = np.concatenate([pose, [0.0, 0.0], arm])
    packed = controller.qp.solve(
        state, np.r_[base, com], np.r_[base_rate, 0, 0, 0], q_ref, None, None
    )
    assert cmd.success and cmd.status is QPStatus.SUCCESS
    np.testing.assert_array_equal(np.r_[cmd.tracks, cmd.arm], packed.qdot)
    assert cmd.objective == packed.objective


def test_no_error_no_motion(controller, robot):
    """Targets at the measured values and no feed-forward: the QP's answer is q̇ = 0."""
    pose, arm = np.array([1.0, 2.0, 0.7]), robot.stowed.copy()
    xi = controller.qp.model.task(np.concatenate([pose, [0.0, 0.0], arm]))
    controller.tasks["base_point"].set_target(xi[:3])
    controller.tasks["arm_com_body"].set_target(robot.arm_com(arm))
    controller.tasks["posture"].set_target(arm)
    cmd = controller.step(base_pose=pose, arm=arm)
    np.testing.assert_allclose(np.r_[cmd.tracks, cmd.arm], 0.0, atol=1e-12)


def test_a_point_ahead_drives_both_tracks_forward_alike(controller, robot):
    """The base point 10 cm straight ahead: equal, positive sprocket speeds."""
    arm = robot.stowed.copy()
    d = controller.settings.base_offset
    controller.tasks["base_point"].set_target([d + 0.1, 0.0, 0.0])
    controller.tasks["arm_com_body"].set_target(robot.arm_com(arm))
    controller.tasks["posture"].set_target(arm)
    cmd = controller.step(base_pose=[0.0, 0.0, 0.0], arm=arm)
    left, right = cmd.tracks
    assert left > 0 and left == pytest.approx(right, rel=1e-9)
    np.testing.assert_allclose(cmd.arm, 0.0, atol=1e-9)


def test_bad_targets_are_refused(robot):
    c = mmstab.Controller(robot)
    with pytest.raises(ValueError, match="has no target"):
        c.step(base_pose=[0.0, 0.0, 0.0], arm=robot.stowed)
    with pytest.raises(ValueError, match=r"shape \(3,\)"):
        c.tasks["base_point"].set_target([1.0, 2.0])
    with pytest.raises(ValueError, match="finite"):
        c.tasks["posture"].set_target([0.0, np.nan, 0.0, 0.0])
    c.tasks["base_point"].set_target([1.0, 0.0, 0.0])
    c.tasks["arm_com_body"].set_target([0.0, 0.0, 0.2])
    with pytest.raises(ValueError, match=r"arm must have shape \(4,\)"):
        c.step(base_pose=[0.0, 0.0, 0.0], arm=[0.0, 0.0])


def test_one_pose_gives_one_mu_and_stance_takes_the_robot_first(robot):
    ramp = mmstab.Ramp(0.2)
    g = ramp.gravity_body([0.0, 0.0, 0.3])
    com = robot.arm_com(robot.stowed)
    many = mmstab.robot_force_angle(robot, g, com[None])
    one = mmstab.robot_force_angle(robot, g[0], com)
    assert isinstance(one.mu, float) and one.mu == many.mu[0]
    np.testing.assert_array_equal(one.angles, many.angles[0])
    q = robot.stowed + 0.2
    new = mmstab.stance(robot, ramp, [0.0, 0.0, 0.3], arm=q)
    old = mmstab.stance(ramp, robot, [0.0, 0.0, 0.3], None, q)
    assert new.mu == old.mu and new.roll == old.roll
    # on a plane the rest is the ramp's: the one μ is the force-angle of that posture
    assert new.mu == pytest.approx(mmstab.robot_force_angle(robot, g[0], robot.arm_com(q)).mu)
    with pytest.raises(ValueError, match=r"arm must have shape \(4,\)"):
        mmstab.stance(robot, ramp, [0.0, 0.0, 0.0], arm=[0.0, 0.0])
