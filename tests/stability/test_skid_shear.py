"""The skid-steer model's Wong-Chiang shear (mmstab.stability.skid, shear_modulus K)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from mmstab.stability.skid import (
    _forces,
    belts_for_twist,
    contact_time,
    normal_loads,
    skid_twist,
    track_patch,
    turn_slide,
)

MU, K = 0.7, 0.01
LEVEL = [[0.0, 0.0, -9.81]] * 3


def side_slope(alpha: float, heading: float = 0.0) -> np.ndarray:
    """Gravity in B on a plane of slope ``alpha`` [rad] rising along +y, body yawed by heading."""
    g = 9.81 * np.array([0.0, -np.sin(alpha), -np.cos(alpha)])
    c, s = np.cos(heading), np.sin(heading)
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]]) @ g


@pytest.fixture(scope="module")
def patch(robot):
    return track_patch(robot)


def test_nose_up_a_ramp_the_belts_slip_as_wong_chiang_integrates(patch):
    """Uniform pressure, gravity along -x: the belts' mean mobilised shear holds m g sin α.

    An element at distance ξ behind the front has slipped s ξ / u, so the mean of
    1 - exp(-s ξ / (u K)) over the length L is 1 - (u K / (s L)) (1 - exp(-s L / (u K))),
    and that equals tan α / μ: solved for the slip s by brentq, the body runs at u - s.
    """
    L, u = patch.length, 0.25
    for deg, k in ((5.0, 0.005), (15.0, 0.03), (30.0, 0.01)):
        a = np.radians(deg)

        def mobilised(s, a=a, k=k):
            return 1 - (u * k / (s * L)) * (1 - np.exp(-s * L / (u * k))) - np.tan(a) / MU

        s = brentq(mobilised, 1e-12, 10.0)
        g = [-9.81 * np.sin(a), 0.0, -9.81 * np.cos(a)]
        tw = skid_twist(patch, g, [0, 0, 0], (u, u), MU, k)
        assert tw.velocity_body[0] == pytest.approx([u - s, 0.0], abs=2e-3 * s + 1e-6)
        assert tw.yaw_rate[0] == pytest.approx(0.0, abs=1e-9)


def test_a_vanishing_modulus_is_coulomb_and_a_standing_belt_holds_forever(patch, rng):
    for _ in range(5):
        g = side_slope(rng.uniform(0, 0.5), rng.uniform(-np.pi, np.pi))
        u = rng.uniform(-0.3, 0.3, 2)
        a = skid_twist(patch, g, [0.02, 0.0, 0.15], u, MU)
        b = skid_twist(patch, g, [0.02, 0.0, 0.15], u, MU, 1e-7)
        assert np.r_[b.velocity_body[0], b.yaw_rate] == pytest.approx(
            np.r_[a.velocity_body[0], a.yaw_rate], abs=1e-3
        )
    tau = contact_time(patch, np.array([[0.0, 0.2]]))
    assert np.isinf(tau[0, patch.side == 0]).all()
    assert tau[0, patch.side == 1] == pytest.approx((patch.length / 2 - patch.x[:40]) / 0.2)


def test_driving_straight_inside_the_cone_creeps_downhill_more_with_k(patch):
    """Coulomb holds a straight run on a side slope; the shear lets it creep, more with K."""
    com = [0.0, 0.0, 0.15]
    creep = []
    for k in (0.0, 0.005, 0.02):
        tw = skid_twist(patch, side_slope(np.radians(20)), com, (0.25, 0.25), MU, k)
        creep.append(-tw.velocity_body[0, 1])  # downhill is -y
    assert creep[0] == pytest.approx(0.0, abs=1e-4)  # the regularisation ε only
    assert 0 < creep[1] < creep[2] < 0.05
    faster = skid_twist(patch, side_slope(np.radians(20)), com, (0.5, 0.5), MU, 0.02)
    assert -faster.velocity_body[0, 1] == pytest.approx(2 * creep[2], rel=1e-3)  # homogeneous


def test_the_shear_slides_no_less_than_coulomb_in_turns(patch):
    """Less friction mobilised at every contact for the same slip: the turns slide more."""
    com = [0.02, 0.0, 0.16]
    # the slide is measured at the CoM's foot: B's velocity plus the yaw about it
    for deg in (5.0, 12.0, 20.0, 28.0):
        for heading in np.radians([0.0, 45.0, 135.0, 180.0, 270.0]):
            g = [side_slope(np.radians(deg), heading)] * 3
            v, w = [0.0, 0.2, 0.25], [0.8, 0.5, -0.3]
            new = turn_slide(patch, g, com, v, w, MU, shear_modulus=K)
            # the former model: Coulomb, the slope's twist less the level one, over the yaw
            belts = belts_for_twist(v, w, patch.separation)
            a, b = skid_twist(patch, g, com, belts, MU), skid_twist(patch, LEVEL, com, belts, MU)
            down = g[0][:2] / np.linalg.norm(g[0][:2])
            dw = (a.yaw_rate - b.yaw_rate)[:, None]
            dv = a.velocity_body - b.velocity_body + dw * [-com[1], com[0]]
            slide = np.maximum(dv @ down, 0.0)
            old = slide / np.maximum(np.abs(a.yaw_rate), 0.5 * np.abs(w)) * np.abs(w)
            assert np.all(new.rate >= old - 1e-4), (deg, heading, old, new.rate)
            assert np.all(new.rate > 0)


def test_left_and_right_turns_mirror(patch):
    """Mirroring y (gravity, CoM) and the turn's sign mirrors the twist and the slide."""
    for deg in (8.0, 20.0):
        g = side_slope(np.radians(deg), 0.6)
        com = np.array([0.03, 0.0, 0.16])
        a = turn_slide(patch, [g], com, [0.2], [0.4], MU, shear_modulus=K)
        b = turn_slide(patch, [g * [1, -1, 1]], com * [1, -1, 1], [0.2], [-0.4], MU,
                       shear_modulus=K)  # fmt: skip
        assert b.rate == pytest.approx(a.rate, rel=1e-6, abs=1e-9)
        assert b.turn_ratio == pytest.approx(a.turn_ratio, rel=1e-6)


def test_the_shear_jacobian_is_the_balance_s_derivative(patch, rng):
    loads = normal_loads(patch, [side_slope(0.3, 0.7)], [0.05, 0.02, 0.16])
    for _ in range(10):
        z = rng.uniform(-1, 1, (1, 3))
        u = rng.uniform(-1, 1, (1, 2))
        tau = contact_time(patch, u)
        _, J = _forces(patch, loads, u, z, 1e-2, tau, 0.03)
        h = 1e-6
        fd = np.stack(
            [(_forces(patch, loads, u, z + h * e, 1e-2, tau, 0.03)[0]
              - _forces(patch, loads, u, z - h * e, 1e-2, tau, 0.03)[0])[0] / (2 * h)
             for e in np.eye(3)], axis=1)  # fmt: skip
        assert J[0] == pytest.approx(fd, abs=1e-5)
