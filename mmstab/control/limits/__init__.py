"""The controller's limits, pink-style: each gives bounds on rows of the joint speeds q̇ (CasADi).

A limit (:class:`Limit`) declares the rows of q̇ it bounds (:meth:`Limit.rows`) and turns the
state and the parameters into their lower and upper bounds; the QP intersects them row by row
(:func:`mmstab.control.limits.base.intersect`, in
:func:`mmstab.control.controller.qp.build_qp`):

- :class:`JointVelocityLimit`: |q̇| ≤ q̇_max, every joint (sprockets and arm);
- :class:`JointPositionLimit`: q_min ≤ q + q̇ dt ≤ q_max, the arm joints (the sprockets turn
  freely);
- :class:`YawRateLimit`: on a slope the commanded yaw rate within the reference's plus a
  margin (a box on the two sprockets about the forward speed the base point asks for).

:data:`LIMITS` names every limit, :data:`DEFAULT_LIMITS` is the controller's list; adding a
limit is one module of this package and its class in :data:`LIMITS`.
"""

from __future__ import annotations

from collections.abc import Sequence

from mmstab.control.limits.base import Bounds, Limit, LimitContext, intersect
from mmstab.control.limits.joint_position import JointPositionLimit
from mmstab.control.limits.joint_velocity import JointVelocityLimit
from mmstab.control.limits.yaw_rate import YawRateLimit

#: Every limit, by name.
LIMITS: dict[str, type[Limit]] = {
    cls.name: cls
    for cls in (
        JointVelocityLimit,
        JointPositionLimit,
        YawRateLimit,
    )
}
#: The controller's limits, in the order they are intersected.
DEFAULT_LIMITS: tuple[str, ...] = ("joint_velocity", "joint_position", "yaw_rate")


def build_limits(names: Sequence[str] = DEFAULT_LIMITS) -> list[Limit]:
    """The named limits (:data:`LIMITS`).

    Raises:
        ValueError: a name not in :data:`LIMITS`.
    """
    unknown = [n for n in names if n not in LIMITS]
    if unknown:
        raise ValueError(f"unknown controller limits {unknown}; registered: {', '.join(LIMITS)}")
    return [LIMITS[n]() for n in names]


__all__ = [
    "DEFAULT_LIMITS",
    "LIMITS",
    "Bounds",
    "JointPositionLimit",
    "JointVelocityLimit",
    "Limit",
    "LimitContext",
    "YawRateLimit",
    "build_limits",
    "intersect",
]
