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
