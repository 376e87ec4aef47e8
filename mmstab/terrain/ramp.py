"""The planar ramp and base poses on it (``docs/design.md``, "Frames").

G is the global frame (z up). The slope frame S is G turned by the slope angle about
G's x axis, so +y_S points straight uphill and z_S is the plane normal. S is the ramp's map
frame M: a base pose ``(x, y, yaw)`` lives in S, the body rests on the plane
(``M_T_B = Trans(x, y, 0) Rot_z(yaw)``, local ground zero) and
``G_T_B = G_T_S @ M_T_B``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, NamedTuple

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial import ConvexHull

from mmstab.terrain.base import (
    DEFAULT_FRICTION,
    GRAVITY_G,
    GROUND_SIZE,
    FloatArray,
    Support,
    as_poses,
    local_transforms,
    place_local,
    place_local_sx,
    rot_x,
)

if TYPE_CHECKING:
    from mmstab.model.robot import Robot


class BasePose(NamedTuple):
    """A base pose on the slope, in S: position [m] and heading about the normal [rad]."""

    x: float
    y: float
    heading: float


def _single(poses: ArrayLike, batched: FloatArray) -> FloatArray:
    return batched[0] if np.ndim(poses) == 1 else batched


def ordered_polygon(points_B: FloatArray) -> FloatArray:
    """The convex hull of body-frame points on z_B = const, ordered CCW about +z_B."""
    hull = ConvexHull(points_B[:, :2])
    return points_B[hull.vertices]  # a 2-D hull is counter-clockwise


class Ramp:
    """A planar ramp of slope ``slope`` [rad] about G's x axis (0 = flat floor).

    Implements :class:`mmstab.terrain.Terrain` with the map frame M = the slope frame S.
    """

    kind = "ramp"

    def __init__(self, slope: float, friction: float = DEFAULT_FRICTION):
        self.slope = float(slope)
        self.friction = float(friction)  # tracks on the ground, Coulomb [-]
        self.G_R_S = rot_x(self.slope)

    @property
    def label(self) -> str:
        """``ramp, slope 5.7 deg``."""
        return f"ramp, slope {np.degrees(self.slope):.1f} deg"

    def G_T_M(self) -> FloatArray:
        """Pose of the slope frame S = M in G (4x4); S shares G's origin."""
        T = np.eye(4)
        T[:3, :3] = self.G_R_S
        return T

    def local_ground(self, poses: ArrayLike) -> FloatArray:
        """Zero: the body rests on the plane z_S = 0, level with S (N, 3)."""
        return np.zeros((len(as_poses(poses)), GROUND_SIZE))

    def M_T_B(self, poses: ArrayLike) -> FloatArray:
        """``Trans(x, y, 0) Rot_z(yaw)``: (4, 4) for one pose, (N, 4, 4) for many."""
        P = as_poses(poses)
        return _single(poses, local_transforms(P, self.local_ground(P)))

    def G_T_B(self, poses: ArrayLike) -> FloatArray:
        """``G_T_S M_T_B``: (4, 4) for one pose, (N, 4, 4) for many."""
        return self.G_T_M() @ self.M_T_B(poses)

    def gravity_body(self, poses: ArrayLike) -> FloatArray:
        """Gravity in the body frame at poses (N, 3) [m/s^2]; only the yaw changes it."""
        P = as_poses(poses)
        R = local_transforms(P, self.local_ground(P))[:, :3, :3]
        g_S = self.G_R_S.T @ GRAVITY_G
        return np.einsum("nji,j->ni", R, g_S)

    def place(self, poses: ArrayLike, points_body: ArrayLike) -> FloatArray:
        """Body points placed in S at poses (N, 3) [m] (:func:`place_local`)."""
        P = as_poses(poses)
        return place_local(P, self.local_ground(P), points_body).points

    def place_sx(self, pose: ca.SX, point_body: Any) -> ca.SX:
        """Symbolic ``Trans(x, y, 0) Rot_z(yaw) p`` (:func:`place_local_sx`, zero ground)."""
        return place_local_sx(pose, ca.DM.zeros(GROUND_SIZE), point_body)

    def with_robot(
        self, robot: Robot, flipper_angle: float | None = None, arm_q: ArrayLike | None = None
    ) -> Ramp:
        """The ramp under ``robot``: the body lies on the plane whatever its load.

        Raises:
            MmstabError: flippers (at ``flipper_angle`` [rad], default the robot's) that
                reach into the plane, which a rigid base on a plane cannot have.
        """
        from mmstab.core.files import MmstabError
        from mmstab.model.robot import FLIPPER_CONTACT_TOL, with_flipper_angle

        if flipper_angle is not None:
            robot = with_flipper_angle(robot, flipper_angle)
        for prefix, pair in robot.base.flipper_pairs().items():
            lowest = pair.lowest()
            if lowest < -FLIPPER_CONTACT_TOL:
                raise MmstabError(
                    f"flipper angle {pair.angle:g} rad: the {prefix.replace('_', ' ')}s reach "
                    f"{-lowest:.3f} m into the ramp; raise them"
                )
        return self

    def support(self, robot: Robot, pose: ArrayLike, com_body: ArrayLike | None = None) -> Support:
        """Every contact of the base touches the plane; the polygon is their hull, CCW about z_B.

        Whatever the load (``com_body`` is not needed): the body lies on the plane.
        """
        T = self.G_T_B(np.asarray(pose, dtype=float).reshape(3))
        pts = np.asarray(robot.base.support_points(), dtype=float)
        to_G = lambda p: p @ T[:3, :3].T + T[:3, 3]  # noqa: E731
        return Support(T, to_G(pts), to_G(ordered_polygon(pts)))

    @property
    def bounds(self) -> None:
        """None: the plane has no edge."""
        return None

    def surface_G(self, x: ArrayLike, y: ArrayLike) -> FloatArray:
        """Points of the plane in G under S coordinates (x, y) [m], (..., 3)."""
        xb, yb = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        return np.stack([xb, yb, np.zeros_like(xb)], axis=-1) @ self.G_R_S.T
