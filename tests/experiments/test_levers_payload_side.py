"""The levers' stowed payload rows are named by where the load is."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ROBOT_YAML

from experiments import levers as L
from mmstab.model.payload import Payload, attach_payload
from mmstab.model.robot import load_robot


@pytest.mark.parametrize("direction", ["front", "left", "right"])
def test_the_folded_arm_holds_the_load_on_the_named_side(direction):
    """The load's position in B from the CoM shift it causes (10 kg at the wrist origin)."""
    robot = load_robot(ROBOT_YAML)
    q = L.stowed_holding(robot, direction)
    heavy = attach_payload(robot, Payload(10.0, np.zeros(3)))
    load = (heavy.arm_mass * heavy.arm_com(q) - robot.arm_mass * robot.arm_com(q))[0] / 10.0
    side = {"front": (0, 1.0), "left": (1, 1.0), "right": (1, -1.0)}[direction]
    assert side[1] * load[side[0]] > 0.05  # on that side, by several cm
    other = 1 - side[0]
    if direction != "front":
        assert abs(load[other]) < abs(load[side[0]])
