"""The slip limit: where the tracks slide down the ground before the robot tips.

A rigid robot resting on its support carries its whole weight ``m g`` through the contacts.
In the body frame B (z up the support's normal), gravity splits into a normal part
``g_n = -g_B . z`` pressing the tracks on the ground and a tangential part ``g_t`` along it.
With Coulomb friction of coefficient ``friction`` (the same at every contact, isotropic),
the contacts can hold the tangential part only while it stays inside the friction cone of
the total normal force: ``|g_t| <= friction g_n``, i.e. while the tilt of the support
(the angle between gravity and -z_B) stays below ``atan(friction)``. Beyond, the robot
slides whichever way it heads (isotropic friction: the heading enters only through the
resting pose on uneven ground). Assumptions (``docs/stability.md``): quasi-static, the
arm's motion exerts no force on the base, no track drive force (brakes hold the tracks:
the tangential force comes from static friction alone), the ground does not deform or
give way, and the robot's normal is the one of its resting pose.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.terrain.base import DEFAULT_FRICTION, Terrain

FloatArray = np.ndarray


class SlipLimit(NamedTuple):
    """The friction cone at resting poses.

    Attributes:
        tilt: (N,) angle between gravity and -z_B at each pose [rad].
        critical_tilt: ``atan(friction)`` [rad], the tilt at which the tracks slide.
        margin: (N,) ``critical_tilt - tilt`` [rad] (> 0: the tracks hold).
        slides: (N,) tilt beyond the critical tilt.
        friction: the friction coefficient [-].
    """

    tilt: FloatArray
    critical_tilt: float
    margin: FloatArray
    slides: np.ndarray
    friction: float


def support_tilt(gravity_body: ArrayLike) -> FloatArray:
    """Tilt of the support [rad]: angle between gravity (N, 3) or (3,) in B and -z_B.

    Args:
        gravity_body: gravity in the body frame [m/s^2].
    """
    g = np.atleast_2d(np.asarray(gravity_body, dtype=float))
    tangential = np.hypot(g[:, 0], g[:, 1])
    return np.arctan2(tangential, -g[:, 2])  # > pi/2 when the body is upside down


def slip_limit(gravity_body: ArrayLike, friction: float) -> SlipLimit:
    """The friction-cone check of a rigid robot on its support.

    Args:
        gravity_body: gravity in the body frame at each pose (N, 3) or (3,) [m/s^2].
        friction: Coulomb friction coefficient of tracks on ground [-] (> 0).
    """
    tilt = support_tilt(gravity_body)
    critical = float(np.arctan(friction))
    margin = critical - tilt
    return SlipLimit(tilt, critical, margin, ~(margin >= 0), float(friction))


def terrain_slip(terrain: Terrain, poses: ArrayLike) -> SlipLimit:
    """:func:`slip_limit` at resting poses (x [m], y [m], yaw [rad]) (N, 3) on a terrain.

    Uses ``terrain.friction`` (the problem's ``terrain.friction``).
    """
    return slip_limit(terrain.gravity_body(poses), terrain_friction(terrain))


def terrain_friction(terrain: Any) -> float:
    """The terrain's friction coefficient [-] (:data:`DEFAULT_FRICTION` when it has none)."""
    return float(getattr(terrain, "friction", DEFAULT_FRICTION))


def binding_limit(tip_slope: float, slip_slope: float) -> str:
    """Which limit binds first as the slope grows: ``slip`` or ``tip`` (ties: ``tip``).

    Args:
        tip_slope: slope at which the robot tips [rad].
        slip_slope: slope at which the tracks slide [rad].
    """
    return "slip" if slip_slope < tip_slope else "tip"
