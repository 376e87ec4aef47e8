"""Joint position limits over one period: q_min ≤ q + q̇ dt ≤ q_max (the arm joints)."""

from __future__ import annotations

import casadi as ca

from mmstab.control.layout import ARM, SPROCKETS, ControllerParams, Layout
from mmstab.control.limits.base import Bounds, Limit, LimitContext


class JointPositionLimit(Limit):
    """(q_min − q)/dt ≤ q̇ ≤ (q_max − q)/dt on the arm joints; the sprockets turn freely."""

    name = "joint_position"

    def rows(self, layout: Layout) -> tuple[int, int]:
        """The arm joints' rows (the sprockets turn freely)."""
        return (SPROCKETS, layout.joints)

    def bounds(
        self, state: ca.SX, params: ControllerParams, context: LimitContext | None = None
    ) -> Bounds:
        """Bounds on the arm joints (n,) [rad/s]."""
        q_arm = state[ARM]
        return Bounds((params.q_min - q_arm) / params.dt, (params.q_max - q_arm) / params.dt)
