"""The controller's tasks, pink-style: each with its value, error and Jacobian (CasADi).

A task (:class:`Task`) is a quantity of the robot the controller drives toward a target at a
desired rate ``v = K e + f ṙ_ref`` (gain K, error e = target − value, feed-forward f ṙ_ref);
its QP objective is ½‖v − J q̇‖²_W (J: its Jacobian with respect to the joint speeds q̇, W:
its weights), i.e. H = Jᵀ W J, g = −Jᵀ W v (:meth:`Task.objective`). The tasks of the paper's
Eq. 7 plus the posture task:

- :class:`BasePointTask`: the base control point (x, y) and the heading (3 rows, heading
  error wrapped);
- :class:`ArmCoMTask`: the arm CoM in the map frame (3 rows);
- :class:`PostureTask`: the arm joints toward a posture (one row per arm joint; the redundant
  arm directions).

Every task reads the robot through :class:`TaskModel`: the symbolic state, the local ground,
the track kinematics B(γ) and the one placement of body points (:mod:`mmstab.terrain`). The
QP is assembled from the tasks and the limits (:mod:`mmstab.control.limits`) by
:func:`mmstab.control.controller.qp.build_qp`.
"""

from mmstab.control.tasks.arm_com import ArmCoMTask
from mmstab.control.tasks.base import Task, TaskObjective, TaskTarget
from mmstab.control.tasks.base_point import BasePointTask
from mmstab.control.tasks.model import TaskModel
from mmstab.control.tasks.posture import PostureTask

__all__ = [
    "ArmCoMTask",
    "BasePointTask",
    "PostureTask",
    "Task",
    "TaskModel",
    "TaskObjective",
    "TaskTarget",
]
