"""URDF export: well-formed, and checked against an independent peer library (pinocchio)."""

from __future__ import annotations

import os
import subprocess
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin
import pytest
from conftest import ROBOT_YAML, ROOT, random_postures, write_problem

from mmstab.model.robot import Box, Capsule, rpy_matrix
from mmstab.model.urdf import (
    DEFAULT_EFFORT,
    default_file_mode,
    matrix_to_rpy,
    robot_to_urdf,
    solid_box_inertia,
    solid_capsule_inertia,
)

N_POSTURES = 200


@pytest.fixture(scope="module")
def urdf_text(robot) -> str:
    return robot_to_urdf(robot)


@pytest.fixture(scope="module")
def peer(urdf_text):
    """The URDF loaded by pinocchio, fixed base: base_link is pinocchio's universe."""
    model = pin.buildModelFromXML(urdf_text)
    return model, model.createData()


def _peer_q(model, q: np.ndarray) -> np.ndarray:
    """Pinocchio's configuration vector from mmstab's (4,) arm posture, by joint name."""
    q_peer = pin.neutral(model)
    for i, qi in enumerate(q):
        q_peer[model.joints[model.getJointId(f"arm_joint_{i}")].idx_q] = qi
    return q_peer


def test_urdf_is_well_formed_and_every_reference_is_defined(urdf_text, robot):
    root = ET.fromstring(urdf_text)
    assert root.tag == "robot" and root.get("name") == robot.name
    links = [el.get("name") for el in root.findall("link")]
    assert len(links) == len(set(links))
    joints = root.findall("joint")
    children = [j.find("child").get("link") for j in joints]
    parents = [j.find("parent").get("link") for j in joints]
    assert set(children) | set(parents) <= set(links)
    # a tree rooted at base_link: every other link is the child of exactly one joint
    assert sorted(children) == sorted(set(links) - {"base_link"})
    materials = {m.get("name") for m in root.findall("material")}
    used = {m.get("name") for m in root.iter("material") if m.find("color") is None}
    assert used and used <= materials
    assert set(robot.base.collision_boxes()) <= set(links)  # a link per base part
    revolute = [j for j in joints if j.get("type") == "revolute"]
    assert [j.get("name") for j in revolute] == [f"arm_joint_{i}" for i in range(4)]
    for i, (j, link) in enumerate(zip(revolute, robot.links, strict=True)):
        lim = j.find("limit")
        assert float(lim.get("lower")) == link.lower and float(lim.get("upper")) == link.upper
        assert float(lim.get("velocity")) == link.velocity
        assert float(lim.get("effort")) == DEFAULT_EFFORT
        assert j.find("child").get("link") == f"arm_link_{i}"
    # every link with geometry has as many visuals as collisions; capsules are cylinder+spheres
    arm1 = next(el for el in root.findall("link") if el.get("name") == "arm_link_1")
    kinds = sorted(g[0].tag for g in arm1.iter("geometry"))
    assert kinds == ["cylinder", "cylinder", "sphere", "sphere", "sphere", "sphere"]


def test_peer_arm_com_and_jacobian_match_at_random_postures(peer, robot, rng):
    model, data = peer
    ids = [model.getJointId(f"arm_joint_{i}") for i in range(4)]
    assert model.nq == 4 and ids == [1, 2, 3, 4]  # one chain, in order
    masses = np.array([model.inertias[j].mass for j in ids])
    np.testing.assert_allclose(masses, [link.mass for link in robot.links], rtol=1e-15)
    worst_com = worst_jac = worst_frame = 0.0
    for q in random_postures(robot, rng, N_POSTURES):
        q_peer = _peer_q(model, q)
        pin.forwardKinematics(model, data, q_peer)
        pin.updateFramePlacements(model, data)
        # mass-weighted CoM of the four arm links, in base_link
        com_peer = (
            sum(model.inertias[j].mass * data.oMi[j].act(model.inertias[j].lever) for j in ids)
            / masses.sum()
        )
        J_peer = pin.jacobianSubtreeCenterOfMass(model, data, q_peer, ids[0])
        worst_com = max(worst_com, np.abs(com_peer - robot.arm_com(q)).max())
        worst_jac = max(worst_jac, np.abs(J_peer - robot.kinematics.arm_com_jacobian(q)).max())
        # the fixed frames arm_frame_i are mmstab's DH frames R_i
        B_T_R = robot.kinematics.link_frames(q)
        for i in range(4):
            T_peer = data.oMf[model.getFrameId(f"arm_frame_{i}")].homogeneous
            worst_frame = max(worst_frame, np.abs(T_peer - B_T_R[i]).max())
    assert worst_com < 1e-9
    assert worst_jac < 1e-9
    assert worst_frame < 1e-9


def test_peer_joint_limits_equal_the_robots(peer, robot):
    model, _ = peer
    np.testing.assert_array_equal(model.lowerPositionLimit, robot.joint_lower)
    np.testing.assert_array_equal(model.upperPositionLimit, robot.joint_upper)
    np.testing.assert_array_equal(model.velocityLimit, robot.joint_velocity)
    np.testing.assert_array_equal(model.effortLimit, np.full(4, DEFAULT_EFFORT))


def test_peer_base_mass_and_com_equal_the_robots(urdf_text, robot):
    """With a free-flyer root, pinocchio merges base_link and its fixed children into one body."""
    model = pin.buildModelFromXML(urdf_text, pin.JointModelFreeFlyer())
    base = model.inertias[model.getJointId("root_joint")]
    assert base.mass == pytest.approx(robot.base.mass, rel=1e-14)
    np.testing.assert_allclose(base.lever, robot.base.com, atol=1e-14)
    assert np.all(np.linalg.eigvalsh(base.inertia) > 0)


def test_matrix_to_rpy_inverts_rpy_matrix(rng):
    cases = [*rng.uniform(-np.pi, np.pi, size=(50, 3)), [0.3, np.pi / 2, 0.0], [0.3, -np.pi / 2, 0]]
    for rpy in cases:
        R = rpy_matrix(rpy)
        np.testing.assert_allclose(rpy_matrix(matrix_to_rpy(R)), R, atol=1e-14)


def test_solid_inertias_limits():
    np.testing.assert_allclose(solid_box_inertia(12.0, [1, 2, 3]), np.diag([13.0, 10.0, 5.0]))
    # zero length: a sphere; vanishing radius: a thin rod
    np.testing.assert_allclose(solid_capsule_inertia(2.0, 0.5, 0.0), np.eye(3) * 0.4 * 2 * 0.25)
    rod = solid_capsule_inertia(3.0, 1e-6, 2.0)
    np.testing.assert_allclose(np.diag(rod), [1.0, 1.0, 0.0], atol=1e-5)


def test_capsule_inertia_matches_monte_carlo():
    rng = np.random.default_rng(7)
    r, h, m = 0.1, 0.5, 4.0
    pts = rng.uniform([-r, -r, -h / 2 - r], [r, r, h / 2 + r], size=(400_000, 3))
    z_clamped = np.clip(pts[:, 2], -h / 2, h / 2)
    inside = np.hypot(np.hypot(pts[:, 0], pts[:, 1]), pts[:, 2] - z_clamped) <= r
    p = pts[inside]
    I_mc = m * np.array(
        [np.mean(p[:, 1] ** 2 + p[:, 2] ** 2), np.mean(p[:, 0] ** 2 + p[:, 2] ** 2)]
        + [np.mean(p[:, 0] ** 2 + p[:, 1] ** 2)]
    )
    np.testing.assert_allclose(np.diag(solid_capsule_inertia(m, r, h)), I_mc, rtol=1e-2)


def test_geometry_types_are_covered(robot):
    kinds = {type(link.geometry) for link in robot.links}
    assert kinds == {Box, Capsule}  # the export test above exercises both shapes


def _cli(*args: str):
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.run(
        [sys.executable, "-m", "mmstab", *args], env=env, cwd=ROOT, capture_output=True, text=True
    )


def test_cli_writes_the_urdf(tmp_path, urdf_text):
    out = tmp_path / "sub" / "robot.urdf"
    res = _cli("urdf", str(ROBOT_YAML), "-o", str(out))
    assert res.returncode == 0, res.stderr
    assert out.read_text() == urdf_text
    assert [p.name for p in out.parent.iterdir()] == ["robot.urdf"]  # no temp file left
    assert out.stat().st_mode & 0o777 == default_file_mode()  # not mkstemp's private 0600


def test_cli_bad_robot_is_one_line_and_exit_2(tmp_path):
    def edit(prob, rob):
        rob["arm"]["links"][1]["mass"] = -1.0

    write_problem(tmp_path, edit)
    out = tmp_path / "robot.urdf"
    res = _cli("urdf", str(tmp_path / "robots" / "cameleon.yaml"), "-o", str(out))
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "arm.links[1].mass" in lines[0]
    assert not out.exists()
