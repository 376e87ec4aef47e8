"""The base's paths: the paper's circle, and routes the tracks can drive (geometry, speed).

``mmstab.paths.circle`` is the paper's lap; ``mmstab.paths.geometry`` turns waypoints into a
smooth route (straight lines joined by circular arcs of a bounded radius, or by pivot turns
on the spot where an arc does not fit),
``mmstab.paths.speed`` gives it a speed profile the tracks can follow, and
``mmstab.paths.io`` reads waypoint files. Poses are ``(x, y, yaw)`` in the terrain's map
frame M (``docs/design.md``, "Frames"); the yaw is the route's tangent, so the tracks always
drive forward. ``mmstab.paths.route`` makes a route a problem's path (``RoutePath``, checked
against the robot and the terrain).
"""

from mmstab.paths.geometry import (
    Arc,
    Corner,
    Line,
    Pivot,
    Route,
    RouteSample,
    route_from_waypoints,
)
from mmstab.paths.speed import SpeedLimits, SpeedProfile, speed_profile

__all__ = [
    "Arc",
    "Corner",
    "Line",
    "Pivot",
    "Route",
    "RouteSample",
    "SpeedLimits",
    "SpeedProfile",
    "route_from_waypoints",
    "speed_profile",
]
