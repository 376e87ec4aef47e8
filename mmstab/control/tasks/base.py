"""The task interface (as pink's ``Task``): value, error, Jacobian, slots, QP objective.

A task reads its target from the step's packed inputs (:mod:`mmstab.control.layout`): it
declares which rows of which fields of :class:`~mmstab.control.layout.StepReference` and
:class:`~mmstab.control.layout.ControllerParams` it reads (:class:`TaskSlots`), and
:meth:`Task.target` reads them. The packed order is the layout's; a task only points into it.
"""

from __future__ import annotations

import abc
from collections.abc import Sequence
from typing import Any, NamedTuple

import casadi as ca

from mmstab.control.layout import TASK_SIZE, ControllerParams, StepReference
from mmstab.control.tasks.model import TaskModel


class TaskTarget(NamedTuple):
    """What a task tracks at one step (CasADi expressions).

    Attributes:
        value: the target (m,) [task units].
        rate: its rate (m,), the feed-forward [task units/s].
        gain: the gains K (m,) [1/s].
        weight: the weights W (m,) [-].
        feedforward: 1 to add the rate, 0 not to.
    """

    value: Any
    rate: Any
    gain: Any
    weight: Any
    feedforward: Any


class Slot(NamedTuple):
    """Rows of one field of the step's packed reference or parameters.

    Attributes:
        field: a :class:`StepReference` or :class:`ControllerParams` field name.
        rows: its rows the task reads (start, stop); None: the whole field.
    """

    field: str
    rows: tuple[int, int] | None = None

    def read(self, reference: StepReference, params: ControllerParams) -> Any:
        """The slot's rows of the unpacked reference or parameters (CasADi or NumPy)."""
        packed = reference if self.field in StepReference._fields else params
        x = getattr(packed, self.field)
        return x if self.rows is None else x[self.rows[0] : self.rows[1]]

    def describe(self) -> str:
        """``field`` or ``field[a:b]``, for the C header's comments and the docs."""
        return self.field if self.rows is None else f"{self.field}[{self.rows[0]}:{self.rows[1]}]"


class TaskSlots(NamedTuple):
    """Where a task's target sits in the packed step inputs (:class:`TaskTarget`'s parts).

    Attributes:
        value: the target's slot (None: the task computes it, :meth:`Task.target`).
        rate: the target rate's slot (None: zero, or the task computes it).
        gain: the gains' slot [1/s].
        weight: the weights' slot.
    """

    value: Slot | None
    rate: Slot | None
    gain: Slot
    weight: Slot


class TaskObjective(NamedTuple):
    """A task's share of the QP: ½ q̇ᵀ H q̇ + gᵀ q̇ + cost0, and the rate it asks for.

    Attributes:
        H: Hessian (2 + n, 2 + n), n the arm's joints.
        g: gradient (2 + n,).
        cost0: the constant (the cost at q̇ = 0).
        rate: the desired task rate v = K e + f ṙ_ref (m,).
    """

    H: Any
    g: Any
    cost0: Any
    rate: Any


class Task(abc.ABC):
    """A task of the controller: a quantity of the robot with a target (pink's ``Task``)."""

    #: The task's name in the registry (:data:`mmstab.control.tasks.TASKS`).
    name: str
    #: Number of rows (tasks whose rows depend on the robot override :meth:`rows`).
    size: int
    #: Where the target sits in the packed reference and parameters.
    slots: TaskSlots

    @classmethod
    def from_settings(cls, settings: Any) -> Task:
        """The task from the ``controller:`` settings (those without settings: ``cls()``)."""
        return cls()

    def target(self, reference: StepReference, params: ControllerParams) -> TaskTarget:
        """The target at one step, read from the slots (:attr:`slots`); feed-forward ``f``.

        A slot of None reads as None (the value: the overriding task fills it in) or 0 (the rate).
        """
        value, rate, gain, weight = (
            None if slot is None else slot.read(reference, params) for slot in self.slots
        )
        return TaskTarget(value, 0.0 if rate is None else rate, gain, weight, params.feedforward)

    def rows(self, model: TaskModel) -> int:
        """Number of rows for the model's robot (``size`` unless the task says otherwise)."""
        return self.size

    @abc.abstractmethod
    def value(self, model: TaskModel) -> ca.SX:
        """The task's value at the model's state and ground (size,)."""

    @abc.abstractmethod
    def jacobian(self, model: TaskModel) -> ca.SX:
        """D value / dt = J q̇: J (rows, 2 + n), with respect to the joint speeds."""

    def error(self, model: TaskModel, target: Any) -> ca.SX:
        """Target − value (size,); angular rows wrap it where the task says so."""
        return target - self.value(model)

    def objective(self, model: TaskModel, target: TaskTarget) -> TaskObjective:
        """½‖v − J q̇‖²_W with v = K e + f ṙ_ref: H = Jᵀ W J, g = −Jᵀ W v, cost0 = ½ vᵀ W v.

        Raises:
            TypeError: a target without a value (no value slot, and ``target`` not overridden).
        """
        if target.value is None:
            raise TypeError(f"task {self.name!r} has no value slot: it must override target()")
        rate = target.gain * self.error(model, target.value) + target.feedforward * target.rate
        J = self.jacobian(model)
        JtW = J.T @ ca.diag(target.weight)
        return TaskObjective(
            weighted_gram(J, target.weight),
            -JtW @ rate,
            0.5 * ca.dot(rate, target.weight * rate),
            rate,
        )


def weighted_gram(J: ca.SX, weight: Any) -> ca.SX:
    """Jᵀ diag(weight) J, each off-diagonal entry computed once and used for both triangles.

    (``J.T @ W @ J`` builds H[i, j] and H[j, i] as two expressions: twice the work in the step.)
    """
    n = J.size2()
    Jw = J * ca.repmat(weight, 1, n)  # rows scaled by the weights
    entries: dict[tuple[int, int], ca.SX] = {}
    for i in range(n):
        for j in range(i, n):
            entries[i, j] = ca.dot(Jw[:, i], J[:, j])
    rows = [ca.horzcat(*(entries[min(i, j), max(i, j)] for j in range(n))) for i in range(n)]
    return ca.vertcat(*rows)


def _xi_rows(task: Task) -> tuple[int, int] | None:
    """The rows of ξ_des a task's target takes (None: its target is not in ξ_des)."""
    value = task.slots.value
    if value is None or value.field != "xi_des":
        return None
    return value.rows or (0, TASK_SIZE)


def task_map(tasks: Sequence[Task]) -> tuple[Task, ...]:
    """The tasks whose targets are rows of ξ_des, in row order: their values stacked are ξ.

    Raises:
        ValueError: their rows do not tile ξ's ``TASK_SIZE`` rows, each once.
    """
    rows = sorted((r, i) for i, t in enumerate(tasks) if (r := _xi_rows(t)) is not None)
    starts, stops = [r[0] for r, _ in rows], [r[1] for r, _ in rows]
    if starts != [0, *stops[:-1]] or stops[-1:] != [TASK_SIZE]:
        raise ValueError(
            f"the tasks' xi_des rows {[r for r, _ in rows]} do not tile ξ's {TASK_SIZE}"
        )
    return tuple(tasks[i] for _, i in rows)
