"""The whole robot skid-steering on a MuJoCo ramp: the twist its tracks actually give.

:func:`measure_twist` sets the robot (its arm held at a posture) on a planar ramp at a
heading (:func:`measure_twist_at`: at a pose on any ground, a heightmap's included), drives
its two tracks at constant surface speeds and averages the twist of the body
frame B over a window after a start-up transient: the velocity of B's origin in B and the
yaw rate about the ramp's normal. It is the physics side of
:mod:`mmstab.stability.skid` (``make skid``, ``tests/physics/test_physics_skid.py``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.model.robot import FloatArray, Robot
from mmstab.physics.robot_model import ModelSettings
from mmstab.physics.robot_sim import RobotSim
from mmstab.terrain.base import Terrain
from mmstab.terrain.factory import planar_terrain


class MeasuredTwist(NamedTuple):
    """The mean twist of B over the measuring window.

    Attributes:
        velocity_body: mean velocity of B's origin along x_B, y_B [m/s].
        yaw_rate: mean yaw rate about the ramp's normal [rad/s].
        gravity_body: gravity in B at the window's start [m/s^2].
    """

    velocity_body: FloatArray
    yaw_rate: float
    gravity_body: FloatArray


def measure_twist(
    robot: Robot,
    slope: float,
    heading: float,
    belt_speeds: ArrayLike,
    friction: float,
    arm_q: ArrayLike | None = None,
    *,
    settle: float = 0.5,
    transient: float = 0.5,
    duration: float = 2.0,
    samples: int = 40,
    settings: ModelSettings | None = None,
) -> MeasuredTwist:
    """Drive the tracks at ``belt_speeds`` on a ramp; B's mean twist after the transient.

    Args:
        robot: the robot.
        slope: the ramp's slope [rad] (uphill along +y of the ramp's frame).
        heading: the start heading in the ramp's frame [rad] (0: across, left side uphill).
        belt_speeds: (left, right) track surface speeds [m/s].
        friction: Coulomb coefficient of the ground [-].
        arm_q: the arm's posture [rad]; None: stowed.
        settle: braked time to set the robot down [s].
        transient: driven time before the window [s].
        duration: the measuring window [s].
        samples: states read in the window [-].
        settings: the MuJoCo model's numbers (default: the closed loop's model).
    """
    plane = planar_terrain(slope, friction)
    return measure_twist_at(robot, plane, (0.0, 0.0, heading), belt_speeds, arm_q,
                            settle=settle, transient=transient, duration=duration,
                            samples=samples, settings=settings)  # fmt: skip


def measure_twist_at(
    robot: Robot,
    ground: Terrain,
    pose: ArrayLike,
    belt_speeds: ArrayLike,
    arm_q: ArrayLike | None = None,
    *,
    settle: float = 0.5,
    transient: float = 0.5,
    duration: float = 2.0,
    samples: int = 40,
    settings: ModelSettings | None = None,
) -> MeasuredTwist:
    """:func:`measure_twist` at a pose on any ground (a heightmap's heightfield, its friction).

    Args:
        robot: the robot.
        ground: the terrain (its friction is the contacts').
        pose: the base's start (x [m], y [m], heading [rad]) in the terrain's map frame.
        belt_speeds: (left, right) track surface speeds [m/s].
        arm_q: the arm's posture [rad]; None: stowed.
        settle: braked time to set the robot down [s].
        transient: driven time before the window [s].
        duration: the measuring window [s].
        samples: states read in the window [-].
        settings: the MuJoCo model's numbers (default: the closed loop's model).
    """
    sim = RobotSim(robot, ground, pose=pose, arm_q=arm_q, settings=settings)
    belts = tuple(float(v) for v in np.asarray(belt_speeds, dtype=float))
    sim.step((0.0, 0.0), None, settle)
    state = sim.step(belts, None, transient)
    gravity = state.G_T_B[:3, :3].T @ sim.model.opt.gravity
    velocity, yaw = np.zeros(2), 0.0
    for _ in range(samples):
        state = sim.step(belts, None, duration / samples)
        velocity += state.velocity_body[:2] / samples
        yaw += float(state.omega_body[2]) / samples
    return MeasuredTwist(velocity, yaw, np.asarray(gravity, dtype=float))
