"""The controller's limits, pink-style: each gives bounds on the joint speeds q̇ (CasADi).

A limit (:class:`Limit`) turns the state and the parameters into lower and upper bounds on
q̇ (±inf where it does not bound a joint); the QP intersects them
(:func:`mmstab.control.controller.qp.build_qp`):

- :class:`JointVelocityLimit`: |q̇| ≤ q̇_max, every joint (sprockets and arm);
- :class:`JointPositionLimit`: q_min ≤ q + q̇ dt ≤ q_max, the arm joints (the sprockets turn
  freely).
"""

from mmstab.control.limits.base import Bounds, Limit
from mmstab.control.limits.joint_position import JointPositionLimit
from mmstab.control.limits.joint_velocity import JointVelocityLimit

__all__ = ["Bounds", "JointPositionLimit", "JointVelocityLimit", "Limit"]
