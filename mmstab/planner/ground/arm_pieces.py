"""The arm's collision shapes cut into pieces (the ground under the arm's unit, ``under_arm``).

A capsule is cut into segments of at most :data:`PIECE` [m], a box into boxes of edges at
most that; each piece has a ball about its points' mean that holds it.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from mmstab.model.parts import Box
from mmstab.model.robot import FloatArray, Robot

#: Longest piece of a capsule [m]: a piece's square reaches its radius + half this past it.
PIECE = 0.05


class ArmPieces(NamedTuple):
    """The arm's collision shapes cut into pieces, in their links' frames.

    Attributes:
        link: the link of each piece (P,).
        points: each piece's corners (box) or segment ends (capsule, repeated) (P, 8, 3) [m].
        radius: the capsule's radius, 0 for a box (P,) [m].
        ball: radius of a ball about the points' mean holding the piece (P,) [m].
    """

    link: NDArray[np.intp]
    points: FloatArray
    radius: FloatArray
    ball: FloatArray


def arm_pieces(robot: Robot, piece: float = PIECE) -> ArmPieces:
    """The arm's links' collision shapes as pieces (a capsule cut into ``piece`` [m] segments)."""
    link, points, radius = [], [], []
    for i, lk in enumerate(robot.links):
        g = lk.geometry
        if isinstance(g, Box):  # cut into boxes of edges at most ``piece``
            cuts = np.maximum(np.ceil(g.size / piece), 1).astype(int)
            sub = g.size / cuts
            corner = np.array([[sx, sy, sz] for sx in (0, 1) for sy in (0, 1) for sz in (0, 1)])
            R = g.frame_T_shape[:3, :3]
            for ijk in np.ndindex(*cuts):
                local = (np.array(ijk) + corner) * sub - g.size / 2
                link.append(i)
                points.append(local @ R.T + g.center)
                radius.append(0.0)
            continue
        n = max(int(np.ceil(np.linalg.norm(g.p1 - g.p0) / piece)), 1)
        ends = g.p0 + np.linspace(0.0, 1.0, n + 1)[:, None] * (g.p1 - g.p0)
        for a, b in zip(ends[:-1], ends[1:], strict=True):
            link.append(i)
            points.append(np.repeat(np.stack([a, b]), 4, axis=0))
            radius.append(float(g.radius))
    pts, rad = np.array(points), np.array(radius)
    centre = pts.mean(axis=1, keepdims=True)
    ball = np.linalg.norm(pts - centre, axis=2).max(axis=1) + rad
    return ArmPieces(np.array(link), pts, rad, ball)


def arm_reach(robot: Robot, pieces: ArmPieces) -> tuple[FloatArray, float]:
    """A ball in B holding the arm at every posture: the turret's origin [m], a radius [m].

    Every point of link i is within Σ_{j<i} |o_{j+1} − o_j| + |p − o_i| of the turret's
    origin o_0 (the links' origins at fixed offsets along the chain).
    """
    frames = robot.kinematics.link_frames(np.atleast_2d(robot.stowed))[0]
    o = frames[:, :3, 3]
    chain = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(o, axis=0), axis=1))]
    far = np.linalg.norm(pieces.points, axis=2).max(axis=1) + pieces.radius
    return o[0], float((chain[pieces.link] + far).max())


#: Spacing of the points on the arm's surface [m] (:func:`arm_surface`).
SURFACE_STEP = 0.02
#: Directions about each point of a capsule's axis (a spiral on the sphere: every direction
#: within 0.43 rad of one, so a 4 cm radius's lowest point is found within 4 mm).
SURFACE_DIRECTIONS = 40


class ArmSurface(NamedTuple):
    """Points on the arm's collision shapes, in their links' frames.

    Attributes:
        link: the link of each point (Q,).
        points: the points (Q, 3) [m].
    """

    link: NDArray[np.intp]
    points: FloatArray


def sphere_directions(n: int) -> FloatArray:
    """Unit vectors spread over the sphere, ``n`` of them (a Fibonacci spiral), (n, 3)."""
    k = np.arange(n) + 0.5
    polar, turn = np.arccos(1.0 - 2.0 * k / n), np.pi * (1.0 + 5.0**0.5) * k
    return np.stack([np.cos(turn) * np.sin(polar), np.sin(turn) * np.sin(polar), np.cos(polar)], 1)


def arm_surface(
    robot: Robot, step: float = SURFACE_STEP, directions: int = SURFACE_DIRECTIONS
) -> ArmSurface:
    """The arm's links' collision shapes as points on their surfaces, ``step`` [m] apart.

    A box: a grid on each face, its edges and corners included. A capsule: the spheres of
    its radius about points of its axis ``step`` apart (ends included), each sampled in
    ``directions`` directions (:func:`sphere_directions`).
    """
    link, points = [], []
    around = sphere_directions(directions)
    for i, lk in enumerate(robot.links):
        g = lk.geometry
        if isinstance(g, Box):
            faces = []
            for axis in range(3):
                a, b = (k for k in range(3) if k != axis)
                u, v = (np.linspace(-0.5, 0.5, max(int(np.ceil(g.size[k] / step)), 1) + 1)
                        for k in (a, b))  # fmt: skip
                U, V = np.meshgrid(u, v)
                for side in (-0.5, 0.5):
                    face = np.zeros((U.size, 3))
                    face[:, axis], face[:, a], face[:, b] = side, U.ravel(), V.ravel()
                    faces.append(face * g.size)
            R = g.frame_T_shape[:3, :3]
            pts = np.vstack(faces) @ R.T + g.center
        else:
            n = max(int(np.ceil(np.linalg.norm(g.p1 - g.p0) / step)), 1)
            axis_pts = g.p0 + np.linspace(0.0, 1.0, n + 1)[:, None] * (g.p1 - g.p0)
            pts = (axis_pts[:, None, :] + g.radius * around[None]).reshape(-1, 3)
        link.append(np.full(len(pts), i, dtype=np.intp))
        points.append(pts)
    return ArmSurface(np.concatenate(link), np.vstack(points))
