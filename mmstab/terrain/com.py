"""The CoMs in the global frame G for a base pose on any terrain (paper Eq. 1 and 5)."""

from __future__ import annotations

from typing import NamedTuple

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from mmstab.model.robot import FloatArray, Robot
from mmstab.terrain.base import Terrain


def _evaluate(f: ca.Function, q: ArrayLike, pose: ArrayLike) -> FloatArray:
    out = f(ca.DM(np.asarray(q, dtype=np.float64)), ca.DM(np.asarray(pose, dtype=np.float64)))
    return np.asarray(out, dtype=np.float64).ravel()


class GlobalCoM(NamedTuple):
    """CasADi Functions of the CoMs in the global frame G on a terrain (paper Eq. 1 and 5).

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


def global_com_functions(robot: Robot, terrain: Terrain) -> GlobalCoM:
    """Build the global-frame CoM Functions and their Jacobians (``casadi.jacobian``)."""
    kin = robot.kinematics
    pose = ca.SX.sym("pose", 3)
    G_T_M = terrain.G_T_M()
    G_R_M, G_p_M = ca.DM(G_T_M[:3, :3]), ca.DM(G_T_M[:3, 3])
    arm_G = G_p_M + G_R_M @ terrain.place_sx(pose, kin.com_body)
    base_G = G_p_M + G_R_M @ terrain.place_sx(pose, ca.DM(robot.base.com))
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
