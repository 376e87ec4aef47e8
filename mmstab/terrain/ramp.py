"""The planar ramp and base poses on it (``docs/design.md``, "Frames").

G is the global frame (z up). The slope frame S is G turned by the slope angle about
G's x axis, so +y_S points straight uphill and z_S is the plane normal. A base pose
``(x, y, heading)`` lives in S: ``G_T_B = G_T_S @ Trans(x, y, 0) @ Rot_z(heading)``.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from mmstab.robot import FloatArray, Robot
from mmstab.terrain.base import GRAVITY_G


class BasePose(NamedTuple):
    """A base pose on the slope, in S: position [m] and heading about the normal [rad]."""

    x: float
    y: float
    heading: float


def rot_x(angle: float) -> FloatArray:
    """Rotation about x by ``angle`` [rad]."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_z(angle: float) -> FloatArray:
    """Rotation about z by ``angle`` [rad]."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def wrap_angle(angle: ArrayLike) -> FloatArray:
    """Wrap angles to (-pi, pi] [rad]."""
    a = np.asarray(angle, dtype=float)
    return np.pi - np.mod(np.pi - a, 2 * np.pi)


class Ramp:
    """A planar ramp of slope ``slope`` [rad] about G's x axis (0 = flat floor)."""

    def __init__(self, slope: float):
        self.slope = float(slope)
        self.G_R_S = rot_x(self.slope)

    def G_T_B(self, pose: BasePose | ArrayLike) -> FloatArray:
        """Pose of the body frame in G (4x4) for a base pose in S."""
        x, y, heading = np.asarray(pose, dtype=float)
        T = np.eye(4)
        T[:3, :3] = self.G_R_S @ rot_z(heading)
        T[:3, 3] = self.G_R_S @ np.array([x, y, 0.0])
        return T

    def G_T_S(self) -> FloatArray:
        """Pose of the slope frame in G (4x4); S shares G's origin."""
        T = np.eye(4)
        T[:3, :3] = self.G_R_S
        return T

    def gravity_body(self, headings: ArrayLike) -> FloatArray:
        """Gravity acceleration in the body frame for base headings (N,) -> (N, 3) [m/s^2].

        Position on a plane does not change it; only the heading does.
        """
        h = np.atleast_1d(np.asarray(headings, dtype=float))
        g_S = self.G_R_S.T @ GRAVITY_G  # gravity in S
        c, s = np.cos(h), np.sin(h)
        # B_R_S = Rot_z(heading)^T
        return np.stack(
            [c * g_S[0] + s * g_S[1], -s * g_S[0] + c * g_S[1], np.full_like(h, g_S[2])], axis=1
        )

    def roll_pitch(self, heading: float) -> tuple[float, float]:
        """Roll and pitch of the base [rad] at a heading.

        Positive roll lifts the left side; positive pitch lifts the nose.
        """
        g = self.gravity_body([heading])[0]
        roll = float(np.arctan2(-g[1], -g[2]))
        pitch = float(np.arctan2(-g[0], np.hypot(g[1], g[2])))
        return roll, pitch

    def body_to_slope_sx(self, pose_sx: ca.SX, point_body: Any) -> ca.SX:
        """Symbolic point in S from a point in B: ``Trans(x, y, 0) Rot_z(heading) p``."""
        c, s = ca.cos(pose_sx[2]), ca.sin(pose_sx[2])
        return ca.vertcat(
            pose_sx[0] + c * point_body[0] - s * point_body[1],
            pose_sx[1] + s * point_body[0] + c * point_body[1],
            point_body[2],
        )


class CirclePath(NamedTuple):
    """A circle on the slope: centre in S [m], radius [m], start angle [rad], direction."""

    center: tuple[float, float]
    radius: float
    start_angle: float
    direction: str = "ccw"

    @property
    def sign(self) -> float:
        """+1 for counter-clockwise (seen from above the slope), -1 for clockwise."""
        return 1.0 if self.direction == "ccw" else -1.0

    def pose_at(self, s: ArrayLike) -> FloatArray:
        """Base poses at path fractions ``s`` in [0, 1] -> (N, 3) of (x, y, heading) in S.

        The heading is the path tangent, so the tracks drive forward along the circle.
        """
        s = np.atleast_1d(np.asarray(s, dtype=float))
        phi = self.start_angle + self.sign * 2 * np.pi * s
        x = self.center[0] + self.radius * np.cos(phi)
        y = self.center[1] + self.radius * np.sin(phi)
        heading = phi + self.sign * np.pi / 2
        return np.stack([x, y, heading], axis=1)

    def poses(self, n: int) -> FloatArray:
        """``n`` poses evenly spread over one lap (the first at ``start_angle``) -> (n, 3)."""
        return self.pose_at(np.arange(n) / n)


def _evaluate(f: ca.Function, q: ArrayLike, pose: ArrayLike) -> FloatArray:
    out = f(ca.DM(np.asarray(q, dtype=np.float64)), ca.DM(np.asarray(pose, dtype=np.float64)))
    return np.asarray(out, dtype=np.float64).ravel()


class GlobalCoM(NamedTuple):
    """CasADi Functions of the CoMs in the global frame G on a ramp (paper Eq. 1 and 5).

    Each takes the arm posture ``q`` (4,) [rad] and the base pose ``(x, y, heading)`` in S
    [m, m, rad]; the Jacobians are with respect to ``[q, pose]`` (3x7).

    Attributes:
        arm_com: (q, pose) -> G g_a [m] (Eq. 1: G_T_B applied to the body-frame arm CoM).
        overall_com: (q, pose) -> G g_o [m] (Eq. 5).
        arm_com_jacobian: (q, pose) -> d G g_a / d [q, pose] (3x7).
        overall_com_jacobian: (q, pose) -> d G g_o / d [q, pose] (3x7).
    """

    arm_com: ca.Function
    overall_com: ca.Function
    arm_com_jacobian: ca.Function
    overall_com_jacobian: ca.Function

    def arm(self, q: ArrayLike, pose: ArrayLike) -> FloatArray:
        """G g_a (3,) [m] for one posture and base pose."""
        return _evaluate(self.arm_com, q, pose)

    def overall(self, q: ArrayLike, pose: ArrayLike) -> FloatArray:
        """G g_o (3,) [m] for one posture and base pose."""
        return _evaluate(self.overall_com, q, pose)


def global_com_functions(robot: Robot, ramp: Ramp) -> GlobalCoM:
    """Build the global-frame CoM Functions and their Jacobians (``casadi.jacobian``)."""
    kin = robot.kinematics
    pose = ca.SX.sym("pose", 3)
    G_R_S = ca.DM(ramp.G_R_S)
    arm_G = G_R_S @ ramp.body_to_slope_sx(pose, kin.com_body)
    base_G = G_R_S @ ramp.body_to_slope_sx(pose, ca.DM(robot.base.com))
    overall_G = (robot.arm_mass * arm_G + robot.base.mass * base_G) / robot.total_mass
    x = ca.vertcat(kin.q, pose)
    names = ["q", "pose"]
    return GlobalCoM(
        arm_com=ca.Function("arm_com_G", [kin.q, pose], [arm_G], names, ["com_G"]),
        overall_com=ca.Function("overall_com_G", [kin.q, pose], [overall_G], names, ["com_G"]),
        arm_com_jacobian=ca.Function(
            "arm_com_G_jac", [kin.q, pose], [ca.jacobian(arm_G, x)], names, ["J"]
        ),
        overall_com_jacobian=ca.Function(
            "overall_com_G_jac", [kin.q, pose], [ca.jacobian(overall_G, x)], names, ["J"]
        ),
    )
