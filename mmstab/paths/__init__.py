"""Routes the tracked base can drive: geometry by arc length and a speed profile.

``mmstab.paths.geometry`` turns waypoints into a smooth route (straight lines joined by
circular arcs of a bounded radius), ``mmstab.paths.speed`` gives it a speed profile the
tracks can follow, and ``mmstab.paths.io`` reads waypoint files. Poses are ``(x, y, yaw)``
in the terrain's map frame M (``docs/design.md``, "Frames"); the yaw is the route's tangent,
so the tracks always drive forward.
"""

from mmstab.paths.geometry import Arc, Line, Route, RouteSample, route_from_waypoints
from mmstab.paths.speed import SpeedLimits, SpeedProfile, speed_profile

__all__ = [
    "Arc",
    "Line",
    "Route",
    "RouteSample",
    "SpeedLimits",
    "SpeedProfile",
    "route_from_waypoints",
    "speed_profile",
]
