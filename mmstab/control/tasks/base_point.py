"""The base task: the control point ahead of the body origin, and the heading."""

from __future__ import annotations

from typing import Any

import casadi as ca

from mmstab.control.tasks.base import Slot, Task, TaskSlots
from mmstab.control.tasks.model import TaskModel


class BasePointTask(Task):
    """[g_bx, g_by, γ]: the point ``offset`` d ahead of the body origin, in M, and the heading.

    g_b = place(pose, ground, [d, 0, 0])[:2] (on the ramp [x, y] + d [cos γ, sin γ]); the
    heading error is wrapped to (−π, π]. For d > 0 the point's rows have full rank in the
    two track speeds (the look-ahead point of differential-drive tracking).
    """

    name = "base_point"
    size = 3
    slots = TaskSlots(
        Slot("xi_des", (0, 3)), Slot("xi_dot_ref", (0, 3)), Slot("kp", (0, 3)), Slot("w_a", (0, 3))
    )

    def __init__(self, offset: float):
        self.offset = float(offset)

    @classmethod
    def from_settings(cls, settings: Any) -> BasePointTask:
        """The point ``settings.base_offset`` [m] ahead of the body origin."""
        return cls(settings.base_offset)

    def value(self, model: TaskModel) -> ca.SX:
        """[g_bx, g_by, γ] (3,) [m, m, rad]."""
        point = model.place(ca.SX(ca.vertcat(self.offset, 0, 0)))
        return ca.vertcat(point[:2], model.state[2])

    def jacobian(self, model: TaskModel) -> ca.SX:
        """(3, 2 + n): the track columns only (the arm does not move the base)."""
        return model.rate_jacobian(self.value(model))

    def error(self, model: TaskModel, target: Any) -> ca.SX:
        """Target − value, the heading row wrapped to (−π, π]."""
        e = target - self.value(model)
        # e − 2π·ceil(e/2π − ½): the wrap of atan2(sin e, cos e) up to round-off, one ceil
        # where that took a sincos and an atan2 (the step's costliest calls)
        e[2] = e[2] - 2 * ca.pi * ca.ceil(e[2] / (2 * ca.pi) - 0.5)
        return e
