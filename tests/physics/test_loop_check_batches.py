"""The closed loop's cheap checks against the per-record code they stand for.

``beyond_no_return`` tests the CoM's vertical against the footprint's ring (``base_polygon``)
instead of a hull per check, and ``simulated_mus`` takes the hulls of all records at once; both must
answer what ``contact_force_angle`` answers record by record.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ROBOT_YAML

pytest.importorskip("mujoco")

from mmstab.model.robot import load_robot, with_flipper_angle  # noqa: E402
from mmstab.physics.loop_checks import beyond_no_return, simulated_mu, simulated_mus  # noqa: E402
from mmstab.stability.static import base_polygon, contact_force_angle  # noqa: E402


def _rotation(rng: np.random.Generator, tilt_max: float) -> np.ndarray:
    """A rotation whose z axis is at most ``tilt_max`` [rad] off G's z, any heading."""
    yaw, azimuth = rng.uniform(-np.pi, np.pi, 2)
    tilt = rng.uniform(0, tilt_max)
    axis = np.array([np.cos(azimuth), np.sin(azimuth), 0.0])
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    tilt_R = np.eye(3) + np.sin(tilt) * K + (1 - np.cos(tilt)) * K @ K
    c, s = np.cos(yaw), np.sin(yaw)
    return tilt_R @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


@pytest.mark.parametrize("flippers", (None, -0.6))
def test_the_ring_test_is_the_footprints_force_angle_sign(flippers):
    robot = load_robot(ROBOT_YAML)
    if flippers is not None:  # flippers down: their corners join the footprint
        robot = with_flipper_angle(robot, flippers)
    support_B = np.asarray(robot.base.support_points(), dtype=float)
    ring_B = base_polygon(robot).vertices
    assert len(ring_B) >= 4
    rng = np.random.default_rng(7)
    over = 0
    for _ in range(2000):
        T = np.eye(4)
        T[:3, :3] = _rotation(rng, np.pi)  # upside down included
        T[:3, 3] = rng.uniform(-1, 1, 3)
        com_B = np.array([rng.uniform(-0.6, 0.6), rng.uniform(-0.4, 0.4), rng.uniform(0, 0.5)])
        com_G = T[:3, :3] @ com_B + T[:3, 3]
        points = support_B @ T[:3, :3].T + T[:3, 3]
        mu = contact_force_angle(points, com_G, np.array([0.0, 0.0, -1.0])).mu
        expected = not mu > 0
        assert beyond_no_return(ring_B, T, com_G) == expected
        over += expected
    assert 200 < over < 1800  # both answers are exercised


def _contact_sets(rng: np.random.Generator, n: int) -> list[np.ndarray]:
    """Contact sets like MuJoCo's: wheels on a tilted patch, with lines, pairs and points."""
    sets = []
    for _ in range(n):
        kind = rng.integers(6)
        k = int(rng.integers(3, 14))
        xy = rng.uniform([-0.5, -0.3], [0.5, 0.3], size=(k, 2))
        if kind == 0:  # one track: a line seen from above
            xy[:, 1] = 0.25
        elif kind == 1:
            xy = xy[: int(rng.integers(0, 3))]  # none, one or two contacts
        elif kind == 2:  # a wheel's contact and its nearest point, 0.1 mm apart
            xy = np.vstack([xy, xy[:1] + 1e-4])
        slope = rng.uniform(-0.4, 0.4, 2)
        z = xy @ slope + rng.normal(0, 0.005, len(xy))
        sets.append(np.c_[xy, z])
    return sets


def test_the_batch_of_records_gives_each_records_mu():
    rng = np.random.default_rng(11)
    sets = _contact_sets(rng, 400)
    coms = np.c_[rng.uniform([-0.3, -0.2], [0.3, 0.2], (400, 2)), rng.uniform(0.1, 0.4, 400)]
    mass = 120.0
    batch = simulated_mus(sets, coms, mass)
    one = np.array([simulated_mu(p, c, mass) for p, c in zip(sets, coms, strict=True)])
    assert np.array_equal(np.isnan(batch), np.isnan(one))
    np.testing.assert_allclose(batch, one, rtol=0, atol=1e-9)
    assert np.isnan(one).sum() > 0 and (one <= 0).sum() > 50 and (one > 0).sum() > 100
    assert simulated_mus([], np.zeros((0, 3)), mass).shape == (0,)
