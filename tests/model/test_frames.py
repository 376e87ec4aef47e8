"""mmstab.model.frames: link frames and link shapes' poses in C, bit for bit NumPy's."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ROOT

from mmstab.model import frames
from mmstab.model.collision import CollisionChecker
from mmstab.model.kinematics import dh_np
from mmstab.model.robot import load_robot

ROBOTS = ["cameleon", "cameleon_6dof", "cameleon_long_arm"]


def _postures(rng, n, joints):
    q = rng.uniform(-3.2, 3.2, (n, joints))
    return np.vstack([q, np.round(q, 1), np.round(q / (np.pi / 2)) * (np.pi / 2), 0 * q[:5]])


@pytest.mark.parametrize("name", ROBOTS)
def test_c_frames_and_shapes_are_numpys_bit_for_bit(name):
    robot = load_robot(ROOT / "problems" / "robots" / f"{name}.yaml")
    kin, checker = robot.kinematics, CollisionChecker(robot)
    if frames._kernels() is None:
        pytest.skip("no C compiler")
    q = _postures(np.random.default_rng(3), 2000, len(robot.links))
    got = frames.link_frames(kin._trig(q), kin._dh_gain, kin._dh_rest, kin.mount_T)
    if got is None:
        pytest.skip("no FMA unit")
    want = kin._frames_np(q)  # NumPy's batched 4x4 products (BLAS)
    assert frames.same_bits(got, want)
    assert frames.same_bits(kin.link_frames(q), want)  # the path link_frames takes
    R, p = checker._shape_poses_c(want)
    R0, p0 = checker._shape_poses_np(want)
    assert frames.same_bits(R, R0) and frames.same_bits(p, p0)
    R1, p1 = checker.shape_poses(q)
    assert frames.same_bits(R1, R0) and frames.same_bits(p1, p0)
    # a frame by hand at one posture: the chain of DH transforms
    T = kin.mount_T.copy()
    for i, link in enumerate(kin.links):
        th = q[7, i] + link.theta_offset
        ct, st, ca, sa = np.cos(th), np.sin(th), np.cos(link.alpha), np.sin(link.alpha)
        D = np.array(
            [[ct, -st * ca, st * sa, link.a * ct], [st, ct * ca, -ct * sa, link.a * st],
             [0, sa, ca, link.d], [0, 0, 0, 1]]
        )  # fmt: skip
        T = T @ D
        np.testing.assert_allclose(got[7, i], T, atol=1e-14)


def test_disagreeing_or_missing_kernel_keeps_numpys_path(monkeypatch):
    a = np.array([1.0, -0.0, 2.0])
    assert frames._agrees(lambda: a.copy(), lambda: a)
    assert not frames._agrees(lambda: np.array([1.0, 0.0, 2.0]), lambda: a)  # a signed zero
    assert not frames._agrees(lambda: np.nextafter(a, 9), lambda: a)  # one ulp
    assert not frames._agrees(lambda: None, lambda: a)  # no kernel
    robot = load_robot(ROOT / "problems" / "robots" / "cameleon.yaml")
    q = _postures(np.random.default_rng(4), 50, 4)
    T, chain = np.broadcast_to(robot.kinematics.mount_T, (len(q), 4, 4)), []
    for i, link in enumerate(robot.kinematics.links):  # link after link, dh_np's transforms
        T = T @ dh_np(q[:, i] + link.theta_offset, link.a, link.alpha, link.d)
        chain.append(T)
    want = np.stack(chain, axis=1)
    monkeypatch.setattr(frames, "_kernels", lambda: None)
    monkeypatch.setattr(frames, "_AGREED", {})
    kin = load_robot(ROOT / "problems" / "robots" / "cameleon.yaml").kinematics
    assert frames.same_bits(kin.link_frames(q), want) and kin._fast is False
