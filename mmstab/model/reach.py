"""How far each joint moves the arm: the bound that spaces the checked postures of a move.

A joint-space move by Δq moves no point of the arm more than Σ_j reach_j |Δq_j|, reach_j
the largest distance of a point of links j.. from joint j's axis. The posture roadmap
spaces its edges' collision checks with it, and the roadmap's and ``method: sequence``'s
moves their ground checks (:func:`mmstab.model.plane_clearance.lowest_along_moves`).
"""

from __future__ import annotations

import numpy as np

from mmstab.model.collision import CollisionChecker
from mmstab.model.robot import FloatArray, Robot

#: Postures of V sampled to bound each joint's reach (seeded).
REACH_SAMPLES = 20000


def joint_reach(robot: Robot, q: FloatArray) -> FloatArray:
    """Per joint j, the largest distance of a point of links j.. from joint j's origin [m].

    Each link shape's centre distance plus its bounding radius, the maximum over postures q
    (N, 4) [rad]: the distance depends only on the joints after j, which q samples.
    """
    checker = CollisionChecker(robot)
    frames = robot.kinematics.link_frames(q)
    _, p = checker.shape_poses(q, frames)
    radius = np.array([link.geometry.bounding_radius for link in robot.links])
    out = np.zeros(robot.arm_joints)
    for j in range(robot.arm_joints):
        o = frames[:, j, :3, 3]
        d = np.linalg.norm(p[:, j:, :] - o[:, None, :], axis=2) + radius[j:]
        out[j] = float(d.max())
    return out


def sampled_reach(robot: Robot, q: FloatArray) -> FloatArray:
    """:func:`joint_reach` over ``REACH_SAMPLES`` of the postures q (N, 4) [rad] (seeded) [m].

    The roadmap's ``reach`` (from V's collision-free postures); ``method: sequence``
    samples its moves with the same.
    """
    rng = np.random.default_rng(0)
    return joint_reach(robot, q[rng.choice(len(q), min(REACH_SAMPLES, len(q)), replace=False)])
