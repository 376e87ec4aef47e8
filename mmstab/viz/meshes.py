"""The robot's surfaces for drawing: polygons of its collision geometry, placed in G [m].

The bodies the collision checker knows, as polygons: the base boxes
(``Base.collision_boxes()``) and the four arm links (box or capsule in their DH frame R_i,
placed by ``ArmKinematics.link_frames``). Capsules are low-poly cylinders with low-poly
hemispherical caps. Points are mapped to the drawing frame by ``G_T_B`` (the body frame's
pose in G, e.g. ``Terrain.G_T_B(pose)``); without it they are in B. No matplotlib here:
:mod:`mmstab.viz.drawing` draws these.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from mmstab.model.robot import Box, Capsule, FloatArray, Geometry, Robot
from mmstab.model.urdf import axis_to_z_rotation
from mmstab.stability.static import base_polygon

#: Sides of the low-poly cylinders that stand for capsules.
CAPSULE_SIDES = 10

#: The support polygon is drawn this far above the ground, to stay visible [m].
SUPPORT_LIFT = 2e-3


def transform_points(T: ArrayLike, points: ArrayLike) -> FloatArray:
    """Apply a 4x4 transform to points (..., 3) [m]."""
    M = np.asarray(T, dtype=float)
    p = np.asarray(points, dtype=float)
    return p @ M[:3, :3].T + M[:3, 3]


def box_faces(box: Box) -> list[FloatArray]:
    """The six quads (4, 3) of a box, in its owning frame [m]."""
    c = box.corners()  # index = 4 * (sx > 0) + 2 * (sy > 0) + (sz > 0)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return [c[list(q)] for q in quads]


def capsule_faces(capsule: Capsule, sides: int = CAPSULE_SIDES) -> list[FloatArray]:
    """Low-poly capsule: a ``sides``-gon cylinder and two caps of one ring each [m].

    Args:
        capsule: the capsule, in its owning frame.
        sides: number of sides of the cylinder (>= 3).

    Returns:
        Quads (4, 3) in the owning frame: ``sides`` on the cylinder, then per cap ``sides``
        to a ring at 45 deg and ``sides`` triangles to the pole (the pole given twice, so
        that every polygon has four vertices: matplotlib's autoscaling reads the padding
        of ragged polygon lists as data).
    """
    axis = capsule.p1 - capsule.p0
    R = axis_to_z_rotation(axis) if capsule.length > 0 else np.eye(3)
    z = R[:, 2]
    phi = np.arange(sides) * 2 * np.pi / sides
    ring = capsule.radius * (np.outer(np.cos(phi), R[:, 0]) + np.outer(np.sin(phi), R[:, 1]))
    nxt = np.roll(np.arange(sides), -1)
    faces: list[FloatArray] = []
    a, b = capsule.p0 + ring, capsule.p1 + ring
    faces += [np.array([a[k], a[nxt[k]], b[nxt[k]], b[k]]) for k in range(sides)]
    s45 = np.sqrt(0.5)
    for end, sign in ((capsule.p0, -1.0), (capsule.p1, 1.0)):
        base = end + ring
        mid = end + ring * s45 + sign * z * capsule.radius * s45
        pole = end + sign * z * capsule.radius
        faces += [np.array([base[k], base[nxt[k]], mid[nxt[k]], mid[k]]) for k in range(sides)]
        # triangles as quads with a repeated pole: mplot3d mis-scales ragged polygon lists
        faces += [np.array([mid[k], mid[nxt[k]], pole, pole]) for k in range(sides)]
    return faces


def geometry_faces(geometry: Geometry) -> list[FloatArray]:
    """Polygons of a box or capsule in its owning frame [m]."""
    return box_faces(geometry) if isinstance(geometry, Box) else capsule_faces(geometry)


def robot_meshes(
    robot: Robot, q: ArrayLike, G_T_B: FloatArray | None = None
) -> dict[str, list[FloatArray]]:
    """Polygons of the robot's nine bodies at posture ``q``, in G (or B) [m].

    Args:
        robot: the robot.
        q: arm joint angles (4,) [rad].
        G_T_B: pose of the body frame in the drawing frame (4x4); ``None`` = identity.

    Returns:
        Body name -> list of polygons (k, 3): the base bodies, then ``arm_link_0..3``.
    """
    T = np.eye(4) if G_T_B is None else np.asarray(G_T_B, dtype=float)
    out = {
        name: [transform_points(T, f) for f in box_faces(box)]
        for name, box in robot.base.collision_boxes().items()
    }
    B_T_R = robot.kinematics.link_frames(np.asarray(q, dtype=float))
    for i, link in enumerate(robot.links):
        G_T_R = T @ B_T_R[i]
        out[f"arm_link_{i}"] = [transform_points(G_T_R, f) for f in geometry_faces(link.geometry)]
    return out


def support_polygon_G(robot: Robot, G_T_B: FloatArray | None = None) -> FloatArray:
    """The base's support polygon (n, 3), CCW, lifted by ``SUPPORT_LIFT``, in G (or B) [m]."""
    T = np.eye(4) if G_T_B is None else np.asarray(G_T_B, dtype=float)
    vertices_B = base_polygon(robot).vertices + np.array([0.0, 0.0, SUPPORT_LIFT])
    return transform_points(T, vertices_B)


def mesh_points(meshes: dict[str, list[FloatArray]]) -> FloatArray:
    """All polygon vertices of :func:`robot_meshes` stacked (n, 3) [m] (for axis limits)."""
    return np.concatenate([np.concatenate(faces) for faces in meshes.values()])
