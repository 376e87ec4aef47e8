"""The arm-CoM task: the arm's centre of mass in the map frame (paper Eq. 7)."""

from __future__ import annotations

import casadi as ca

from mmstab.control.tasks.base import Slot, Task, TaskSlots
from mmstab.control.tasks.model import TaskModel


class ArmCoMTask(Task):
    """[g_ax, g_ay, g_az] = place(pose, ground, g_a^B(q_arm)) in M [m]."""

    name = "arm_com"
    size = 3
    slots = TaskSlots(
        Slot("xi_des", (3, 6)), Slot("xi_dot_ref", (3, 6)), Slot("kp", (3, 6)), Slot("w_a", (3, 6))
    )

    def value(self, model: TaskModel) -> ca.SX:
        """g_a^M (3,) [m]."""
        return model.place(model.com_body)

    def jacobian(self, model: TaskModel) -> ca.SX:
        """(3, 2 + n): through the base pose (tracks) and the arm joints."""
        return model.rate_jacobian(self.value(model))
