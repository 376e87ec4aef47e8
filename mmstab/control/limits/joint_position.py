"""Joint position limits over one period: q_min ≤ q + q̇ dt ≤ q_max (the arm joints)."""

from __future__ import annotations

import casadi as ca

from mmstab.control.layout import ARM, SPROCKETS, ControllerParams
from mmstab.control.limits.base import Bounds, Limit


class JointPositionLimit(Limit):
    """(q_min − q)/dt ≤ q̇ ≤ (q_max − q)/dt on the arm joints; the sprockets turn freely."""

    def bounds(self, state: ca.SX, params: ControllerParams) -> Bounds:
        """Bounds (2 + n,) [rad/s]; ±inf on the sprockets."""
        q_arm = state[ARM]
        inf = ca.DM.ones(SPROCKETS) * ca.inf
        return Bounds(
            ca.vertcat(-inf, (params.q_min - q_arm) / params.dt),
            ca.vertcat(inf, (params.q_max - q_arm) / params.dt),
        )
