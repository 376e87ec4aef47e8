"""A rear pair of flippers (``base.rear_flippers``), checked by turning the robot round.

A robot with front flippers only, turned by pi about its z axis, is a robot whose flippers
are a rear pair (body, CoM and arm mount turned with it): on the same ground it rests alike
and has the same μ at the heading plus pi, and its arm meets the same bodies.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest
from conftest import SCOUT
from test_one_mu import user_ground
from test_plain_base import mujoco_model_of

from mmstab.core.files import ConfigError, MmstabError
from mmstab.model.collision import CollisionChecker
from mmstab.model.robot import robot_from_dict, rpy_matrix
from mmstab.model.urdf import matrix_to_rpy
from mmstab.stability.support import posture_mu
from mmstab.terrain import HeightmapTerrain, Ramp
from mmstab.terrain.generators import generate

TURN = np.diag([-1.0, -1.0, 1.0])  # Rz(pi)


def front() -> dict:
    """The scout, its flippers lowered so they bear on the ground's rises."""
    data = {**copy.deepcopy(SCOUT), "collision": {"allow": [["turret", "body"]]}}
    data["base"]["flippers"].update(angle=-0.15, length=0.3)
    return data


def turned(data: dict) -> dict:
    """The same robot turned by pi about z: its flippers become a rear pair."""
    out = copy.deepcopy(data)
    b = out["base"]
    b["com"] = (TURN @ b["com"]).tolist()
    b["body"]["center"] = (TURN @ b["body"]["center"]).tolist()
    fl = b.pop("flippers")
    fl["pivot"] = [-fl["pivot"][0], fl["pivot"][1], fl["pivot"][2]]  # the left hinge
    b["rear_flippers"] = fl
    mount = out["arm"]["mount"]
    mount["xyz"] = (TURN @ mount["xyz"]).tolist()
    mount["rpy"] = matrix_to_rpy(TURN @ rpy_matrix(mount["rpy"])).tolist()
    out["name"] = "turned"
    return out


@pytest.mark.parametrize("seed", [31, 32])
def test_turned_round_it_rests_alike_with_the_same_mu(seed):
    one, two = robot_from_dict(front(), "a.yaml"), robot_from_dict(turned(front()), "b.yaml")
    assert two.base.flippers is None and two.base.rear_flippers is not None
    assert list(two.base.collision_boxes())[-2:] == ["flipper_rear_left", "flipper_rear_right"]
    rng = np.random.default_rng(seed)
    hm = generate(user_ground(rng))
    poses = np.c_[rng.uniform(-1.5, 1.5, (24, 2)), rng.uniform(-np.pi, np.pi, 24)]
    back = poses + [0.0, 0.0, np.pi]
    q = rng.uniform(one.joint_lower, one.joint_upper, (24, one.arm_joints))
    g1, g2 = HeightmapTerrain(hm).with_robot(one), HeightmapTerrain(hm).with_robot(two)
    r1, r2 = g1.rest(poses), g2.rest(back)
    flip = np.diag([-1.0, -1.0, 1.0, 1.0])
    np.testing.assert_allclose(r2.G_T_B @ flip, r1.G_T_B, rtol=0, atol=1e-9)
    mu1, mu2 = posture_mu(one, g1, poses, q), posture_mu(two, g2, back, q)
    np.testing.assert_allclose(mu2, mu1, rtol=1e-10, atol=0)  # the turned coordinates round
    # the flippers bear: without them the μ differs
    bare = copy.deepcopy(front())
    del bare["base"]["flippers"]
    three = robot_from_dict(bare, "c.yaml")
    mu3 = posture_mu(three, HeightmapTerrain(hm).with_robot(three), poses, q)
    assert np.abs(mu3 - mu1).max() > 1.0


def test_turned_round_its_arm_meets_the_same_bodies(rng):
    one, two = robot_from_dict(front(), "a.yaml"), robot_from_dict(turned(front()), "b.yaml")
    q = rng.uniform(one.joint_lower, one.joint_upper, (400, one.arm_joints))
    a, b = CollisionChecker(one), CollisionChecker(two)
    rear = {f"{link}-flipper_rear_{side}" for link in ("turret", "upper", "fore")
            for side in ("left", "right")}  # fmt: skip
    assert {p.name for p in b.pairs} - {p.name for p in a.pairs} == rear
    np.testing.assert_array_equal(b.collides(q, cull=False), a.collides(q, cull=False))


def test_rear_flippers_below_the_ground_and_their_angle_set_are_refused():
    data = turned(front())
    data["base"]["rear_flippers"]["angle"] = -0.3
    with pytest.raises(ConfigError, match="base.rear_flippers.angle: flippers reach 0.0"):
        robot_from_dict(data, "r.yaml")
    # a flipper angle sets the front pair, which this robot has not
    with pytest.raises(MmstabError, match="has no flippers"):
        Ramp(0.1).with_robot(robot_from_dict(turned(front()), "b.yaml"), 0.3)


@pytest.mark.mujoco
def test_the_mujoco_robot_has_the_rear_pair_and_the_descriptions_mass():
    two = robot_from_dict(turned(front()), "b.yaml")
    q = np.array([0.4, 0.9, -0.7])
    names, mass, com = mujoco_model_of(two, q)
    assert {"flipper_rear_left", "flipper_rear_right"} <= names
    assert not {"flipper_left", "flipper_right"} & names
    assert mass == pytest.approx(two.total_mass, abs=1e-9)
    np.testing.assert_allclose(com, two.overall_com(two.arm_com(q)), atol=1e-9)
