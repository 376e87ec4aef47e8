"""The controller's tasks, pink-style: each with its value, error and Jacobian (CasADi).

A task (:class:`Task`) is a quantity of the robot the controller drives toward a target at a
desired rate ``v = K e + f ṙ_ref`` (gain K, error e = target − value, feed-forward f ṙ_ref);
its QP objective is ½‖v − J q̇‖²_W (J: its Jacobian with respect to the joint speeds q̇, W:
its weights), i.e. H = Jᵀ W J, g = −Jᵀ W v (:meth:`Task.objective`). It declares where its
target sits in the step's packed reference and parameters (:class:`TaskSlots`). The tasks of
the paper's Eq. 7 plus the posture task:

- :class:`BasePointTask`: the base control point (x, y) and the heading (3 rows, heading
  error wrapped);
- :class:`ArmCoMTask`: the arm CoM in the map frame (3 rows);
- :class:`ArmCoMBodyTask`: the arm CoM in the body frame (3 rows, the same slots), in its
  place with ``controller.arm_com_frame: body`` (:func:`controller_task_names`);
- :class:`PostureTask`: the arm joints toward a posture (one row per arm joint; the redundant
  arm directions).

Every task reads the robot through :class:`TaskModel`: the symbolic state, the local ground,
the track kinematics B(γ) and the one placement of body points (:mod:`mmstab.terrain`). The
QP is assembled by looping over the tasks and the limits (:mod:`mmstab.control.limits`) in
:func:`mmstab.control.controller.qp.build_qp`.

**The registry.** :data:`TASKS` names every task; :data:`DEFAULT_TASKS` is the controller's
list, in the order their objectives are summed (:func:`controller_task_names`: the list a
problem's ``controller:`` settings select). Adding a task is one module of this package
(a :class:`Task` subclass with its ``name``, rows, value, Jacobian and slots) and its class in
:data:`TASKS` (``docs/controller.md``, "Adding a controller task").
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from mmstab.control.tasks.arm_com import ArmCoMTask
from mmstab.control.tasks.arm_com_body import ArmCoMBodyTask
from mmstab.control.tasks.base import Slot, Task, TaskObjective, TaskSlots, TaskTarget, task_map
from mmstab.control.tasks.base_point import BasePointTask
from mmstab.control.tasks.model import TaskModel
from mmstab.control.tasks.posture import PostureTask
from mmstab.model.robot import Robot

#: Every task, by name (each built from the ``controller:`` settings by ``from_settings``).
TASKS: dict[str, type[Task]] = {
    cls.name: cls
    for cls in (
        BasePointTask,
        ArmCoMTask,
        ArmCoMBodyTask,
        PostureTask,
    )
}
#: The controller's tasks, in the order their objectives are summed (the numbers depend on it).
DEFAULT_TASKS: tuple[str, ...] = ("base_point", "arm_com", "posture")
#: The arm-CoM task of each ``controller.arm_com_frame``: map M (paper Eq. 7) or body B.
ARM_COM_TASKS: dict[str, str] = {"map": ArmCoMTask.name, "body": ArmCoMBodyTask.name}


def controller_task_names(settings: Any) -> tuple[str, ...]:
    """:data:`DEFAULT_TASKS` with the arm-CoM task of ``settings.arm_com_frame``.

    Raises:
        ValueError: a frame not in :data:`ARM_COM_TASKS`.
    """
    frame = settings.arm_com_frame
    if frame not in ARM_COM_TASKS:
        raise ValueError(f"unknown arm_com_frame {frame!r}; choose one of {list(ARM_COM_TASKS)}")
    swap = {ArmCoMTask.name: ARM_COM_TASKS[frame]}
    return tuple(swap.get(name, name) for name in DEFAULT_TASKS)


def build_tasks(settings: Any, names: Sequence[str] | None = None) -> list[Task]:
    """The named tasks (:data:`TASKS`) built from the ``controller:`` settings.

    Args:
        settings: the ``controller:`` settings.
        names: the tasks, in order (default :func:`controller_task_names` of ``settings``).

    Raises:
        ValueError: a name not in :data:`TASKS`.
    """
    names = controller_task_names(settings) if names is None else names
    unknown = [n for n in names if n not in TASKS]
    if unknown:
        raise ValueError(f"unknown controller tasks {unknown}; registered: {', '.join(TASKS)}")
    return [TASKS[n].from_settings(settings) for n in names]


def build_task_model(robot: Robot, base_offset: float) -> TaskModel:
    """The model with the default task map ξ: the base point ``base_offset`` [m] ahead, arm CoM."""
    return TaskModel(robot, task_map([BasePointTask(base_offset), ArmCoMTask()]))


__all__ = [
    "ARM_COM_TASKS",
    "DEFAULT_TASKS",
    "TASKS",
    "ArmCoMBodyTask",
    "ArmCoMTask",
    "BasePointTask",
    "PostureTask",
    "Slot",
    "Task",
    "TaskModel",
    "TaskObjective",
    "TaskSlots",
    "TaskTarget",
    "build_task_model",
    "build_tasks",
    "controller_task_names",
    "task_map",
]
