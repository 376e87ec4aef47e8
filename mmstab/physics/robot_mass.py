"""Rigid-body mass properties for the MuJoCo robot model: parts, shifts and differences.

An :class:`Inertial` is a body's mass, CoM and inertia about the CoM in one frame. The robot
model (:mod:`mmstab.physics.robot_model`) takes its parts' inertias from mmstab's URDF
export (:mod:`mmstab.model.urdf`), places them with :meth:`Inertial.moved`, takes the road
wheels out of their track with :func:`minus`, and writes each body's principal moments and
axes with :func:`principal`, so that MuJoCo stores exactly the numbers computed here.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from mmstab.model.robot import FloatArray


def point_inertia(mass: float, r: FloatArray) -> FloatArray:
    """Inertia of a point mass ``mass`` [kg] at ``r`` (3,) [m] about the origin (3, 3)."""
    return mass * (float(r @ r) * np.eye(3) - np.outer(r, r))


class Inertial(NamedTuple):
    """A body's mass [kg], CoM (3,) [m] and inertia about the CoM (3, 3) [kg m^2], one frame."""

    mass: float
    com: FloatArray
    tensor: FloatArray

    def moved(self, T: FloatArray) -> Inertial:
        """The same body seen from a frame in which this one's frame sits at ``T`` (4, 4)."""
        R = np.asarray(T, dtype=float)[:3, :3]
        return Inertial(self.mass, R @ self.com + T[:3, 3], R @ self.tensor @ R.T)

    def about_origin(self) -> FloatArray:
        """Inertia about the frame's origin (3, 3) (parallel-axis theorem)."""
        return self.tensor + point_inertia(self.mass, self.com)


def inertial_of(mass: float, frame_T_com: FloatArray, tensor: FloatArray) -> Inertial:
    """An :class:`Inertial` from a CoM frame ``frame_T_com`` (4, 4) and the tensor in its axes."""
    return Inertial(float(mass), np.zeros(3), np.asarray(tensor, dtype=float)).moved(frame_T_com)


def minus(whole: Inertial, parts: list[Inertial]) -> Inertial:
    """What is left of ``whole`` without ``parts`` (all in one frame).

    Raises:
        ValueError: the remainder has no mass, or an inertia no rigid body has.
    """
    mass = whole.mass - sum(p.mass for p in parts)
    if mass <= 0:
        raise ValueError("the parts weigh as much as the whole")
    com = (whole.mass * whole.com - sum(p.mass * p.com for p in parts)) / mass
    origin = whole.about_origin() - sum(p.about_origin() for p in parts)
    rest = Inertial(mass, com, origin - point_inertia(mass, com))
    principal = np.linalg.eigvalsh(rest.tensor)
    if principal[0] <= 0 or principal[0] + principal[1] < principal[2] * (1 - 1e-12):
        raise ValueError(f"not a rigid body's inertia: principal moments {principal}")
    return rest


def principal(tensor: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Principal moments (3,) [kg m^2] and axes (3, 3) (columns, a proper rotation)."""
    moments, axes = np.linalg.eigh(np.asarray(tensor, dtype=float))
    if np.linalg.det(axes) < 0:
        axes[:, 2] = -axes[:, 2]
    return np.maximum(moments, 0.0), axes


class Wheels(NamedTuple):
    """One track's road wheels (solid cylinders, axle along y) in the track box's frame.

    Attributes:
        x: wheel centres along x (n,) [m] (at the box's centre height = the wheel radius).
        radius: [m] (half the track height: the outline's end circles).
        width: [m] (the track's width).
        mass: each wheel's mass [kg].
    """

    x: FloatArray
    radius: float
    width: float
    mass: float

    def inertial(self, k: int) -> Inertial:
        """Wheel ``k`` in the track box's frame."""
        r, w, m = self.radius, self.width, self.mass
        across = m * (3 * r**2 + w**2) / 12
        return Inertial(m, np.array([self.x[k], 0.0, 0.0]), np.diag([across, m * r**2 / 2, across]))
