"""Waypoint files and the ``path:`` section of a problem for routes.

A CSV route file has one waypoint per line, ``x,y`` or ``x,y,yaw`` (metres, radians, in the
terrain's map frame), with an optional header line. A given yaw is checked against the
route's direction there (a file listed backwards is refused), not used to bend the route:
the route's yaw is its tangent.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from mmstab.core.files import ConfigError
from mmstab.paths.geometry import FloatArray, Route, RouteError, route_from_waypoints
from mmstab.paths.speed import SpeedLimits, SpeedProfile, speed_profile


class Waypoints(NamedTuple):
    """Waypoints (n, 2) [m] and, when the file gives them, yaws (n,) [rad]."""

    xy: FloatArray
    yaw: FloatArray | None


def read_waypoints_csv(path: str | os.PathLike[str]) -> Waypoints:
    """Read ``x,y[,yaw]`` lines.

    Raises:
        ConfigError: naming the file and the line at fault.
    """
    p = Path(path)
    try:
        lines = p.read_text().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(p, "", f"cannot read route file ({exc})") from None
    rows: list[list[float]] = []
    first = True
    for number, line in enumerate(lines, start=1):
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        cells = [c.strip() for c in text.split(",")]
        try:
            values = [float(c) for c in cells]
        except ValueError:
            if first:  # a header line
                first = False
                continue
            msg = f"expected numbers x,y[,yaw], got {text!r}"
            raise ConfigError(p, f"line {number}", msg) from None
        first = False
        if len(values) not in (2, 3):
            raise ConfigError(p, f"line {number}", f"expected 2 or 3 columns, got {len(values)}")
        if not all(np.isfinite(values)):
            raise ConfigError(p, f"line {number}", "values must be finite numbers")
        if rows and len(values) != len(rows[0]):
            raise ConfigError(p, f"line {number}", "every line needs the same number of columns")
        rows.append(values)
    if len(rows) < 2:
        raise ConfigError(p, "", f"a route needs at least two waypoints, found {len(rows)}")
    data = np.array(rows)
    return Waypoints(xy=data[:, :2], yaw=data[:, 2] if data.shape[1] == 3 else None)


def check_yaw(waypoints: Waypoints) -> int | None:
    """Index of the first waypoint whose yaw points against the route there, else ``None``."""
    if waypoints.yaw is None:
        return None
    seg = np.diff(waypoints.xy, axis=0)
    dirs = seg / np.linalg.norm(seg, axis=1, keepdims=True)
    heading = np.vstack([dirs[:1], dirs[:-1] + dirs[1:], dirs[-1:]])  # in, out, or their mean
    yaw_dir = np.stack([np.cos(waypoints.yaw), np.sin(waypoints.yaw)], axis=1)
    against = np.flatnonzero(np.sum(heading * yaw_dir, axis=1) <= 0)
    return int(against[0]) if len(against) else None


#: Longest route through the waypoints [m]: its speed profile samples every centimetre
#: (1e6 stations here); a longer one (a mistyped coordinate, 1e300) would exhaust the memory
#: before the size bounds of the tracking run see it.
MAX_ROUTE_LENGTH = 10_000.0


def check_length(source: Path, field: str, xy: FloatArray) -> None:
    """Refuse waypoints (n, 2) [m] whose polyline is longer than :data:`MAX_ROUTE_LENGTH`.

    Raises:
        ConfigError: naming ``source`` and ``field`` (the route file: its waypoints).
    """
    with np.errstate(over="ignore", invalid="ignore"):  # hypot of 1e308s: inf, refused
        length = float(np.sum(np.hypot(*np.diff(xy, axis=0).T)))
    if not length <= MAX_ROUTE_LENGTH:
        msg = (
            f"the line through the waypoints is {length:.3g} m long; at most {MAX_ROUTE_LENGTH:g} m"
        )
        raise ConfigError(source, field or "waypoints", msg)


class PlannedRoute(NamedTuple):
    """A route and its speed profile."""

    route: Route
    profile: SpeedProfile


def route_from_section(
    problem_path: str | os.PathLike[str], section: dict[str, Any], limits: SpeedLimits
) -> PlannedRoute:
    """Build the route of a ``path:`` section (``waypoints`` or ``file``) with its speed.

    A corner whose arc does not fit, and every corner with ``turn_radius: 0``, is a pivot
    turn of radius ``limits.track_separation / 2`` (``mmstab.paths.geometry``; the route's
    ``report()`` says which).

    Args:
        problem_path: the problem file (a ``file`` is relative to its folder).
        section: ``{waypoints: [[x, y], ...] | file: PATH, turn_radius: R [m], ...}``.
        limits: speed limits (``speed`` from the section, the rest from the robot).

    Raises:
        ConfigError: naming the problem (or route) file and the field at fault.
    """
    p = Path(problem_path)
    if "file" in section:
        where = (p.parent / section["file"]).resolve()
        if not where.is_file():
            raise ConfigError(p, "path.file", f"no route file at {where}")
        waypoints = read_waypoints_csv(where)
        source, prefix = where, "line"
    else:
        waypoints = Waypoints(np.asarray(section["waypoints"], dtype=float), None)
        source, prefix = p, "path."
    check_length(source, "path.waypoints" if prefix == "path." else "", waypoints.xy)
    bad = check_yaw(waypoints)
    if bad is not None:
        raise ConfigError(source, f"waypoint {bad}", "its yaw points against the route there")
    try:
        route = route_from_waypoints(
            waypoints.xy, float(section["turn_radius"]), limits.track_separation / 2
        )
    except RouteError as exc:
        field = exc.field
        if prefix == "line" and field.startswith("waypoints["):
            field = f"waypoint {field[len('waypoints[') : -1]}"
        elif prefix == "path.":
            field = prefix + field
        raise ConfigError(source, field, str(exc)) from None
    try:
        profile = speed_profile(route, limits)
    except ValueError as exc:
        raise ConfigError(p, "path.speed", str(exc)) from None
    return PlannedRoute(route=route, profile=profile)
