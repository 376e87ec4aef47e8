"""The arm's height above the plane the tracks rest on (z_B = 0).

The workspace V and the posture roadmap check the arm against the robot's own body only;
nothing there keeps it out of the ground. On a plane the robot rests on, the ground is the
body frame's z_B = 0 at any slope, so the lowest point of the arm's collision shapes in B
says whether a posture puts the arm into the ground. Used by the planner (the roadmap's
eligible nodes, ``planner.ground_clearance``) and by the physics checks. It knows the
support plane only; the ground under the arm at a pose is :mod:`mmstab.planner.under_arm`'s.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from mmstab.model.parts import Box
from mmstab.model.robot import FloatArray, Robot

#: Postures per batch of link frames (bounds the memory of a roadmap's 288k nodes).
CHUNK = 65536


def arm_ground_clearance(robot: Robot, postures: ArrayLike) -> FloatArray:
    """Height of the arm's lowest point above the support plane z_B = 0, per posture (N,) [m].

    From the links' collision shapes: a box's corners, a capsule's end points less its
    radius. Negative: the arm reaches below the plane the tracks rest on.

    Args:
        robot: the robot.
        postures: arm joint angles (N, n) or (n,) [rad].
    """
    q = np.atleast_2d(np.asarray(postures, dtype=float))
    lowest = np.full(len(q), np.inf)
    for c in range(0, len(q), CHUNK):
        frames = robot.kinematics.link_frames(q[c : c + CHUNK])
        low = lowest[c : c + CHUNK]
        for i, link in enumerate(robot.links):
            g = link.geometry
            if isinstance(g, Box):
                points, radius = g.corners(), 0.0
            else:
                points, radius = np.stack([g.p0, g.p1]), float(g.radius)
            z = points @ frames[:, i, 2, :3].T + frames[:, i, 2, 3]  # (P, n) heights in B
            np.minimum(low, z.min(axis=0) - radius, out=low)
    return lowest
