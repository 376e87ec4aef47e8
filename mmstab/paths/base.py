"""What every base path offers (the circle and a route alike), so no stage asks which it has.

A base path is parametrised by a fraction ``u`` in [0, 1] of one run along it (the
circle: of the lap; a route: of its lap time, ``mmstab.paths.route``). Poses are
``(x, y, yaw)`` in the terrain's map frame M, the yaw along the path's tangent.
"""

from __future__ import annotations

from typing import NamedTuple, Protocol

from numpy.typing import ArrayLike

from mmstab.terrain.base import FloatArray


class PathSample(NamedTuple):
    """Poses (N, 3) [m, m, rad] at path fractions and their rate d/du (N, 3)."""

    value: FloatArray
    rate: FloatArray


class BasePath(Protocol):
    """A base reference path: the circle or a route (``CirclePath``, ``RoutePath``)."""

    @property
    def length(self) -> float:
        """Arc length of one run along the path [m]."""
        ...

    @property
    def closed(self) -> bool:
        """Whether the path ends where it starts (a lap) rather than at a goal."""
        ...

    def pose_at(self, u: ArrayLike) -> FloatArray:
        """Base poses (N, 3) at path fractions ``u``."""
        ...

    def pose_rate(self, u: ArrayLike) -> PathSample:
        """Base poses at path fractions ``u`` and their derivative d pose / du (N, 3)."""
        ...

    def poses(self, n: int) -> FloatArray:
        """``n`` poses spread along the path (N, 3) (the planner's on a lap)."""
        ...
