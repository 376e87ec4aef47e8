"""The drop tests' rigid body: its collision shapes and mass properties (in B).

The collision geometry is exactly the one the terrain's contact model uses (tracks as a box
and two end cylinders each, the flippers at their angle, the chassis), and the mass is the
robot's total at its overall CoM with the arm's links as point masses
(:mod:`mmstab.physics.mujoco_drop`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.model.robot import Box, FloatArray, Robot, with_flipper_angle


class CollisionGeom(NamedTuple):
    """One collision shape in B, posed by ``B_T_geom`` (4, 4).

    ``kind`` is ``"box"`` (``size`` = full edge lengths [m]) or ``"cylinder"`` (``size`` =
    (radius, length) [m], axis = the shape's z).
    """

    name: str
    kind: str
    size: FloatArray
    B_T_geom: FloatArray


class MassProperties(NamedTuple):
    """Rigid-body mass [kg], CoM in B (3,) [m] and inertia about the CoM in B (3, 3) [kg m^2]."""

    mass: float
    com_body: FloatArray
    inertia_body: FloatArray


def pose_matrix(rotation: ArrayLike, center: ArrayLike) -> FloatArray:
    """The 4x4 pose of a rotation (3, 3) and a centre (3,) [m]."""
    T = np.eye(4)
    T[:3, :3] = rotation
    T[:3, 3] = center
    return T


def _box_geom(name: str, box: Box) -> CollisionGeom:
    return CollisionGeom(name, "box", np.asarray(box.size, float), box.frame_T_shape)


def collision_geoms(robot: Robot, flipper_angle: float | None = None) -> list[CollisionGeom]:
    """The base's collision shapes in B (tracks, sprockets/idlers, flippers, chassis).

    Args:
        robot: the robot.
        flipper_angle: flipper angle [rad] (positive raises the tip); None = the robot's.
    """
    if flipper_angle is not None:
        robot = with_flipper_angle(robot, flipper_angle)
    base = robot.base
    t = base.tracks
    r = t.height / 2
    axis_y = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # z -> y
    geoms: list[CollisionGeom] = []
    for side, sign in (("left", 1.0), ("right", -1.0)):
        geoms.append(_box_geom(f"track_{side}", t.box(side)))  # type: ignore[arg-type]
        for end, sx in (("front", 1.0), ("rear", -1.0)):
            c = np.array([sx * t.length / 2, sign * t.separation / 2, r])
            geoms.append(
                CollisionGeom(
                    f"wheel_{side}_{end}",
                    "cylinder",
                    np.array([r, t.width]),
                    pose_matrix(axis_y, c),
                )
            )
        for prefix, pair in base.flipper_pairs().items():
            geoms.append(_box_geom(f"{prefix}_{side}", pair.box(side)))  # type: ignore[arg-type]
    geoms.append(_box_geom("chassis", base.body))
    return geoms


def mass_properties(robot: Robot, arm_posture: ArrayLike | None = None) -> MassProperties:
    """Total mass, overall CoM and a reasonable inertia of the robot as one rigid body.

    The base is a uniform box (the tracks' outline) of the base mass centred at its CoM;
    each arm link is a point mass at its CoM at the posture (stowed by default).

    Args:
        robot: the robot.
        arm_posture: arm joint angles (4,) [rad]; None = ``robot.stowed``.
    """
    q = robot.stowed if arm_posture is None else np.asarray(arm_posture, dtype=float)
    t = robot.base.tracks
    dims = np.array([t.length + t.height, t.separation + t.width, t.height])
    m_b = robot.base.mass
    link_coms = robot.kinematics.link_coms(q)  # (4, 3) in B
    link_masses = np.array([link.mass for link in robot.links])
    com = (m_b * robot.base.com + link_masses @ link_coms) / (m_b + link_masses.sum())

    def shifted(mass: float, r: FloatArray) -> FloatArray:
        return mass * (float(r @ r) * np.eye(3) - np.outer(r, r))

    inertia = np.diag(m_b / 12 * (dims @ dims - dims**2))
    inertia = inertia + shifted(m_b, robot.base.com - com)
    for m, c in zip(link_masses, link_coms, strict=True):
        inertia = inertia + shifted(float(m), c - com)
    return MassProperties(float(m_b + link_masses.sum()), com, inertia)


def surface_points(geoms: list[CollisionGeom], spacing: float = 0.02) -> FloatArray:
    """Points on the collision shapes' surfaces in B (n, 3) [m], about ``spacing`` apart."""
    pts = []
    for g in geoms:
        if g.kind == "box":
            axes = [
                np.linspace(-h, h, max(2, int(np.ceil(2 * h / spacing)) + 1)) for h in g.size / 2
            ]
            grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
            on_face = np.any(np.isclose(np.abs(grid), g.size / 2), axis=1)
            local = grid[on_face]
        else:
            r, length = g.size
            a = np.linspace(
                0, 2 * np.pi, max(8, int(np.ceil(2 * np.pi * r / spacing))), endpoint=False
            )
            z = np.linspace(-length / 2, length / 2, max(2, int(np.ceil(length / spacing)) + 1))
            A, Z = np.meshgrid(a, z, indexing="ij")
            local = np.stack([r * np.cos(A), r * np.sin(A), Z], -1).reshape(-1, 3)
        pts.append(local @ g.B_T_geom[:3, :3].T + g.B_T_geom[:3, 3])
    return np.concatenate(pts)
