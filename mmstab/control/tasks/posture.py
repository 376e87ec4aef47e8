"""The posture task: the arm joints toward a posture (as pink's and mink's ``PostureTask``)."""

from __future__ import annotations

import casadi as ca

from mmstab.control.layout import ARM, SPROCKETS
from mmstab.control.tasks.base import Slot, Task, TaskSlots
from mmstab.control.tasks.model import TaskModel


class PostureTask(Task):
    """q_arm → q_ref: the arm's redundant directions (3 CoM rows, n arm joints).

    No wrap: q_ref is in limit coordinates. With small weights (well under the CoM rows') the
    CoM task dominates and this only chooses the remaining arm direction.
    """

    name = "posture"
    slots = TaskSlots(
        Slot("q_ref"), Slot("q_dot_ref"), Slot("posture_gain"), Slot("posture_weight")
    )

    def rows(self, model: TaskModel) -> int:
        """n: one row per arm joint (``model.layout.arm``)."""
        return model.layout.arm

    def value(self, model: TaskModel) -> ca.SX:
        """q_arm (n,) [rad]."""
        return model.state[ARM]

    def jacobian(self, model: TaskModel) -> ca.SX:
        """S (n, 2 + n): selects the arm columns of q̇."""
        n = self.rows(model)
        return ca.horzcat(ca.SX.zeros(n, SPROCKETS), ca.SX.eye(n))
