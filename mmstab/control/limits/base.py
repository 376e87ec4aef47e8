"""The limit interface (as pink's ``Limit``): bounds on the joint speeds."""

from __future__ import annotations

import abc
from typing import Any, NamedTuple

import casadi as ca

from mmstab.control.layout import ControllerParams


class Bounds(NamedTuple):
    """Lower and upper bounds on q̇ (6,) [rad/s] (CasADi; ±inf where unbounded)."""

    lower: Any
    upper: Any


class Limit(abc.ABC):
    """A limit of the controller: bounds on q̇ from the state and the parameters."""

    @abc.abstractmethod
    def bounds(self, state: ca.SX, params: ControllerParams) -> Bounds:
        """The bounds at a state (9,) with the run-time parameters."""


def intersect(limits: list[Limit], state: ca.SX, params: ControllerParams) -> Bounds:
    """The intersection of several limits' bounds: max of the lowers, min of the uppers."""
    lower, upper = limits[0].bounds(state, params)
    for limit in limits[1:]:
        b = limit.bounds(state, params)
        lower, upper = ca.fmax(lower, b.lower), ca.fmin(upper, b.upper)
    return Bounds(lower, upper)
