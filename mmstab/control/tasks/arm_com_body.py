"""The arm-CoM task in the body frame B: the arm's centre of mass relative to the base.

The controller's ``arm_com_frame: body`` (``docs/controller.md``). Where :class:`ArmCoMTask`
tracks g_a^M, which moves with the base pose, this task tracks g_a^B(q_arm) only: a base that
lags its reference (tracks skidding on a side slope) does not make the arm chase a map point,
and the CoM stays where the planner put it relative to the support, which is what stability
depends on.
"""

from __future__ import annotations

import casadi as ca

from mmstab.control.layout import ARM, SPROCKETS
from mmstab.control.tasks.arm_com import ArmCoMTask
from mmstab.control.tasks.model import TaskModel


class ArmCoMBodyTask(ArmCoMTask):
    """[g_ax, g_ay, g_az] = g_a^B(q_arm) in B [m]; the slots of :class:`ArmCoMTask`."""

    name = "arm_com_body"

    def value(self, model: TaskModel) -> ca.SX:
        """g_a^B (3,) [m]."""
        return model.com_body

    def jacobian(self, model: TaskModel) -> ca.SX:
        """(3, 2 + n) [m/rad]: zero for the sprockets, ∂g_a^B/∂q_arm for the arm joints."""
        arm = ca.jacobian(model.com_body, model.state[ARM])
        return ca.horzcat(ca.SX.zeros(3, SPROCKETS), arm)
