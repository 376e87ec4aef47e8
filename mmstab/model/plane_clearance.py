"""The arm's height above the plane the tracks rest on (z_B = 0).

The workspace V and the posture roadmap check the arm against the robot's own body only;
nothing there keeps it out of the ground. On a plane the robot rests on, the ground is the
body frame's z_B = 0 at any slope, so the lowest point of the arm's collision shapes in B
says whether a posture puts the arm into the ground. Used by the planner (the roadmap's
eligible nodes and moves, ``method: sequence``'s candidates and moves,
``planner.ground_clearance``) and by the physics checks. It knows the support plane only;
the ground under the arm at a pose is :mod:`mmstab.planner.ground.under_arm`'s.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from mmstab.model.parts import Box
from mmstab.model.robot import FloatArray, Robot

#: Postures per batch of link frames (bounds the memory of a roadmap's 288k nodes).
CHUNK = 65536


def tilted_height(points_B: FloatArray, margin: float) -> FloatArray:
    """Least height [m] above z_B = 0 of points (..., 3) in B [m] over the body's tilts.

    The tilts are rotations by up to ``margin`` [rad] about any horizontal axis through
    B's origin (``planner.attitude_margin``: the body pitching or rolling in motion away
    from its resting attitude). A point at height z and horizontal distance ρ from the
    origin comes down most when the axis is normal to ρ: to ``z cos θ − ρ sin θ`` at
    θ = ``margin`` for z ≥ 0 (the height falls monotonically in θ up to π/2). A point
    below the plane (z < 0) fails any clearance ≥ 0 already: the min with z keeps it
    there. ``margin`` 0: z itself.
    """
    z = points_B[..., 2]
    if margin == 0.0:
        return np.asarray(z)
    rho = np.hypot(points_B[..., 0], points_B[..., 1])
    return np.minimum(z, z * np.cos(margin) - rho * np.sin(margin))


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


def lowest_along_moves(
    robot: Robot, reach: FloatArray, q_from: ArrayLike, q_to: ArrayLike, step: float
) -> FloatArray:
    """The arm's lowest height above z_B = 0 along straight joint-space moves (N,) [m].

    Each move q_from -> q_to (N, n) [rad] is sampled so that no arm point moves more than
    ``step`` [m] between two samples (the bound Σ_j reach_j |Δq_j|, ``reach`` (n,) [m]:
    per joint, the largest distance of an arm point from its axis), the ends included.
    The one sampling rule of the roadmap's moves and the sequence's.
    """
    a, b = np.broadcast_arrays(np.atleast_2d(q_from), np.atleast_2d(q_to))
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    n = np.ceil(np.abs(b - a) @ np.asarray(reach, dtype=float) / step).astype(np.intp) + 1
    move = np.repeat(np.arange(len(a)), n + 1)
    first = np.repeat(np.r_[0, np.cumsum(n + 1)[:-1]], n + 1)
    u = ((np.arange(len(move)) - first) / n[move])[:, None]
    low = arm_ground_clearance(robot, a[move] + u * (b[move] - a[move]))
    lowest = np.full(len(a), np.inf)
    np.minimum.at(lowest, move, low)
    return lowest
