"""Dynamic force-angle measure: hand-computed cases, the static limit, invariances."""

from __future__ import annotations

import numpy as np
import pytest

from mmstab.stability.dynamic import dynamic_force_angle, net_wrench
from mmstab.stability.static import force_angle_batch, support_polygon
from mmstab.terrain import rot_x, rot_z

G = np.array([0.0, 0.0, -9.81])
# 1.0 x 0.6 m rectangle, counter-clockwise about +z; the CoM 0.5 m above its centre
RECT = np.array([[0.5, -0.3, 0.0], [0.5, 0.3, 0.0], [-0.5, 0.3, 0.0], [-0.5, -0.3, 0.0]])
COM = np.array([0.0, 0.0, 0.5])


def test_point_mass_accelerating_forward_by_hand():
    m, a = 20.0, 3.0
    w = net_wrench([m], [COM], [[a, 0.0, 0.0]], G)
    np.testing.assert_allclose(w.force, m * np.array([-a, 0.0, -9.81]))
    np.testing.assert_allclose(w.moment, 0.0, atol=1e-12)  # a point mass: no moment about itself
    fa = dynamic_force_angle(RECT, w.com, w.force, w.moment)
    # by hand: the rear axis; l points 45 deg below horizontal, f_r leans back by atan(a/g)
    theta_rear = np.pi / 4 - np.arctan(a / 9.81)
    theta_front = np.pi / 4 + np.arctan(a / 9.81)
    theta_side = np.arctan(0.3 / 0.5)  # f_r has no y part: the sides see plain gravity
    # axes in order: front (v0->v1), left (v1->v2), rear (v2->v3), right (v3->v0)
    np.testing.assert_allclose(
        fa.angles[0], [theta_front, theta_side, theta_rear, theta_side], atol=1e-12
    )
    np.testing.assert_allclose(fa.mu[0], theta_rear * m * np.hypot(a, 9.81), rtol=1e-12)


def test_braking_hard_enough_tips_forward():
    m = 20.0
    a_tip = -9.81 * 0.5 / 0.5  # deceleration at which f_r points at the front edge
    for a, sign in ((a_tip * 0.9, 1.0), (a_tip * 1.1, -1.0)):
        w = net_wrench([m], [COM], [[a, 0.0, 0.0]], G)
        mu = dynamic_force_angle(RECT, w.com, w.force, w.moment).mu[0]
        assert np.sign(mu) == sign


def test_pure_moment_about_rear_axis_by_hand():
    m, M = 20.0, 15.0
    # the rear axis runs from (-0.5, 0.3) to (-0.5, -0.3): direction -y; a positive moment
    # about it tips the robot backwards over that edge
    n = M * np.array([0.0, -1.0, 0.0])
    fa = dynamic_force_angle(RECT, COM, m * G, n)
    l_vec = np.array([-0.5, 0.0, -0.5])  # from the CoM to the rear axis, normal to it
    couple = M / np.linalg.norm(l_vec) * np.array([-1.0, 0.0, 1.0]) / np.sqrt(2)
    f_star = m * G + couple
    theta = np.arccos(l_vec @ f_star / np.linalg.norm(l_vec) / np.linalg.norm(f_star))
    np.testing.assert_allclose(fa.angles[0, 2], theta, rtol=1e-12)
    # the couple's moment about the axis is M: r x F with r from the axis to the CoM
    np.testing.assert_allclose(np.cross(-l_vec, couple) @ np.array([0, -1.0, 0]), M)
    # the same moment lowers the rear angle and leaves the side axes as they were
    static = force_angle_batch(RECT, COM[None], m * G[None])
    assert fa.angles[0, 2] < static.angles[0, 2]
    np.testing.assert_allclose(fa.angles[0, [1, 3]], static.angles[0, [1, 3]], atol=1e-12)


def test_zero_acceleration_is_the_static_measure_exactly(rng):
    masses = rng.uniform(1, 10, 5)
    positions = rng.uniform([-0.3, -0.2, 0.1], [0.3, 0.2, 0.8], (5, 3))
    w = net_wrench(masses, positions, np.zeros((5, 3)), G)
    np.testing.assert_allclose(w.moment, 0.0, atol=1e-12)  # gravity has no moment about g_o
    poly = support_polygon(RECT + rng.normal(0, 0.02, RECT.shape), w.com, w.force)
    dyn = dynamic_force_angle(poly.vertices, w.com, w.force, np.zeros(3))
    sta = force_angle_batch(poly.vertices, w.com[None], w.force[None])
    np.testing.assert_array_equal(dyn.mu, sta.mu)
    np.testing.assert_array_equal(dyn.angles, sta.angles)


def test_two_masses_moment_by_hand():
    # two 1 kg masses 1 m apart along y, accelerating opposite ways along x (a spin)
    w = net_wrench([1.0, 1.0], [[0, 0.5, 0], [0, -0.5, 0]], [[2.0, 0, 0], [-2.0, 0, 0]], G)
    np.testing.assert_allclose(w.force, 2 * G)
    # inertial forces -m a: (-2, 0, 0) at +0.5 y and (+2, 0, 0) at -0.5 y -> moment +2 about z
    np.testing.assert_allclose(w.moment, [0.0, 0.0, 2.0], atol=1e-12)
    w2 = net_wrench(
        [1.0, 1.0],
        [[0, 0.5, 0], [0, -0.5, 0]],
        np.zeros((2, 3)),
        G,
        inertial_moments=[[0, 0, 1.0], [0, 0, 0.5]],
        force_ext=[0.0, 50.0, 0.0],
        point_ext=[1.0, 0.0, 0.0],
        moment_ext=[0.1, 0.0, 0.0],
    )
    np.testing.assert_allclose(w2.force, 2 * G + [0, 50.0, 0])
    np.testing.assert_allclose(w2.moment, [0.1, 0.0, -1.5 + 50.0], atol=1e-12)


def test_rigid_motion_invariance(rng):
    masses = np.array([30.0, 5.0])
    positions = np.array([[0.0, 0.0, 0.2], [0.4, 0.1, 0.6]])
    acc = np.array([[1.0, -0.5, 0.2], [2.0, 1.0, -1.0]])
    w = net_wrench(masses, positions, acc, G, force_ext=[5, 0, 0], point_ext=positions[1])
    ref = dynamic_force_angle(RECT, w.com, w.force, w.moment)
    for _ in range(5):
        R = rot_z(rng.uniform(-3, 3)) @ rot_x(rng.uniform(-1, 1))
        t = rng.normal(size=3)
        w2 = net_wrench(
            masses,
            positions @ R.T + t,
            acc @ R.T,
            R @ G,
            force_ext=R @ [5, 0, 0],
            point_ext=R @ positions[1] + t,
        )
        got = dynamic_force_angle(RECT @ R.T + t, w2.com, w2.force, w2.moment)
        np.testing.assert_allclose(got.mu, ref.mu, rtol=1e-10)


def test_batched_equals_single(rng):
    coms = COM + rng.normal(0, 0.05, (6, 3))
    forces = 20 * G + rng.normal(0, 10, (6, 3))
    moments = rng.normal(0, 5, (6, 3))
    batch = dynamic_force_angle(RECT, coms, forces, moments)
    for k in range(6):
        one = dynamic_force_angle(RECT, coms[k], forces[k], moments[k])
        np.testing.assert_allclose(one.mu, batch.mu[k : k + 1], rtol=1e-13)


def test_bad_inputs():
    with pytest.raises(ValueError, match="differ"):
        net_wrench([1.0, 2.0], [[0, 0, 0]], [[0, 0, 0]], G)
    with pytest.raises(ValueError, match="point_ext"):
        net_wrench([1.0], [[0, 0, 0]], [[0, 0, 0]], G, force_ext=[1, 0, 0])


def test_robot_wrench_zero_is_static_and_pull_through_com_by_hand(robot, rng):
    from mmstab.stability.dynamic import robot_force_angle_wrench
    from mmstab.stability.static import robot_force_angle

    q = rng.uniform(robot.joint_lower, robot.joint_upper, (8, 4))
    g_a = robot.arm_com(q)
    gravity = np.tile(G, (8, 1))
    tool = rng.normal(0, 0.3, (8, 3))
    zero = robot_force_angle_wrench(robot, gravity, g_a, tool, np.zeros(6))
    np.testing.assert_allclose(zero.mu, robot_force_angle(robot, gravity, g_a).mu, rtol=1e-13)
    # a pull acting at the overall CoM has no moment: the measure of the static form with
    # f_r = m g + F, by hand from the polygon
    g_o = robot.overall_com(g_a)
    pull = np.array([0.0, 60.0, 0.0])
    got = robot_force_angle_wrench(robot, gravity, g_a, g_o, np.r_[pull, 0, 0, 0])
    ref = force_angle_batch(base_polygon_vertices(robot), g_o, robot.total_mass * G + pull)
    np.testing.assert_allclose(got.mu, ref.mu, rtol=1e-12)
    # pulling to the left (+y) tips toward the left edge: the left axis angle drops and the
    # right one grows
    v = base_polygon_vertices(robot)
    mid_y = (v[:, 1] + np.roll(v, -1, axis=0)[:, 1]) / 2
    left, right = np.argmax(mid_y), np.argmin(mid_y)
    assert np.all(got.angles[:, left] < zero.angles[:, left])
    assert np.all(got.angles[:, right] > zero.angles[:, right])
    with pytest.raises(ValueError, match="wrench"):
        robot_force_angle_wrench(robot, G, g_a[0], tool[0], np.zeros(5))


def base_polygon_vertices(robot):
    from mmstab.stability.static import base_polygon

    return base_polygon(robot).vertices


def test_batched_net_wrench_equals_one_instant_at_a_time() -> None:
    rng = np.random.default_rng(17)
    masses = rng.uniform(0.5, 20.0, 5)
    positions = rng.normal(size=(7, 5, 3))
    accelerations = rng.normal(scale=3.0, size=(7, 5, 3))
    gravity = rng.normal(size=(7, 3)) + [0.0, 0.0, -9.81]
    inertial = rng.normal(size=(7, 5, 3))
    f_ext, point, n_ext = rng.normal(size=3), rng.normal(size=(7, 3)), rng.normal(size=3)
    batch = net_wrench(masses, positions, accelerations, gravity, inertial, f_ext, point, n_ext)
    for i in range(7):
        one = net_wrench(masses, positions[i], accelerations[i], gravity[i], inertial[i],
                         f_ext, point[i], n_ext)  # fmt: skip
        for a, b in zip(batch, one, strict=True):
            assert a[i] == pytest.approx(b, abs=1e-12)
    with pytest.raises(ValueError, match="differ"):
        net_wrench(masses, positions, accelerations[:, :4], gravity)
