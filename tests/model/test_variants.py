"""The robot variants load, stow without self-collision, and differ as their geometry says."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import PROBLEMS

from mmstab.model.collision import CollisionChecker
from mmstab.model.robot import load_robot
from mmstab.stability.static import mu_max

VARIANTS = ["cameleon", "cameleon_long_arm", "cameleon_narrow"]


@pytest.mark.parametrize("name", VARIANTS)
def test_variant_loads_and_stows_freely(name):
    robot = load_robot(PROBLEMS / "robots" / f"{name}.yaml")
    assert robot.name == name
    assert not CollisionChecker(robot).collides(robot.stowed)


def test_variants_differ_as_built():
    base, long_arm, narrow = (load_robot(PROBLEMS / "robots" / f"{n}.yaml") for n in VARIANTS)
    assert long_arm.arm_mass > base.arm_mass and narrow.arm_mass == base.arm_mass
    # stretched arm reaches further
    reach = [
        np.linalg.norm(r.kinematics.link_frames(np.zeros(4))[-1][:3, 3]) for r in (base, long_arm)
    ]
    assert reach[1] > reach[0] + 0.2
    # flat ground, arm stowed: the right-hand side axis is critical for both bases, so by
    # hand mu_max = atan((w/2 - |y_o|) / z_o) m g with w the outer track width
    for robot in (base, narrow):
        g_o = robot.overall_com(robot.arm_com(robot.stowed))
        half_w = robot.base.tracks.separation / 2 + robot.base.tracks.width / 2
        by_hand = np.arctan2(half_w - abs(g_o[1]), g_o[2]) * robot.total_mass * 9.81
        assert mu_max(robot) == pytest.approx(by_hand, rel=1e-12)
    assert mu_max(narrow) < mu_max(base) - 50
