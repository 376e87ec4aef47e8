"""planner.attitude_margin: the arm clears the ground through the body's tilts (pitch, roll).

A point's least height over the tilts up to θ about B's origin is ``z cos θ − ρ sin θ``
(mmstab.model.plane_clearance.tilted_height); checked by hand, against rotated points, on a plane
(a posture that clears without the margin fails with it by the amount computed by hand)
and by plans beside a kerb and on bumps whose postures clear the ground densely at every
sampled tilt.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_under_arm import GROUND, TOL, _map, _poses, _settings, dense_heights

from mmstab.core.problem import load_problem
from mmstab.model.plane_clearance import tilted_height
from mmstab.planner.ground.under_arm import GroundUnderArm, arm_pieces
from mmstab.planner.searches.roadmap import solve_roadmap_sequence
from mmstab.stability.static import mu_max
from mmstab.workspace import build_workspace
from mmstab.workspace.roadmap import build_roadmap

#: 3 degrees [rad]: the kerb's measured rocking is 2.6 degrees (docs/physics.md).
THETA = np.deg2rad(3.0)
#: The arm reaching forward, low: the kerb plan's posture at 2.71 m without the margin [rad].
REACH_Q = np.array([0.262, -0.3, 0.242, 0.0])


@pytest.fixture(scope="module")
def small(robot):
    return build_roadmap(robot, build_workspace(robot, (10, 8, 8, 8), progress=False))


def _tilt(axis_angle: float, theta: float) -> np.ndarray:
    """Rotation (4, 4) by theta [rad] about the horizontal axis at axis_angle [rad] from x."""
    u = np.array([np.cos(axis_angle), np.sin(axis_angle), 0.0])
    K = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    T = np.eye(4)
    T[:3, :3] = np.eye(3) + np.sin(theta) * K + (1 - np.cos(theta)) * K @ K
    return T


def _piece_points_B(robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every piece point of posture q (4,) in B (P*8, 3) [m] and its radius (P*8,) [m]."""
    pieces = arm_pieces(robot)
    frames = robot.kinematics.link_frames(q[None])[0]
    R, t = frames[pieces.link, :3, :3], frames[pieces.link, :3, 3]
    p = np.einsum("pij,pkj->pki", R, pieces.points) + t[:, None]
    return p.reshape(-1, 3), np.repeat(pieces.radius, pieces.points.shape[1])


def test_a_points_least_height_by_hand_and_by_rotating_it():
    p = np.array([[1.3, 0.0, 0.07], [0.0, 0.0, 0.2], [0.3, 0.4, 0.1], [1.0, 0.0, -0.01]])
    h = tilted_height(p, THETA)
    c, s = np.cos(THETA), np.sin(THETA)
    # 1.3 m ahead, 7 cm up (the kerb's wrist at rest): 0.07 cos 3° − 1.3 sin 3° = 1.9 mm
    np.testing.assert_allclose(h[:3], [0.07 * c - 1.3 * s, 0.2 * c, 0.1 * c - 0.5 * s])
    assert h[0] == pytest.approx(0.00186, abs=1e-5)
    assert h[3] < -0.01  # below the plane: no higher than it is
    np.testing.assert_array_equal(tilted_height(p, 0.0), p[:, 2])
    # the rotations about 720 horizontal axes by θ: their least z is the formula's
    rotated = [p[:3] @ _tilt(a, THETA)[:3, :3].T for a in np.linspace(0, 2 * np.pi, 720)]
    lowest = np.min([r[:, 2] for r in rotated], axis=0)
    assert np.all(lowest >= h[:3] - 1e-12)
    np.testing.assert_allclose(lowest, h[:3], atol=1e-5)


def test_on_a_plane_a_clear_posture_fails_with_the_margin_by_the_amount_by_hand(robot):
    terrain = _map(robot, "flat")
    poses = _poses(1)
    off, on = (
        GroundUnderArm(robot, terrain, poses),
        GroundUnderArm(robot, terrain, poses, margin=THETA),
    )
    assert off.poses[0].cos_tilt == pytest.approx(1.0)
    h0, h1 = off.heights(0, REACH_Q)[0], on.heights(0, REACH_Q)[0]
    p, r = _piece_points_B(robot, REACH_Q)
    rho = np.hypot(p[:, 0], p[:, 1])
    np.testing.assert_allclose(h0, (p[:, 2] - r).min(), atol=1e-12)
    by_hand = (p[:, 2] * np.cos(THETA) - rho * np.sin(THETA) - r).min()
    np.testing.assert_allclose(h1, by_hand, atol=1e-12)
    low = np.argmin(p[:, 2] * np.cos(THETA) - rho * np.sin(THETA) - r)
    assert rho[low] > 1.0 and h0 - h1 > rho[low] * np.sin(THETA) - 1e-12  # reaching ~1.3 m
    assert on.clear(0, REACH_Q[None], h1)[0] and not on.clear(0, REACH_Q[None], h0)[0]
    assert off.clear(0, REACH_Q[None], h0)[0]  # passes at its own height without the margin
    # the bound that skips the close look (the pieces' least z_B over the tilts): on a
    # plane it is the height itself, so it holds at h1 and not 1 cm lower
    sure = on.surely_clear(0, np.array([h1, h1 - 0.01]), h1)
    assert sure[0] and not sure[1]


@pytest.mark.parametrize("kind", ["kerb", "slope-bumps"])
def test_a_plan_clears_the_ground_through_the_tilts(robot, small, kind):
    # seed 0: without the margin a 3° tilt brings the arm to 1.4 cm (beside the kerb) and
    # 2.6 cm (bumps on a side slope) of the ground, with it 7.9 and 17.0 cm
    terrain = _map(robot, kind, 0)
    poses = _poses(6)
    g = terrain.gravity_body(poses)
    s = _settings(GROUND)
    base = GroundUnderArm(robot, terrain, poses)
    under = GroundUnderArm(robot, terrain, poses, margin=THETA)
    off = solve_roadmap_sequence(robot, g, small, s, mu_max(robot), False, poses, under=base)
    on = solve_roadmap_sequence(robot, g, small, s, mu_max(robot), False, poses, under=under)
    default = GroundUnderArm(robot, terrain, poses, margin=0.0)
    same = solve_roadmap_sequence(robot, g, small, s, mu_max(robot), False, poses, under=default)
    np.testing.assert_array_equal(same.nodes, off.nodes)  # margin 0: today's plan

    def tilted_low(plan) -> float:
        lows = []
        for k in range(len(poses)):
            T = under.poses[k].M_T_B
            for a in np.linspace(0, 2 * np.pi, 16, endpoint=False):
                lows.append(dense_heights(robot, terrain, T @ _tilt(a, THETA), plan.postures[k])[0])
        return min(lows)

    assert tilted_low(off) < GROUND - 0.02  # without the margin a tilt brings the arm down
    assert tilted_low(on) >= GROUND - TOL
    assert on.total <= off.total + 1e-9  # the margin only removes candidates


def test_the_margin_is_off_by_default_and_checked(tmp_path, capsys):
    from conftest import RAMP_YAML, assert_bad_planner_key

    from mmstab.planner import PlannerSettings

    assert (
        PlannerSettings.from_section(load_problem(RAMP_YAML).section("planner")).attitude_margin
        is None
    )
    assert_bad_planner_key(tmp_path, capsys, "attitude_margin", -0.1)
