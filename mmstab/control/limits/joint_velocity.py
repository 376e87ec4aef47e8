"""Joint speed limits: |q̇| ≤ q̇_max."""

from __future__ import annotations

import casadi as ca

from mmstab.control.layout import ControllerParams
from mmstab.control.limits.base import Bounds, Limit, LimitContext


class JointVelocityLimit(Limit):
    """−q̇_max ≤ q̇ ≤ q̇_max for every joint (``params.qdot_max``, sprockets then the arm)."""

    name = "joint_velocity"

    def bounds(
        self, state: ca.SX, params: ControllerParams, context: LimitContext | None = None
    ) -> Bounds:
        """(−q̇_max, q̇_max) (2 + n,) [rad/s]."""
        return Bounds(-params.qdot_max, params.qdot_max)
