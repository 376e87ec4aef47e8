"""Turret continuity: the planner keeps link0 within a window of its previous angle.

The planner searches the arm CoM, not the posture, so Eq. 6's motion term sees a CoM that
moves from just left of the turret's front to just right of it as a few centimetres. When
the turret's end stop points forward (link0 limited to [0, 2π]), that move is a swing of
almost a full turn through the back, which the tracked arm cannot follow without
saturating or hitting the base. ``planner.turret_window`` [rad] bounds the turret angle of
each planned pose to within that window of the previous pose's (the realised posture's
link0); on a closed path the last pose is also kept within the window of the first, so
the lap closes. The first pose is free: the approach phase moves the arm from stowed.

The turret angle of a CoM is the link0 of its nearest sample of V (V's samples are the CoMs
of collision-free grid postures), so the same rule holds for the exhaustive reference,
the coarse seeds and the CMA-ES polish (:meth:`PlanningRegion.windowed`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.model.robot import FloatArray
from mmstab.planner.regions import CoMRegion, PlanningRegion, as_region

#: Slack on the window [rad]: a posture at the window's edge is inside.
WINDOW_TOL = 1e-9


def sample_turret(region: CoMRegion) -> FloatArray:
    """link0 of each of the region's samples (M,) [rad], in ``sample_index`` order."""
    return as_region(region).turret_angles


def sample_postures(region: CoMRegion) -> FloatArray:
    """The grid posture of each of the region's samples (M, 4) [rad] (``sample_index`` order)."""
    return as_region(region).postures


class Window(NamedTuple):
    """An interval of turret angles [rad]: ``lower <= link0 <= upper``."""

    lower: float
    upper: float

    def contains(self, angle: ArrayLike) -> NDArray[np.bool_]:
        """Whether turret angles [rad] lie in the window (with ``WINDOW_TOL``)."""
        a = np.asarray(angle, dtype=float)
        return (a >= self.lower - WINDOW_TOL) & (a <= self.upper + WINDOW_TOL)

    def excess(self, angle: ArrayLike) -> FloatArray:
        """How far turret angles lie outside the window, 0 inside [rad]."""
        a = np.asarray(angle, dtype=float)
        return np.maximum(0.0, np.maximum(self.lower - a, a - self.upper))


def turret_window(previous: float, width: float, first: float | None = None) -> Window:
    """The window of a pose: within ``width`` [rad] of the previous pose's link0 [rad].

    Args:
        previous: link0 of the previous pose's posture [rad].
        width: ``planner.turret_window`` [rad].
        first: link0 of the path's first pose [rad] when this is the last pose of a closed
            path; the window is then also within ``width`` of it, where both overlap.
    """
    lower, upper = previous - width, previous + width
    if first is not None:
        lo, hi = max(lower, first - width), min(upper, first + width)
        if lo <= hi:
            lower, upper = lo, hi
    return Window(float(lower), float(upper))


def windowed_region(region: CoMRegion, window: Window) -> PlanningRegion:
    """The region restricted to the window (:meth:`PlanningRegion.windowed`).

    Raises:
        MmstabError: no sample of the region lies in the window.
    """
    return as_region(region).windowed(window)
