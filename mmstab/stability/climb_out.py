"""Climbing a step with the rear down: whether the CoM passes the edge before the rear contact.

A step higher than the tracks can roll onto level (a ditch's far wall, a tall kerb) is
climbed in two phases. The front wheel rises up the face (the climb limit of
:mod:`mmstab.stability.climb`); then the track's belly rests on the step's edge while the
rear stays on the lower ground, and as the tracks drive on, the rear closes on the face and
the robot pitches nose up. It comes down onto the upper ground only once its CoM passes
ahead of the edge; if the CoM gets behind the rear contact first, the robot goes over
backwards. The resting pose on the map (:mod:`mmstab.terrain.rest`) has no history: past
the edge it lowers the robot level onto the upper ground wherever the CoM is over it, an
attitude the climbing robot never reaches while its CoM is behind the edge.

**Model**, in the vertical plane along the heading (x forward, z up; the track an outline of
two wheels of radius r = ``tracks.height / 2`` at x = ±L/2, z = r in B, joined by the belt).
At each path sample the rear wheel rests on the ground (the higher of the two tracks'
profiles) under x = −L/2 and the robot pivots nose up about its axle until the outline
touches the ground ahead: a ground point at distance d and angle φ from the axle needs
pitch ``φ + asin(r / d)`` under the belt (d² ≤ L² + r²) and ``φ + acos((d² + L² − r²) /
(2 d L))`` under the front wheel (d ≤ L + r); the pitch is the largest, the front contact
the foremost point that needs it. Gravity is vertical in the plane: the CoM (x_c, z_c) in
B lies ``(x_c + L/2) cos p − (z_c − r) sin p`` ahead of the axle. The attitude is a climb
where the foremost contact is under the belt (the front wheel is off the ground). Along
the path, a climb that starts from the robot on its end wheels goes on while the CoM stays
between the rear contact and the front one; it ends, crossed, where the CoM passes the
front contact; it **overturns** where the CoM falls behind the rear contact, or where the
rear wheel meets a wall (its contact more than 45° off the vertical and the face rising
above its axle: the rear cannot roll up it with the CoM still behind the edge).

Assumptions: quasi-static (the drive's push on the rear is what moves the climb on; no
momentum), no lateral gravity (both tracks meet the step together, as the climb limit),
rigid wheels, the flippers off the ground.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.model.robot import FloatArray, Robot
from mmstab.terrain.base import Terrain

#: Spacing of the ground samples along the track [m] (the maps' cells are 2-5 cm).
SAMPLE_STEP = 0.005
#: Ground points that need within this of the largest pitch touch too [rad].
TOUCH_TOL = 1e-3
#: A contact this far behind the front axle [m] is under the belt: the front wheel is up.
BELLY_TOL = 0.01
#: The rear wheel meets a face where its contact is more than this off the vertical [rad]
#: and the ground within :data:`WALL_REACH` of its rim rises above its axle [m].
FACE_ANGLE = np.pi / 4
WALL_REACH = 0.05


class PivotRest(NamedTuple):
    """The robot rested on its rear wheel and pivoted nose up onto the ground ahead (N poses).

    Horizontal positions are along the heading from the pose's (x, y) [m].

    Attributes:
        pitch: nose-up pitch [rad] (NaN: ground off the map).
        axle: the rear axle's horizontal position [m] (−L/2).
        axle_z: the rear axle's height [m].
        rear: the rear wheel's ground contact [m].
        rear_face: the rear wheel is at a wall: its contact more than :data:`FACE_ANGLE` off
            the vertical, and the ground within :data:`WALL_REACH` ahead of its rim above its
            axle.
        front: the foremost contact ahead [m].
        belly: that contact is under the belt, not the front wheel.
    """

    pitch: FloatArray
    axle: float
    axle_z: FloatArray
    rear: FloatArray
    rear_face: np.ndarray
    front: FloatArray
    belly: np.ndarray


def ground_profile(
    robot: Robot, terrain: Terrain, poses: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """The ground along the heading under both tracks: offsets (S,) and heights (N, S) [m].

    Offsets from −L/2 − r to L/2 + r ahead of each pose's (x, y) in M, every
    :data:`SAMPLE_STEP`; the height is the higher of the two tracks' centre lines (NaN off
    the map, ``terrain.bounds``). M must be G (a heightmap's map frame): gravity is along
    −z (:func:`pivot_rest` returns no climb on other terrains, planes without steps).
    """
    P = np.atleast_2d(np.asarray(poses, dtype=float))
    t = robot.base.tracks
    r, L = t.height / 2, t.length
    u = np.arange(-L / 2 - r, L / 2 + r + 1e-9, SAMPLE_STEP)
    c, s = np.cos(P[:, 2])[:, None, None], np.sin(P[:, 2])[:, None, None]
    side = np.array([t.separation / 2, -t.separation / 2])[None, :, None]
    x = P[:, 0, None, None] + u * c - side * s  # (N, 2, S)
    y = P[:, 1, None, None] + u * s + side * c
    box = terrain.bounds
    off = np.zeros(x.shape, bool)
    if box is not None:
        off = (x < box[0]) | (x > box[1]) | (y < box[2]) | (y > box[3])
        x, y = np.clip(x, box[0], box[1]), np.clip(y, box[2], box[3])
    z = np.where(off, np.nan, terrain.surface_G(x, y)[..., 2])
    return u, np.max(z, axis=1)


def pivot_rest(robot: Robot, terrain: Terrain, poses: ArrayLike) -> PivotRest:
    """:class:`PivotRest` at poses (x [m], y [m], heading [rad]) (N, 3) in M (module text)."""
    t = robot.base.tracks
    r, L = t.height / 2, t.length
    u, z = ground_profile(robot, terrain, poses)
    if not np.allclose(terrain.G_T_M(), np.eye(4)):  # a plane's map frame: no steps
        z = np.zeros_like(z)
    valid = np.isfinite(z).all(axis=1)
    z = np.where(np.isfinite(z), z, -np.inf)
    axle = -L / 2
    dx = u - axle  # (S,)
    # the rear wheel dropped onto the ground under its axle
    under = np.abs(dx) < r
    lift = np.where(under, np.sqrt(np.maximum(r**2 - dx**2, 0.0)), -np.inf)
    centre = z + lift  # (N, S)
    j_rear = np.argmax(centre, axis=1)
    axle_z = centre[np.arange(len(z)), j_rear]
    rear = u[j_rear]
    # ... pressed against a face that rises above its axle within WALL_REACH (a wall it
    # cannot roll up; a bump's flank below the axle it can)
    near = (dx > 0) & (dx <= r + WALL_REACH)
    wall = np.any(np.where(near, z, -np.inf) >= axle_z[:, None], axis=1)
    rear_face = ((rear - axle) > r * np.sin(FACE_ANGLE)) & wall
    # the pitch each point ahead needs to stay under the outline
    ahead = (dx >= r) & (dx <= L + r)  # nearer points are the rear wheel's own ground
    dz = z - axle_z[:, None]
    d = np.hypot(dx, dz)
    reach = ahead & (d > r) & (d <= L + r) & np.isfinite(dz)
    phi = np.arctan2(dz, dx)
    with np.errstate(invalid="ignore", divide="ignore"):
        belt = np.arcsin(np.clip(r / d, -1.0, 1.0))
        wheel = np.arccos(np.clip((d**2 + L**2 - r**2) / (2 * d * L), -1.0, 1.0))
    need = np.where(reach, phi + np.where(d**2 <= L**2 + r**2, belt, wheel), -np.inf)
    pitch = need.max(axis=1)
    touching = need >= pitch[:, None] - TOUCH_TOL
    j_front = len(u) - 1 - np.argmax(touching[:, ::-1], axis=1)
    n = np.arange(len(z))
    along = d[n, j_front] * np.cos(phi[n, j_front] - pitch)  # along the belt from the axle
    belly = along < L - BELLY_TOL
    pitch = np.where(valid & np.isfinite(pitch), pitch, np.nan)
    return PivotRest(pitch, axle, axle_z, rear, rear_face, u[j_front], belly & valid)


class ClimbOut(NamedTuple):
    """The climb along a path's samples (N), for one overall CoM per sample.

    Attributes:
        climbing: (N,) the robot climbs there on its rear wheel and the step's edge.
        overturns: (N,) it goes over backwards there (CoM behind the rear contact, or the
            rear wheel at the step's face, before the CoM passed the edge).
        pitch: (N,) the pivoted attitude's nose-up pitch [rad].
        behind_edge: (N,) how far the CoM is behind the front contact [m] (> 0: climbing).
        ahead_of_rear: (N,) how far it is ahead of the rear contact [m] (< 0: over backwards).
    """

    climbing: np.ndarray
    overturns: np.ndarray
    pitch: FloatArray
    behind_edge: FloatArray
    ahead_of_rear: FloatArray


def climb_out(robot: Robot, rest: PivotRest, com_body: ArrayLike) -> ClimbOut:
    """Follow the climbs along the samples in driving order (module text).

    Args:
        robot: the robot (its tracks).
        rest: :func:`pivot_rest` at the path's samples, in driving order.
        com_body: the overall CoM in B [m]: (3,), one per sample (N, 3), or the CoMs the
            arm may pass through at each sample (N, M, 3; NaN rows unused): the most
            backward one in the pivoted attitude counts.
    """
    r = robot.base.tracks.height / 2
    n = len(rest.pitch)
    c = np.asarray(com_body, dtype=float)
    if c.ndim == 1:
        c = np.broadcast_to(c, (n, 1, 3))
    elif c.ndim == 2:
        c = c[:, None, :]
    p = np.nan_to_num(rest.pitch)[:, None]
    x = rest.axle + (c[..., 0] - rest.axle) * np.cos(p) - (c[..., 2] - r) * np.sin(p)
    com_x = np.nanmin(np.where(np.isfinite(x), x, np.inf), axis=1)
    behind_edge = rest.front - com_x
    ahead_of_rear = com_x - rest.rear
    climbing = np.zeros(n, bool)
    overturns = np.zeros(n, bool)
    on = False  # a climb that started from the robot on its end wheels
    for k in range(n):
        if not np.isfinite(rest.pitch[k]):
            on = False
        elif not rest.belly[k]:
            on = True  # on its end wheels: any climb starts here
        elif on:
            if behind_edge[k] < 0:
                on = False  # the CoM passed the edge: down onto the upper ground
            elif ahead_of_rear[k] < 0 or rest.rear_face[k]:
                overturns[k] = True
                on = False
            else:
                climbing[k] = rest.pitch[k] > 0
    return ClimbOut(climbing, overturns, rest.pitch, behind_edge, ahead_of_rear)
