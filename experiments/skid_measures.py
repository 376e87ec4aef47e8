"""What the skid-steer comparisons (the ramp grid and rough ground) measure alike."""

from __future__ import annotations

from typing import Any

import numpy as np

#: Turning cases whose MuJoCo yaw rate is below this are reported, not ratioed [rad/s].
TURNING = 0.05


def median(values: list[float]) -> float | None:
    """The median of ``values``; None for none."""
    return float(np.median(values)) if values else None


def per_radian(twist: dict[str, Any]) -> float:
    """Downhill slide per radian turned [m/rad]."""
    return float(twist["downhill"] / max(abs(twist["yaw_rate"]), 1e-9))


def downhill_beyond(velocity: Any, yaw_rate: Any, com: Any, speed: float, down: Any) -> Any:
    """The CoM's velocity beyond the commanded (v, 0), along the downhill [m/s].

    The slide of the verdicts (:func:`mmstab.stability.skid.turn_slide`): B's velocity plus
    the yaw about the CoM's foot on the support plane (its x, y in B).

    Args:
        velocity: B's velocity along x_B, y_B (2,) [m/s] (NaN: none).
        yaw_rate: [rad/s].
        com: the overall CoM in B (3,) or its x, y [m].
        speed: the commanded forward speed v [m/s].
        down: the downhill direction in B's plane (2,) [-].
    """
    v = np.asarray(velocity, dtype=float) + float(yaw_rate) * np.array([-com[1], com[0]])
    return float((v - [speed, 0.0]) @ np.asarray(down, dtype=float))
