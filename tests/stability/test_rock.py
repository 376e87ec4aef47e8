"""A push across a support edge: the base rocks onto the next support, or tips.

On a saddle ``z = c x y`` the tracks' corners (±a, ±b) lie at ``±c a b``: the rigid base
rests on the two high corners (a diagonal) and leans onto a low one. Turned about the
diagonal the opposite low corner, at ``d = 2ab / hypot(a, b)`` from it, meets the ground
after ``2 atan(2 c a b / d)`` (the base's plane turns from one saddle triangle to the
mirrored one; the corner's (x, y) is the same at both ends). On flat ground the support is
the tracks' rectangle: nothing is beyond its edges, so a push across one tips the base.
"""

from __future__ import annotations

import numpy as np
import pytest

from mmstab.stability.rock import (
    BEYOND,
    MAX_ROCK,
    STEP,
    axis_rotation,
    catch,
    energy_margin,
    rested_support,
    rested_supports,
    rock,
    rock_over,
)
from mmstab.stability.static import axis_angles
from mmstab.terrain import HeightmapTerrain
from mmstab.terrain.base import GRAVITY_G
from mmstab.terrain.generators import generate
from mmstab.terrain.heightmap import Heightmap
from mmstab.terrain.polygon import support_vertices
from mmstab.terrain.rest import RestSettings

C, A, B = 0.2, 0.35, 0.26  # the saddle's curvature [1/m]; the bottom runs' corners [m]
PUSH = 0.3 / 9.81  # 0.3 m/s^2: the routes' acceleration


def ground(elevation, robot, compliance: float = 0.0) -> HeightmapTerrain:
    res = 0.01
    x = np.arange(-1.5, 1.5 + 1e-9, res)
    X, Y = np.meshgrid(x, x)
    hm = Heightmap.build(elevation(X, Y), res, [x[0], x[0]], "test")
    return HeightmapTerrain(hm, settings=RestSettings(compliance=compliance)).with_robot(robot)


def arm_for(robot, y_overall: float) -> np.ndarray:
    """An arm CoM in B [m] that puts the overall CoM at ``y_overall`` [m] (x, z as stowed)."""
    arm = np.array(robot.arm_com(robot.stowed), dtype=float)
    m_arm = robot.total_mass - robot.base.mass
    arm[1] = (robot.total_mass * y_overall - robot.base.mass * robot.base.com[1]) / m_arm
    return arm


def support(terrain, com_B):
    r = terrain.rest(np.zeros(3), com_body=com_B)
    T = r.G_T_B[0]
    poly, line = support_vertices(r.bearing_G(terrain.candidates.points, 0), GRAVITY_G)
    assert r.converged[0] and not line
    com_G = T[:3, :3] @ com_B + T[:3, 3]
    return T, poly, com_G, np.asarray(axis_angles(poly, com_G, GRAVITY_G))


def test_the_energy_stability_margin_by_hand():
    # a 0.6 x 0.4 m rectangle on level ground, the CoM 0.2 m up: edge j rises by
    # hypot(r_j, 0.2) - 0.2 turned until the CoM is above it (r_j its horizontal distance)
    poly = np.array([[-0.3, -0.2, 0.0], [0.3, -0.2, 0.0], [0.3, 0.2, 0.0], [-0.3, 0.2, 0.0]])
    assert energy_margin(poly, [0.0, 0.0, 0.2]) == pytest.approx(np.hypot(0.2, 0.2) - 0.2)
    # the CoM 0.1 m from the side y = -0.2: that side binds, unless the base rocked over it
    com = np.array([0.0, -0.1, 0.2])
    assert energy_margin(poly, com) == pytest.approx(np.hypot(0.1, 0.2) - 0.2, rel=1e-12)
    others = np.hypot(0.3, 0.2) - 0.2  # the far side and both ends: 0.3 m away
    assert energy_margin(poly, com, poly[[0, 1]]) == pytest.approx(others, rel=1e-12)
    assert energy_margin(poly, com, poly[[1, 0]]) == pytest.approx(others, rel=1e-12)
    # a CoM outside an edge: no energy holds it
    assert energy_margin(poly, [0.0, 0.25, 0.2]) == 0.0


def test_a_diagonal_on_a_saddle_rocks_onto_the_mirrored_corner(robot):
    terrain = ground(lambda x, y: C * x * y, robot)
    arm = arm_for(robot, 0.03)
    com_B = robot.overall_com(arm)
    T, poly, com_G, theta = support(terrain, com_B)
    j = int(np.argmin(theta))
    p0, p1 = poly[j], poly[(j + 1) % len(poly)]
    # the weak edge is the high diagonal: its ends at +c a b, front-left and rear-right
    ends_B = (np.array([p0, p1]) - T[:3, 3]) @ T[:3, :3]
    assert sorted(np.sign(ends_B[:, 0] * ends_B[:, 1])) == [1.0, 1.0]
    assert np.abs(np.abs(ends_B[:, 0]) - A).max() < 0.02 and np.abs(ends_B[:, 1]).min() > 0.2
    outward = np.cross(p1 - p0, [0.0, 0.0, 1.0]) / np.linalg.norm(p1 - p0)
    rocked = rock(terrain, T, com_G, 0.3 * outward, p0, p1)  # 0.3 g: the CoM ~5 cm across
    assert rocked is not None
    shift = rocked.shift
    assert np.linalg.norm(shift) == pytest.approx(0.3 * (com_G[2] - (p0[2] + p1[2]) / 2))
    want = 2 * np.arctan(2 * C * A * B / (2 * A * B / np.hypot(A, B)))  # 9.97 deg
    assert rocked.angle == pytest.approx(want, abs=np.radians(0.5))
    # the first catch is the track's end just beyond the edge's ends (a strip 8 mm wide):
    # pushed 5 cm across, the base turns on to the corner
    first = catch(terrain, T, p0, p1)
    assert first is not None and first.angle < rocked.angle
    # the rest solver, the CoM pushed across the diagonal, finds the same attitude
    R = terrain.rest(np.zeros(3), com_body=com_B + T[:3, :3].T @ shift).G_T_B[0, :3, :3]
    turn = np.arccos(np.clip((np.trace(T[:3, :3].T @ R) - 1) / 2, -1, 1))
    assert turn == pytest.approx(rocked.angle, abs=2 * STEP)
    # the pushed CoM on the caught support; the CoM passed over the diagonal: about as high
    assert np.min(axis_angles(rocked.poly, rocked.com_G + shift, GRAVITY_G)) > 0
    assert abs(rocked.com_G[2] - com_G[2]) < 0.002


def test_a_balanced_diagonal_holds_the_push_a_track_edge_does_not(robot):
    weight = robot.total_mass * float(np.linalg.norm(GRAVITY_G))
    saddle = ground(lambda x, y: C * x * y, robot)
    # the overall CoM moved across the diagonal: μ is least where the rest changes sides
    # (34 N rad: the tracks' ends beside the corners make the diagonal a strip 8 mm wide)
    ys = np.arange(0.030, 0.046, 0.002)
    mus = [support(saddle, robot.overall_com(arm_for(robot, y)))[3].min() * weight for y in ys]
    arm = arm_for(robot, ys[int(np.argmin(mus))])
    mu, threshold = min(mus), 60.0
    assert 0 < mu < threshold
    # at 0.3 m/s^2 the pushed CoM stays inside (μ about the diagonal 16 N rad): no turn;
    # at 1 m/s^2 (0.1 g) it crosses, and the base turns onto a support that holds it
    r = rock_over(robot, saddle, np.zeros((1, 3)), arm[None], PUSH, threshold, 0.0)
    assert r.holds[0] and r.pushed[0] == 1 and r.rock[0] == 0 and 0 < r.mu[0] < mu - 10
    r = rock_over(robot, saddle, np.zeros((1, 3)), arm[None], 0.1, threshold, 0.0)
    assert r.holds[0] and r.pushed[0] == 1
    assert r.mu[0] > 0 and 0 < r.rock[0] <= np.radians(10.5)  # at most to the far corner
    assert r.drop[0] < r.barrier[0]  # the rock's work cannot carry it over
    # the margin is asked of the caught support: above its μ, the push tips
    assert not rock_over(
        robot, saddle, np.zeros((1, 3)), arm[None], PUSH, threshold, r.mu[0]
    ).holds[0]
    # a push that does not move the CoM across the edge turns nothing: with a margin of
    # 250 N rad the edge's own pushed μ binds (about 1.7 deg, 17 N rad, below the rest's)
    arm_in = arm_for(robot, 0.030)
    mu_in = float(support(saddle, robot.overall_com(arm_in))[3].min() * weight)
    r = rock_over(robot, saddle, np.zeros((1, 3)), arm_in[None], PUSH, 300.0, 250.0)
    assert not r.holds[0] and r.rock[0] == 0 and 0 < r.mu[0] < mu_in - 10
    # flat ground, the CoM 5 mm inside the right track's outer edge: nothing beyond it
    flat = ground(lambda x, y: 0.0 * x, robot, compliance=0.02)
    arm = arm_for(robot, -B + 0.005)
    theta = support(flat, robot.overall_com(arm))[3]
    assert 0 < theta.min() * weight < threshold
    r = rock_over(robot, flat, np.zeros((1, 3)), arm[None], PUSH, threshold, 0.0)
    assert not r.holds[0] and r.mu[0] == -np.inf
    # far from the edge nothing is pushed: it holds as μ says
    r = rock_over(robot, flat, np.zeros((1, 3)), arm_for(robot, 0.0)[None], PUSH, threshold, 0.0)
    assert r.holds[0] and r.pushed[0] == 0 and np.isnan(r.mu[0])


def _first_turn(terrain, T, p0, p1):
    """The turn that meets the ground, every step of it tried at once (no early stop)."""
    axis = (p1 - p0) / np.linalg.norm(p1 - p0)
    outward = np.cross(axis, [0.0, 0.0, 1.0])
    X = terrain.candidates.points @ T[:3, :3].T + T[:3, 3]
    rel = X[(X - p0) @ (outward / np.linalg.norm(outward)) > BEYOND] - p0
    if not len(rel):
        return None
    angles = np.arange(1, int(np.ceil(MAX_ROCK / STEP)) + 1) * STEP
    Rs = np.stack([axis_rotation(axis, float(x)) for x in angles])
    Y = np.einsum("aij,kj->aki", Rs, rel) + p0
    gap = Y[..., 2] - terrain.heightmap.sample(Y[..., :2]).height
    met = np.flatnonzero((np.nan_to_num(gap, nan=np.inf) <= 0).any(axis=1))
    return None if not met.size else float(angles[met[0]])


@pytest.mark.parametrize("seed", [42])
def test_the_batched_rests_and_the_stepped_turns_are_the_one_at_a_time_ones(seed, robot):
    """On user-like ground (bumps, a ditch, a kerb): the states' rests solved in one batch
    are each state's own rest, bit for bit, and a turn about each support edge, tried a few
    steps at a time up to the first that meets the ground, is the turn every step gives."""
    from tests.stability.test_one_mu import user_ground

    rng = np.random.default_rng(seed)
    terrain = HeightmapTerrain(generate(user_ground(rng))).with_robot(robot)
    n = 24
    poses = np.c_[rng.uniform(-1.5, 1.5, (n, 2)), rng.uniform(-np.pi, np.pi, n)]
    q = rng.uniform(robot.joint_lower, robot.joint_upper, (n, robot.arm_joints))
    com_B = np.asarray(robot.overall_com(robot.arm_com(q)), dtype=float)
    batch = rested_supports(terrain, poses, com_B)
    turns = 0
    for i in range(n):
        single = rested_support(terrain, poses[i], com_B[i])
        assert (single is None) == (batch[i] is None)
        if single is None:
            continue
        for a, b in zip(single, batch[i], strict=True):
            np.testing.assert_array_equal(a, b)
        poly = single.poly
        for j in range(len(poly)):
            p0, p1 = poly[j], poly[(j + 1) % len(poly)]
            caught, want = catch(terrain, single.T, p0, p1), _first_turn(terrain, single.T, p0, p1)
            if want is None:  # nothing beyond the edge meets the ground: no catch
                assert caught is None
            elif caught is not None:  # (None: it is caught on a line, no support)
                assert caught.angle == want
                turns += 1
    assert turns > 2 * n  # most edges turn onto a support
