"""Force-angle invariants: sign, rigid motions, vertex order, linearity, symmetry, backends."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mmstab.stability.static import (
    axis_angles,
    base_polygon,
    force_angle,
    force_angle_batch,
    force_angle_sx,
    mu_max,
    robot_force_angle,
    support_polygon,
)
from mmstab.terrain import Ramp

SQUARE = np.array([[1.0, -1.0, 0], [1.0, 1.0, 0], [-1.0, 1.0, 0], [-1.0, -1.0, 0]])
DOWN = np.array([0.0, 0.0, -100.0])


def test_symmetric_case_equal_margins():
    h = 0.5
    com = np.array([0.0, 0.0, h])
    poly = support_polygon(SQUARE, com, DOWN)
    theta = axis_angles(poly.vertices, com, DOWN)
    np.testing.assert_allclose(theta, np.arctan(1.0 / h))
    assert force_angle(SQUARE, com, DOWN) == pytest.approx(np.arctan(2.0) * 100.0)


def test_sign_flips_when_com_crosses_an_edge():
    inside = force_angle(SQUARE, [0.95, 0.0, 0.5], DOWN)
    on_edge = force_angle(SQUARE, [1.0, 0.0, 0.5], DOWN)
    outside = force_angle(SQUARE, [1.05, 0.0, 0.5], DOWN)
    assert inside > 0 > outside
    assert on_edge == pytest.approx(0.0, abs=1e-9)
    # tilted force: the force line, not the CoM, decides
    assert force_angle(SQUARE, [0.9, 0.0, 0.5], [30.0, 0.0, -100.0]) < 0


def test_invariant_under_rigid_motion_and_vertex_order(rng):
    for _ in range(20):
        com = np.array([*rng.uniform(-0.8, 0.8, 2), rng.uniform(0.2, 1.0)])
        force = np.array([*rng.normal(0, 20, 2), -100.0])
        mu = force_angle(SQUARE, com, force)
        R = Rotation.random(random_state=rng.integers(1 << 31)).as_matrix()
        t = rng.normal(size=3)
        perm = rng.permutation(4)
        mu_moved = force_angle(SQUARE[perm] @ R.T + t, R @ com + t, R @ force)
        assert mu_moved == pytest.approx(mu, abs=1e-9)


def test_linear_in_force_magnitude():
    com = np.array([0.3, -0.2, 0.6])
    f = np.array([10.0, -5.0, -90.0])
    assert force_angle(SQUARE, com, 3.0 * f) == pytest.approx(3.0 * force_angle(SQUARE, com, f))


def test_interior_points_are_ignored_and_degenerate_rejected():
    com = np.array([0.1, 0.2, 0.5])
    with_interior = np.vstack([SQUARE, [[0.2, 0.1, 0.0], [0.0, 0.0, 0.0]]])
    assert force_angle(with_interior, com, DOWN) == pytest.approx(force_angle(SQUARE, com, DOWN))
    with pytest.raises(ValueError, match="collinear"):
        force_angle([[0, 0, 0], [1, 0, 0], [2, 0, 0]], com, DOWN)


def test_batch_and_casadi_match_single(rng):
    poly = support_polygon(SQUARE, [0, 0, 1], DOWN)
    coms = np.column_stack([rng.uniform(-1.2, 1.2, (30, 2)), rng.uniform(0.2, 1, 30)])
    forces = np.column_stack([rng.normal(0, 20, (30, 2)), np.full(30, -100.0)])
    batch = force_angle_batch(poly.vertices, coms, forces)
    com_sx = ca.SX.sym("com", 3)
    f_sx = ca.SX.sym("f", 3)
    fn = ca.Function("mu", [com_sx, f_sx], [force_angle_sx(poly.vertices, com_sx, f_sx)])
    for k in range(30):
        single = force_angle(SQUARE, coms[k], forces[k])
        assert batch.mu[k] == pytest.approx(single, abs=1e-9)
        assert float(fn(coms[k], forces[k])) == pytest.approx(single, abs=1e-9)


def test_robot_on_flat_ground_by_hand(robot):
    t = robot.base.tracks
    half_l, half_w = t.length / 2, t.separation / 2 + t.width / 2
    com = robot.base.com
    expected = (
        min(np.arctan((half_l - abs(com[0])) / com[2]), np.arctan((half_w - abs(com[1])) / com[2]))
        * robot.base.mass
        * 9.81
    )
    flat = np.array([0.0, 0.0, -9.81])
    one = robot_force_angle(robot, flat, None)  # one pose: mu a float
    assert isinstance(one.mu, float) and one.mu == pytest.approx(expected)
    assert robot_force_angle(robot, flat[None], None).mu.shape == (1,)
    assert mu_max(robot) > 0
    assert base_polygon(robot).vertices.shape == (4, 3)  # flippers raised: not in contact


def test_arm_uphill_is_more_stable_than_downhill(robot):
    ramp = Ramp(0.25)
    g = ramp.gravity_body([0.0, 0.0, 0.0])  # heading 0: uphill is +y_B (left)
    q_up, q_down = np.array([np.pi / 2, 0, 0, 0]), np.array([3 * np.pi / 2, 0, 0, 0])
    mu_up = robot_force_angle(robot, g, robot.arm_com(q_up)).mu[0]
    mu_down = robot_force_angle(robot, g, robot.arm_com(q_down)).mu[0]
    assert mu_up > mu_down > 0


def test_touching_flippers_extend_the_polygon():
    from dataclasses import replace

    from mmstab.model.robot import load_robot

    robot = load_robot("problems/robots/cameleon.yaml")
    f = robot.base.flippers
    # the angle at which the bottom far edge of the flipper just reaches the ground
    # z = pivot_z + L sin(b) - (t/2) cos(b) = 0
    b = np.linspace(-1.0, 0.0, 200001)
    z = f.pivot[2] + f.length * np.sin(b) - f.thickness / 2 * np.cos(b)
    angle = float(b[np.argmin(np.abs(z))])
    down = replace(robot, base=replace(robot.base, flippers=replace(f, angle=angle)))
    assert len(down.base.support_points()) == 8  # 4 track corners + 2 flipper edges x 2
    poly = base_polygon(down)
    # the flippers are outboard of the tracks: their tips replace the front track corners
    assert len(poly.vertices) == 4
    assert poly.vertices[:, 0].max() > robot.base.tracks.length / 2 + 0.2
    # pitched nose-down on a ramp, the flippers add margin at the front
    ramp = Ramp(0.4)
    g = ramp.gravity_body([0.0, 0.0, -np.pi / 2])
    com = robot.arm_com(robot.stowed)
    assert robot_force_angle(down, g, com).mu[0] > robot_force_angle(robot, g, com).mu[0]


def test_stability_along_gives_the_three_cases(robot, rng):
    """The trio against robot_force_angle case by case, and the arm-removed case by hand."""
    from mmstab.stability.support import stability_along

    ramp = Ramp(0.2)
    poses = np.column_stack([rng.uniform(-2, 2, (6, 2)), rng.uniform(-np.pi, np.pi, 6)])
    arm = robot.arm_com(rng.uniform(robot.joint_lower, robot.joint_upper, (6, 4)))
    cases = stability_along(robot, ramp, poses, arm)
    g = ramp.gravity_body(poses)
    np.testing.assert_allclose(cases.reconfigured, robot_force_angle(robot, g, arm).mu)
    stowed = np.tile(robot.arm_com(robot.stowed), (6, 1))
    np.testing.assert_allclose(cases.stowed, robot_force_angle(robot, g, stowed).mu)
    pts = robot.base.support_points()
    for k in range(6):  # the base alone: force_angle on the support points, m_base g
        expected = force_angle(pts, robot.base.com, robot.base.mass * g[k])
        assert cases.arm_removed[k] == pytest.approx(expected, abs=1e-9)
