"""The skid-steer drive layer: the belt speeds that give the twist the controller means.

The controller's plant is kinematic (:mod:`mmstab.control.plant`): sprocket rates θ̇_L, θ̇_R
[rad/s] give v = r (θ̇_L + θ̇_R) / 2 and ω = r (θ̇_R − θ̇_L) / b. A skid-steered base turns
slower than that: its belts skid sideways at the tracks' ends, so on level ground it yaws at
η ω only, η the *turn ratio* (achieved / kinematic yaw rate). The drive layer between the
controller and the belts does what a skid-steer robot's drive does with its effective track
gauge b / η (the instantaneous-centre-of-rotation kinematics of Mandow et al. 2007,
"Experimental kinematics for wheeled skid-steer mobile robots"): it reads the controller's
rates as the twist (v, ω) they mean and commands the belts

    u_L,R = v ∓ ω b / (2 η)   [m/s],

both scaled down together where one would pass the tracks' velocity limit (their ratio, so
the turn radius, kept). η = 1 is the kinematic drive (the belts at r θ̇).

``physics.turn_ratio: auto`` takes η from mmstab's skid-steer model
(:func:`mmstab.stability.skid.skid_twist`): the robot's pivot on level ground with the arm
stowed, whose ratio does not depend on the friction coefficient (every contact slides, each
pushing with μ n: μ scales all forces alike).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.model.robot import FloatArray, Robot
from mmstab.stability.skid import belts_for_twist, skid_twist, track_patch

#: ``physics.turn_ratio``'s value that asks for the skid model's level pivot ratio
AUTO = "auto"


def pivot_turn_ratio(robot: Robot) -> float:
    """The skid model's yaw rate over the kinematic one, level pivot, arm stowed [-]."""
    patch = track_patch(robot)
    com = robot.overall_com(robot.arm_com(robot.stowed))
    level = np.array([0.0, 0.0, -9.81])
    belt = 0.1  # [m/s]: the model is homogeneous in the belt speeds and in the friction
    twist = skid_twist(patch, level, com, (-belt, belt), friction=1.0)
    return float(twist.yaw_rate[0] / (2 * belt / patch.separation))


def resolve_turn_ratio(robot: Robot, setting: Any) -> float:
    """η of a ``physics.turn_ratio`` setting: a number in (0, 1] or ``auto`` [-]."""
    return pivot_turn_ratio(robot) if setting == AUTO else float(setting)


class DriveLayer(NamedTuple):
    """The drive between the controller's sprocket rates and the belts.

    Attributes:
        radius: sprocket radius r [m].
        separation: the belts' centre-line distance b [m].
        turn_ratio: η, level-ground achieved over kinematic yaw rate [-] (1: kinematic drive).
        limit: the belts' surface-speed limit [m/s] (r times the sprockets' rate limit).
    """

    radius: float
    separation: float
    turn_ratio: float
    limit: float

    @classmethod
    def of(cls, robot: Robot, turn_ratio: float) -> DriveLayer:
        """The robot's drive with turn ratio η [-]."""
        t = robot.base.tracks
        r = t.sprocket_radius
        return cls(r, t.separation, float(turn_ratio), r * t.velocity_limit)

    def belts(self, sprocket_rates: ArrayLike) -> FloatArray:
        """Belt surface speeds (left, right) [m/s] for sprocket rates (left, right) [rad/s].

        Batched: rates (..., 2) give belts (..., 2). η = 1 passes r θ̇ through unchanged (the
        controller's QP holds θ̇ within the limit itself).
        """
        rates = np.asarray(sprocket_rates, dtype=float)
        if self.turn_ratio == 1.0:
            return np.asarray(self.radius * rates)
        v = self.radius * (rates[..., 0] + rates[..., 1]) / 2
        w = self.radius * (rates[..., 1] - rates[..., 0]) / self.separation
        u = belts_for_twist(v, w, self.separation, self.turn_ratio)
        top = np.max(np.abs(u), axis=-1, keepdims=True)
        return np.asarray(u * np.minimum(1.0, self.limit / np.maximum(top, 1e-12)))
