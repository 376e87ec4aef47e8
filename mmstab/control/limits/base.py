"""The limit interface (as pink's ``Limit``): bounds on some of the joint speeds."""

from __future__ import annotations

import abc
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, NamedTuple

import casadi as ca

from mmstab.control.layout import BASE_STATE, ControllerParams, Layout, StepReference

if TYPE_CHECKING:
    from mmstab.control.tasks.model import TaskModel


class Bounds(NamedTuple):
    """Lower and upper bounds on the limit's rows of q̇ [rad/s] (CasADi)."""

    lower: Any
    upper: Any


class LimitContext(NamedTuple):
    """What a limit may read besides the state and the parameters (CasADi).

    Attributes:
        model: the task kinematics (the robot's sprocket radius and track separation).
        reference: the step's unpacked reference (ξ̇_ref's heading rate, the local ground).
        xi_dot_des: the task rates the QP asks for, ξ̇_des (6,) [m/s, m/s, rad/s, m/s ...]:
            the base point's velocity in M and the heading rate first.
    """

    model: TaskModel
    reference: StepReference
    xi_dot_des: Any


class Limit(abc.ABC):
    """A limit of the controller: bounds on rows of q̇ from the state and the parameters."""

    #: The limit's name in the registry (:data:`mmstab.control.limits.LIMITS`).
    name: str
    #: What it reads of the step's reference and task rates (``controller_layout.h``'s
    #: comments; empty: the state and the parameters only).
    reads: str = ""

    def rows(self, layout: Layout) -> tuple[int, int]:
        """The rows of q̇ (2 + n,) it bounds, (start, stop); every joint unless it says otherwise."""
        return (0, layout.joints)

    @abc.abstractmethod
    def bounds(
        self, state: ca.SX, params: ControllerParams, context: LimitContext | None = None
    ) -> Bounds:
        """The bounds of its rows at a state (5 + n,) with the run-time parameters.

        ``context``: the step's reference and task rates, for limits that read them (None:
        the limit must do without, :meth:`needs_context`).
        """

    def needs_context(self) -> bool:
        """Whether :meth:`bounds` reads the :class:`LimitContext` (then it must be given)."""
        return False


def intersect(
    limits: Sequence[Limit],
    state: ca.SX,
    params: ControllerParams,
    context: LimitContext | None = None,
) -> Bounds:
    """The intersection of the limits' bounds, row by row: max of the lowers, min of the uppers.

    Each row takes the bounds of the limits that declare it, in the limits' order (a row no
    limit bounds is ±inf); the result has the 2 + n rows of q̇.
    """
    layout = Layout(state.numel() - BASE_STATE)
    lower: list[Any] = [-ca.inf] * layout.joints
    upper: list[Any] = [ca.inf] * layout.joints
    bounded = [False] * layout.joints
    for limit in limits:
        start, stop = limit.rows(layout)
        if context is None and limit.needs_context():
            raise ValueError(f"limit {limit.name!r} reads the step's reference: give a context")
        b = limit.bounds(state, params, context)
        for k, row in enumerate(range(start, stop)):
            if bounded[row]:
                lower[row] = ca.fmax(lower[row], b.lower[k])
                upper[row] = ca.fmin(upper[row], b.upper[k])
            else:
                lower[row], upper[row], bounded[row] = b.lower[k], b.upper[k], True
    return Bounds(ca.vertcat(*lower), ca.vertcat(*upper))
