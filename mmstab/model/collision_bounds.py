"""The least distance of a pair of bodies that one revolute joint alone moves, over a turn.

:meth:`mmstab.model.collision.CollisionChecker.keeps_clearance` asks FCL for the distance
of every pair whose bounding spheres come within the clearance wanted. The turret box
stays 1 cm above the body at every angle, inside its bounding sphere's reach: half of the
FCL calls of a plan's moves measured exactly that. A pair that one joint alone moves (the
first link against a base part) has a least distance over the whole turn
(:func:`turn_floor`): FCL on a grid of the joint's angle, less the most the shape moves
between grid points (its farthest point from the joint's axis times half a step). Where
that floor is at least the clearance wanted, the pair is not measured: FCL would have
found it that far at every posture (``tests/model/test_collision_bounds.py``).
"""

from __future__ import annotations

import fcl
import numpy as np

from mmstab.model.robot import FloatArray

#: Grid steps of the floor over a full turn of the joint (0.5 deg).
FLOOR_STEPS = 720
#: Slack taken off the floor [m]: FCL's GJK distances are not exact to round-off.
SLACK = 1e-6


def turn_floor(
    obj: fcl.CollisionObject,
    other: fcl.CollisionObject,
    R: FloatArray,
    p: FloatArray,
    corners: FloatArray,
    inflate: float,
) -> float:
    """Least distance [m] of a shape turned by one revolute joint to a fixed body, any angle.

    Args:
        obj: the turning shape's FCL object (moved here).
        other: the fixed body's FCL object.
        R: the shape's rotations at :data:`FLOOR_STEPS` + 1 angles evenly spaced over a
            full turn, both ends included (n, 3, 3).
        p: its centres there (n, 3) [m].
        corners: the points whose hull, grown by ``inflate`` [m], is the shape, in its
            frame (c, 3) [m] (a box's corners, a capsule's segment ends).
        inflate: the capsule's radius [m] (0 for a box).

    Between neighbouring angles (a step δ apart) a point at distance ρ from the axis
    moves its chord 2 ρ sin(δ/2) (measured here on the corners) and at most ρ δ / 2 from
    the nearer grid angle; the shape's farthest point from the axis is a corner's plus
    ``inflate``. FCL's -1 (penetration) makes the floor negative: no bound.
    """
    request = fcl.DistanceRequest()
    d = np.empty(len(R))
    for n in range(len(R)):
        obj.setTransform(fcl.Transform(R[n], p[n]))
        d[n] = float(fcl.distance(obj, other, request, fcl.DistanceResult()))
    delta = 2 * np.pi / (len(R) - 1)
    pts = np.einsum("nij,cj->nci", R, corners) + p[:, None, :]
    chord = np.linalg.norm(np.diff(pts, axis=0), axis=2).max()
    rho = float(chord) / (2 * np.sin(delta / 2)) + inflate
    return float(d.min() - rho * delta / 2 - SLACK)
