"""The task interface (as pink's ``Task``): value, error, Jacobian, QP objective."""

from __future__ import annotations

import abc
from typing import Any, NamedTuple

import casadi as ca

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

    #: Number of rows (tasks whose rows depend on the robot override :meth:`rows`).
    size: int

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
        """½‖v − J q̇‖²_W with v = K e + f ṙ_ref: H = Jᵀ W J, g = −Jᵀ W v, cost0 = ½ vᵀ W v."""
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
