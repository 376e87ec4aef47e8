"""The circle as a base reference path in a terrain's map frame M (:class:`BasePath`)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.paths.base import PathSample
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

    @property
    def length(self) -> float:
        """Arc length of one lap [m]."""
        return 2 * np.pi * self.radius

    @property
    def closed(self) -> bool:
        """A lap: it ends where it starts."""
        return True

    def fraction_of_s(self, s: ArrayLike) -> FloatArray:
        """Time fraction of the lap at arc lengths ``s`` [m]: a lap is driven at one speed."""
        return np.asarray(np.asarray(s, dtype=float) / self.length)

    def pose_rate(self, s: ArrayLike) -> PathSample:
        """Base poses (x, y, heading) at fractions ``s`` and their derivative d/ds (N, 3)."""
        s = np.atleast_1d(np.asarray(s, dtype=float))
        dphi = self.sign * 2 * np.pi  # d phi / ds [rad]
        phi = self.start_angle + dphi * s
        rate = np.stack(
            [
                -self.radius * np.sin(phi) * dphi,
                self.radius * np.cos(phi) * dphi,
                np.full_like(s, dphi),
            ],
            axis=1,
        )
        return PathSample(self.pose_at(s), rate)

    def poses(self, n: int) -> FloatArray:
        """``n`` poses evenly spread over one lap (the first at ``start_angle``) -> (n, 3)."""
        return self.pose_at(np.arange(n) / n)
