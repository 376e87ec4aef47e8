"""The posture task: the arm joints toward a posture (as pink's and mink's ``PostureTask``)."""

from __future__ import annotations

import casadi as ca

from mmstab.control.layout import ARM, ARM_JOINTS, JOINT_COUNT
from mmstab.control.tasks.base import Task
from mmstab.control.tasks.model import TaskModel


class PostureTask(Task):
    """q_arm → q_ref: the arm's redundant direction (3 CoM rows, 4 arm joints).

    No wrap: q_ref is in limit coordinates. With small weights (well under the CoM rows') the
    CoM task dominates and this only chooses the remaining arm direction.
    """

    size = ARM_JOINTS

    def value(self, model: TaskModel) -> ca.SX:
        """q_arm (4,) [rad]."""
        return model.state[ARM]

    def jacobian(self, model: TaskModel) -> ca.SX:
        """S (4, 6): selects the arm columns of q̇."""
        return ca.horzcat(ca.SX.zeros(ARM_JOINTS, JOINT_COUNT - ARM_JOINTS), ca.SX.eye(ARM_JOINTS))
