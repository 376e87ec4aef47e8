"""Base reference paths in a terrain's map frame M."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.terrain.base import FloatArray


class CirclePath(NamedTuple):
    """A circle on the slope: centre in S [m], radius [m], start angle [rad], direction."""

    center: tuple[float, float]
    radius: float
    start_angle: float
    direction: str = "ccw"

    @property
    def sign(self) -> float:
        """+1 for counter-clockwise (seen from above the slope), -1 for clockwise."""
        return 1.0 if self.direction == "ccw" else -1.0

    def pose_at(self, s: ArrayLike) -> FloatArray:
        """Base poses at path fractions ``s`` in [0, 1] -> (N, 3) of (x, y, heading) in S.

        The heading is the path tangent, so the tracks drive forward along the circle.
        """
        s = np.atleast_1d(np.asarray(s, dtype=float))
        phi = self.start_angle + self.sign * 2 * np.pi * s
        x = self.center[0] + self.radius * np.cos(phi)
        y = self.center[1] + self.radius * np.sin(phi)
        heading = phi + self.sign * np.pi / 2
        return np.stack([x, y, heading], axis=1)

    def poses(self, n: int) -> FloatArray:
        """``n`` poses evenly spread over one lap (the first at ``start_angle``) -> (n, 3)."""
        return self.pose_at(np.arange(n) / n)
