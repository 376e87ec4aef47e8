"""Payload at the wrist: the arm CoM and mass by hand, the cache key, bad input."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_postures

from mmstab.core.files import ConfigError
from mmstab.model.payload import attach_payload, check_payload


def test_arm_com_with_payload_by_hand(robot, rng):
    p = check_payload("p.yaml", "payload", 2.5, [0.05, 0.0, 0.01])
    loaded = attach_payload(robot, p)
    assert loaded.arm_mass == pytest.approx(robot.arm_mass + 2.5)
    assert loaded.total_mass == pytest.approx(robot.total_mass + 2.5)
    q = random_postures(robot, rng, 50)
    frames = robot.kinematics.link_frames(q)  # (N, 4, 4, 4): the DH frames in B
    wrist = frames[:, -1]
    at_wrist = np.einsum("nij,j->ni", wrist[:, :3, :3], p.com_wrist) + wrist[:, :3, 3]
    expected = (robot.arm_mass * robot.arm_com(q) + 2.5 * at_wrist) / (robot.arm_mass + 2.5)
    np.testing.assert_allclose(loaded.arm_com(q), expected, atol=1e-12)
    # the symbolic Jacobian follows: compare with finite differences of the NumPy CoM
    q0, h = q[0], 1e-6
    J = np.asarray(loaded.kinematics.arm_com_jacobian(q0))
    fd = np.stack(
        [(loaded.arm_com(q0 + h * e) - loaded.arm_com(q0 - h * e)) / (2 * h) for e in np.eye(4)],
        axis=1,
    )
    np.testing.assert_allclose(J, fd, atol=1e-7)
    assert loaded.source_hash != robot.source_hash
    assert attach_payload(robot, check_payload("p.yaml", "payload", 0.0, [0, 0, 0])) is robot


@pytest.mark.parametrize(
    ("mass", "com", "field"),
    [
        (-1.0, [0, 0, 0], "payload.mass"),
        (float("nan"), [0, 0, 0], "payload.mass"),
        (1.0, [0, 0], "payload.com"),
        (1.0, [0, 0, float("inf")], "payload.com"),
    ],
)
def test_bad_payloads(mass, com, field):
    with pytest.raises(ConfigError, match=f"p.yaml: {field}:"):
        check_payload("p.yaml", "payload", mass, com)
