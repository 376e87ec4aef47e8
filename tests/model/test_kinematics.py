"""Arm kinematics: CasADi vs NumPy, Jacobians vs finite differences, hand-computed CoM."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from conftest import ROOT, random_postures

from mmstab.model.kinematics import FEW_POSTURES, dh_np
from mmstab.model.robot import load_robot
from mmstab.terrain import BasePose, Ramp, roll_pitch, rot_z


def test_casadi_and_numpy_link_frames_agree(robot, rng):
    q = random_postures(robot, rng, 50)
    frames_np = robot.kinematics.link_frames(q)
    for n in range(len(q)):
        frames_ca = robot.kinematics.f_link_frames(q[n])
        for i in range(4):
            np.testing.assert_allclose(np.asarray(frames_ca[i]), frames_np[n, i], atol=1e-12)
    np.testing.assert_allclose(
        robot.arm_com(q),
        np.stack([np.asarray(robot.kinematics.f_arm_com(qi)).ravel() for qi in q]),
        atol=1e-12,
    )


def test_arm_com_jacobian_matches_finite_differences(robot, rng):
    h = 1e-6
    for q in random_postures(robot, rng, 25):
        J = robot.kinematics.arm_com_jacobian(q)
        J_fd = np.stack(
            [(robot.arm_com(q + h * e) - robot.arm_com(q - h * e)) / (2 * h) for e in np.eye(4)],
            axis=1,
        )
        np.testing.assert_allclose(J, J_fd, atol=1e-8)


def test_arm_com_stretched_by_hand(robot):
    """All joints zero: links lie along x_B at the shoulder height; CoM from the DH table."""
    mount = robot.mount_T[:3, 3]
    turret, l1, l2, l3 = robot.links
    shoulder = mount + [0.0, 0.0, turret.d]
    # link frames R1..R3 share R0's orientation: x_R = x_B, y_R = z_B, z_R = -y_B
    to_body = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], dtype=float)
    origins = [
        shoulder,
        shoulder + [l1.a, 0, 0],
        shoulder + [l1.a + l2.a, 0, 0],
        shoulder + [l1.a + l2.a + l3.a, 0, 0],
    ]
    coms = [o + to_body @ link.com for o, link in zip(origins, robot.links, strict=True)]
    expected = sum(link.mass * c for link, c in zip(robot.links, coms, strict=True)) / sum(
        link.mass for link in robot.links
    )
    np.testing.assert_allclose(robot.arm_com(np.zeros(4)), expected, atol=1e-12)
    # and the numbers for the default robot, worked out on paper
    np.testing.assert_allclose(expected, [6.11 / 10.5, -0.12 / 10.5, 3.285 / 10.5], atol=1e-12)


def test_turret_rotates_com_about_the_mount_axis(robot, rng):
    mount = robot.mount_T[:3, 3]
    for q in random_postures(robot, rng, 10):
        delta = rng.uniform(-1, 1)
        q2 = q.copy()
        q2[0] += delta
        expected = rot_z(delta) @ (robot.arm_com(q) - mount) + mount
        np.testing.assert_allclose(robot.arm_com(q2), expected, atol=1e-12)


def test_overall_com_is_mass_weighted(robot):
    g_a = np.array([0.3, -0.2, 0.4])
    g_o = robot.overall_com(g_a)
    np.testing.assert_allclose(
        robot.total_mass * g_o, robot.arm_mass * g_a + robot.base.mass * robot.base.com
    )


def test_ramp_frames(rng):
    ramp = Ramp(0.3)
    for _ in range(10):
        pose = BasePose(*rng.uniform(-2, 2, 2), rng.uniform(-np.pi, np.pi))
        T = ramp.G_T_B(pose)
        np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-12)
        # gravity in B is the global gravity rotated into B
        np.testing.assert_allclose(
            ramp.gravity_body(list(pose))[0], T[:3, :3].T @ [0, 0, -9.81], atol=1e-12
        )
        # symbolic body -> slope map equals the numeric one
        p_body = rng.normal(size=3)
        f = ca.Function("f", [], [ramp.place_sx(ca.DM(list(pose)), ca.DM(p_body))])
        p_S = rot_z(pose.heading) @ p_body + [pose.x, pose.y, 0]
        np.testing.assert_allclose(np.asarray(f()["o0"]).ravel(), p_S, atol=1e-12)
    # +y_S is uphill; heading 0 = pure roll with the left side up
    assert ramp.G_T_B(BasePose(0, 1, 0))[2, 3] > 0
    roll, pitch = roll_pitch(ramp, [0.0, 0.0, 0.0])
    assert np.isclose(roll, 0.3) and np.isclose(pitch, 0.0)
    roll, pitch = roll_pitch(ramp, [0.0, 0.0, np.pi / 2])  # facing uphill: nose up
    assert np.isclose(roll, 0.0, atol=1e-12) and np.isclose(pitch, 0.3)


def test_global_com_functions_match_numpy_and_finite_differences(robot, rng):
    from mmstab.terrain import global_com_functions

    ramp = Ramp(0.25)
    f = global_com_functions(robot, ramp)
    h = 1e-6
    for q in random_postures(robot, rng, 15):
        pose = np.array([*rng.uniform(-2, 2, 2), rng.uniform(-np.pi, np.pi)])
        T = ramp.G_T_B(pose)
        g_a_G = T[:3, :3] @ robot.arm_com(q) + T[:3, 3]
        g_o_G = T[:3, :3] @ robot.overall_com(robot.arm_com(q)) + T[:3, 3]
        np.testing.assert_allclose(f.arm(q, pose), g_a_G, atol=1e-12)
        np.testing.assert_allclose(f.overall(q, pose), g_o_G, atol=1e-12)
        x = np.r_[q, pose]
        for fn, jac in ((f.arm, f.arm_com_jacobian), (f.overall, f.overall_com_jacobian)):
            J_fd = np.stack(
                [
                    (fn(*np.split(x + h * e, [4])) - fn(*np.split(x - h * e, [4]))) / (2 * h)
                    for e in np.eye(7)
                ],
                axis=1,
            )
            np.testing.assert_allclose(np.asarray(jac(q, pose)), J_fd, atol=1e-8)


def test_a_robot_pickles_after_its_kinematics_were_built(robot) -> None:
    """Dask sends robots between processes: the CasADi kinematics stay behind."""
    import copy as copying
    import pickle

    robot = copying.copy(robot)
    q = np.array([[0.3, -0.2, 0.4, 0.1], [1.0, 0.5, -0.5, 0.0]])
    com = robot.arm_com(q)  # builds the CasADi kinematics
    copy = pickle.loads(pickle.dumps(robot))
    assert "kinematics" not in copy.__dict__
    assert np.array_equal(copy.arm_com(q), com)


def _frames_link_by_link(kin, q):
    """The DH chain link after link (dh_np and one batched 4x4 product per link)."""
    T, frames = np.broadcast_to(kin.mount_T, (len(q), 4, 4)), []
    for i, link in enumerate(kin.links):
        T = T @ dh_np(q[:, i] + link.theta_offset, link.a, link.alpha, link.d)
        frames.append(T)
    return np.stack(frames, axis=1)


@pytest.mark.parametrize("name", ["cameleon", "cameleon_6dof"])
def test_link_frames_bit_identical_to_link_by_link(name):
    """Few postures take every link's DH transform at once: the same bits (signed zeros too)
    as the chain link after link, on random, rounded, multiple-of-45° and zero postures,
    at sizes on both sides of FEW_POSTURES."""
    kin = load_robot(ROOT / "problems" / "robots" / f"{name}.yaml").kinematics
    rng = np.random.default_rng(11)
    for n in (1, 3, 8, 17, 333, FEW_POSTURES, FEW_POSTURES + 1, 3000):
        for kind in range(4):
            q = rng.uniform(-3.2, 3.2, (n, len(kin.links)))
            q = [q, np.round(q, 2), np.round(q / (np.pi / 4)) * (np.pi / 4), 0 * q][kind]
            got, want = kin.link_frames(q), _frames_link_by_link(kin, q)
            assert got.shape == (n, len(kin.links), 4, 4)
            assert np.array_equal(got, want) and np.array_equal(np.signbit(got), np.signbit(want))
    q1 = rng.uniform(-3, 3, len(kin.links))
    assert np.array_equal(kin.link_frames(q1), _frames_link_by_link(kin, q1[None])[0])
