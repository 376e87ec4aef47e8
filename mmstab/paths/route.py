"""A route as a problem's base path: the ``path:`` section, its checks, and time along it.

A problem's ``path:`` is a circle (``center``, ``radius``, ``start_angle``, ``direction``)
or a route::

    path: {waypoints: [[x, y], ...], speed: V, turn_radius: R}     # or file: route.csv
    # optional: acceleration [m/s^2] (0.3), lateral_acceleration [m/s^2] (0.3)

:func:`route_path_from_section` builds the route (``mmstab.paths.io``), its speed profile
under the robot's track limits, and checks it against the ground: every cell under the
base's footprint along the way must be on the map and known (not NaN), and the turn radius
must let both tracks drive forward (``turn_radius >= separation / 2``), otherwise the
tracks cannot follow the curvature at any speed > 0; or be 0: a pivot turn (on the spot,
the tracks running in opposite directions) at every corner. A corner whose arc does not fit
between its neighbours is a pivot turn too; ``RoutePath.report()`` lists them. Errors name
the problem (or route) file and the field, as every other section's.

:class:`RoutePath` is the route parametrised by *time fraction* ``u = t / lap_time``: the
controller's references are functions of a path fraction, and with the time fraction the
speed profile (slower in turns, from and to rest) is built in. ``lap_time`` is the time to
drive the route plus a hold at its end (``HOLD`` of it, the base at rest): the references
interpolate a plan's postures with the lap's periodic spline, whose closing stretch (back
to the first posture) then falls after the run's end (a run lasts ``duration``).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from mmstab.core.files import ConfigError, MmstabError
from mmstab.model.robot import Robot
from mmstab.paths.base import PathSample
from mmstab.paths.geometry import FloatArray, Pivot, Route, shift_pivot_centres
from mmstab.paths.io import PlannedRoute, Waypoints, read_waypoints_csv, route_from_section
from mmstab.paths.speed import SpeedLimits, SpeedProfile, TurnLimit, speed_profile
from mmstab.terrain.base import Terrain

#: Defaults of the optional keys of a route's ``path:`` section [m/s^2].
ROUTE_DEFAULTS: dict[str, float] = {"acceleration": 0.3, "lateral_acceleration": 0.3}
#: Share of the driving time added at the route's end, at rest (see the module text).
HOLD = 0.25
#: Largest spacing of the footprint check along the route and across the footprint [m].
CHECK_SPACING = 0.05
#: The default ``planner.spacing`` of a route [m]: how far apart its planned poses are.
DEFAULT_SPACING = 0.5


def route_samples(length: float, spacing: float) -> FloatArray:
    """Arc lengths [m] of the planned poses: 0, ``spacing``, ... and the route's end."""
    n = max(int(np.ceil(length / spacing - 1e-9)), 1)
    return np.linspace(0.0, length, n + 1)


def is_route(section: Any) -> bool:
    """Whether a ``path:`` mapping is a route (``waypoints`` or ``file``), not a circle."""
    return isinstance(section, dict) and ("waypoints" in section or "file" in section)


@dataclass(frozen=True)
class RoutePath:
    """A route with its speed profile, parametrised by time fraction ``u = t / lap_time``.

    Attributes:
        route: the geometry (lines and arcs, by arc length).
        profile: the speed profile along it.
        limits: the speed limits the profile keeps (None: not known; the verdicts then take
            :data:`ROUTE_DEFAULTS`' accelerations).
        turn_limits: yaw-rate caps on some corners the profile keeps
            (:func:`mmstab.paths.speed.speed_profile`; :meth:`with_turn_limits`).
    """

    route: Route
    profile: SpeedProfile
    limits: SpeedLimits | None = None
    turn_limits: tuple[TurnLimit, ...] = ()

    def with_turn_limits(self, turns: tuple[TurnLimit, ...]) -> RoutePath:
        """The same route with its profile rebuilt under ``turns`` (and its own limits).

        Raises:
            ValueError: the route's speed limits are not known, or a yaw rate not > 0.
        """
        if self.limits is None:
            raise ValueError("a route without its speed limits cannot be slowed in turns")
        turns = tuple(TurnLimit(*map(float, t)) for t in turns)
        profile = speed_profile(self.route, self.limits, turns=turns)
        return RoutePath(self.route, profile, self.limits, turns)

    def with_pivot_centres(self, centres: ArrayLike) -> RoutePath:
        """The route with its pivots about points ``centres`` [m] ahead of B's origin.

        :func:`mmstab.paths.geometry.shift_pivot_centres`; the profile is rebuilt under the
        same limits, a turn cap on a pivot moved with the pivot's span (by ``−c``).

        Raises:
            ValueError: the route's speed limits are not known, or not one centre per pivot.
        """
        if self.limits is None:
            raise ValueError("a route without its speed limits cannot move its pivots")
        route = shift_pivot_centres(self.route, centres)
        old, new = self.route.pivot_spans, route.pivot_spans
        turns = []
        for t in self.turn_limits:
            on = np.flatnonzero((old[:, 0] <= t.start_s + 1e-9) & (t.end_s <= old[:, 1] + 1e-9))
            shift = float(new[on[0], 0] - old[on[0], 0]) if len(on) else 0.0
            turns.append(TurnLimit(t.start_s + shift, t.end_s + shift, t.yaw_rate))
        profile = speed_profile(route, self.limits, turns=tuple(turns))
        return RoutePath(route, profile, self.limits, tuple(turns))

    def yaw_rate_max(self, start_s: float, end_s: float) -> float:
        """The largest |yaw rate| of the reference between two arc lengths [m] [rad/s]."""
        p = self.profile
        inside = (p.s[:-1] >= start_s - 1e-9) & (p.s[1:] <= end_s + 1e-9)
        if not inside.any():
            return 0.0
        # d yaw / ds at each interval's midpoint (an arc's own, not its neighbour line's)
        yaw = np.abs(self.route.sample(0.5 * (p.s[:-1] + p.s[1:])[inside]).rate[:, 2])
        return float(np.max(np.maximum(p.v[:-1][inside], p.v[1:][inside]) * yaw))

    @property
    def duration(self) -> float:
        """Time to drive the route from rest to rest [s]."""
        return self.profile.duration

    @property
    def lap_time(self) -> float:
        """The references' period [s]: the driving time and the hold at the end."""
        return self.duration * (1.0 + HOLD)

    @property
    def length(self) -> float:
        """Arc length [m]."""
        return self.route.length

    @property
    def closed(self) -> bool:
        """A route ends at its goal, not where it started."""
        return False

    def planned_poses(self, spacing: float | None) -> int:
        """How many poses the planner places along the route, ``spacing`` [m] apart.

        ``None``: :data:`DEFAULT_SPACING`.
        """
        # counted, not sampled: a spacing of 1e-300 m asks for more poses than an array holds
        # (the planner's size bound then refuses them, naming planner.spacing's poses)
        n = self.length / (DEFAULT_SPACING if spacing is None else spacing)
        if not n < 2**62:
            return 2**62
        return max(math.ceil(n - 1e-9), 1) + 1  # = len(route_samples(...))

    def s_at(self, u: ArrayLike) -> FloatArray:
        """Arc length [m] reached at time fractions ``u`` (clipped to [0, 1])."""
        uu = np.clip(np.atleast_1d(np.asarray(u, dtype=float)), 0.0, 1.0)
        return np.asarray(self.profile.s_at(uu * self.lap_time))

    def speed_at_t(self, t: ArrayLike) -> FloatArray:
        """Reference speed [m/s] at times ``t`` [s] (the derivative of ``profile.s_at``)."""
        p = self.profile
        t = np.asarray(t, dtype=float)
        inside = (t >= 0.0) & (t <= p.duration)
        tc = np.clip(t, 0.0, p.duration)
        i = np.clip(np.searchsorted(p.t, tc, side="right") - 1, 0, len(p.t) - 2)
        dt = p.t[i + 1] - p.t[i]
        a = (p.v[i + 1] - p.v[i]) / np.where(dt > 0, dt, 1.0)
        return np.where(inside, p.v[i] + a * (tc - p.t[i]), 0.0)

    def fraction_of_s(self, s: ArrayLike) -> FloatArray:
        """Time fraction at which the reference reaches arc lengths ``s`` [m]."""
        t = np.interp(np.asarray(s, dtype=float), self.profile.s, self.profile.t)
        return np.asarray(t / self.lap_time)

    def pose_at(self, u: ArrayLike) -> FloatArray:
        """Base poses (N, 3) of (x, y, yaw) in M at time fractions ``u``."""
        return self.route.sample(self.s_at(u)).pose

    def pose_rate(self, u: ArrayLike) -> PathSample:
        """Poses at time fractions ``u`` and d pose / du = d pose/ds · v · lap_time."""
        u = np.atleast_1d(np.asarray(u, dtype=float))
        smp = self.route.sample(self.s_at(u))
        ds_du = self.speed_at_t(u * self.lap_time) * self.lap_time
        return PathSample(smp.pose, smp.rate * ds_du[:, None])

    def poses(self, n: int) -> FloatArray:
        """``n`` poses evenly spread in arc length, first and last included -> (n, 3)."""
        return self.route.sample(np.linspace(0.0, self.length, max(n, 2))).pose

    def report(self) -> list[str]:
        """What the route check did: one line per pivot turn (none when every arc fits)."""
        return self.route.report()

    def corners(self) -> list[dict[str, Any]]:
        """Every corner (waypoint index, point [m], turn [deg], ``arc`` or ``pivot``)."""
        return [
            {
                "waypoint": c.waypoint,
                "point": [float(c.point[0]), float(c.point[1])],
                "turn_deg": float(np.degrees(c.turn)),
                "kind": "pivot" if c.pivot else ("arc" if c.turn != 0 else "straight"),
                "radius_fit_m": None if np.isinf(c.radius_fit) else float(c.radius_fit),
            }
            for c in self.route.corners
        ]


def speed_limits(robot: Robot, section: dict[str, Any]) -> SpeedLimits:
    """The speed limits of a route section for ``robot`` (its tracks' speed and separation)."""
    t = robot.base.tracks
    return SpeedLimits(
        speed=float(section["speed"]),
        acceleration=float(section.get("acceleration", ROUTE_DEFAULTS["acceleration"])),
        lateral_acceleration=float(
            section.get("lateral_acceleration", ROUTE_DEFAULTS["lateral_acceleration"])
        ),
        track_speed=t.sprocket_radius * t.velocity_limit,
        track_separation=t.separation,
    )


def footprint_body(robot: Robot, spacing: float = CHECK_SPACING) -> FloatArray:
    """Points (n, 2) [m] covering the base's footprint (tracks, body, flippers) in B."""
    corners = np.vstack([b.corners() for b in robot.base.collision_boxes().values()])
    lo, hi = corners[:, :2].min(axis=0), corners[:, :2].max(axis=0)
    nx, ny = (np.ceil((hi - lo) / spacing).astype(int) + 1).tolist()
    x, y = np.meshgrid(np.linspace(lo[0], hi[0], nx), np.linspace(lo[1], hi[1], ny))
    return np.column_stack([x.ravel(), y.ravel()])


def first_off_ground(
    route: Route, terrain: Terrain, footprint: FloatArray, spacing: float = CHECK_SPACING
) -> tuple[float, FloatArray] | None:
    """The first arc length [m] and ground point where the footprint leaves known ground.

    The footprint (n, 2) [m] in B is swept along the route every ``spacing`` [m] (on a
    route with pivot turns, finer: so that no footprint point moves more than ``spacing``
    between two checks as the base turns on the spot); a point is bad when the terrain
    cannot give its height (off the map or an unknown cell).
    """
    if len(route.pivot_spans):
        reach = float(np.max(np.hypot(footprint[:, 0], footprint[:, 1])))
        pivot_radius = min(p.radius for p in route.pieces if isinstance(p, Pivot))
        spacing *= min(1.0, pivot_radius / max(reach, 1e-9))
    s = route.resample(spacing)
    pose = route.sample(s).pose
    c, si = np.cos(pose[:, 2]), np.sin(pose[:, 2])
    x = pose[:, :1] + c[:, None] * footprint[:, 0] - si[:, None] * footprint[:, 1]
    y = pose[:, 1:2] + si[:, None] * footprint[:, 0] + c[:, None] * footprint[:, 1]
    for k in range(len(s)):  # one call per pose: the terrain raises at its first bad point
        if np.all(np.isfinite(_heights(terrain, x[k], y[k]))):
            continue
        j = next(
            i for i in range(len(x[k])) if not np.isfinite(_heights(terrain, x[k, i], y[k, i]))
        )
        return float(s[k]), np.array([x[k, j], y[k, j]])
    return None


def _heights(terrain: Terrain, x: ArrayLike, y: ArrayLike) -> FloatArray:
    """Ground heights [m] under map points, all NaN when the terrain has none for one."""
    try:
        return np.asarray(terrain.surface_G(x, y)[..., 2])
    except MmstabError:
        return np.full(np.shape(x), np.nan)


def nearest_segment(waypoints: FloatArray, point: ArrayLike) -> int:
    """Index of the waypoint starting the polyline segment nearest ``point`` (2,) [m]."""
    p = np.asarray(point, dtype=float)
    a, b = waypoints[:-1], waypoints[1:]
    ab = b - a
    t = np.clip(np.sum((p - a) * ab, axis=1) / np.maximum(np.sum(ab * ab, axis=1), 1e-18), 0, 1)
    return int(np.argmin(np.linalg.norm(a + t[:, None] * ab - p, axis=1)))


def pivot_at(route: Route, s: float) -> int | None:
    """The waypoint whose pivot turn the route is in at arc length ``s`` [m], else ``None``."""
    corners = [c.waypoint for c in route.corners if c.pivot]
    for k, (s0, s1) in enumerate(route.pivot_spans):
        if s0 <= s <= s1:
            return corners[k]
    return None


def route_path_from_section(
    problem_path: str | os.PathLike[str],
    section: dict[str, Any],
    robot: Robot,
    terrain: Terrain,
    on_ground: bool = True,
) -> RoutePath:
    """Build and check a route ``path:`` section (see the module docstring).

    Args:
        problem_path: the problem file (a route ``file`` is relative to its folder).
        section: the validated ``path:`` mapping of a route.
        robot: the robot (track speed, separation, footprint).
        terrain: the ground the route must stay on.
        on_ground: check that the footprint stays on known ground (False: a command that
            does not drive the route, ``mmstab rest``).

    Raises:
        ConfigError: naming the problem (or route) file and the field at fault.
    """
    p = Path(problem_path)
    sep = robot.base.tracks.separation
    if 0 < float(section["turn_radius"]) < sep / 2:
        raise ConfigError(
            p,
            "path.turn_radius",
            f"{section['turn_radius']} m is below half the track separation ({sep / 2:.3f} m): "
            "the inner track would have to run backwards, the tracks cannot follow that "
            "curvature at any speed (turn_radius 0: a pivot turn on the spot at every corner)",
        )
    limits = speed_limits(robot, section)
    planned: PlannedRoute = route_from_section(p, section, limits)
    off = first_off_ground(planned.route, terrain, footprint_body(robot)) if on_ground else None
    if off is not None:
        if "file" in section:
            wp = read_waypoints_csv((p.parent / section["file"]).resolve())
            where, field = (p.parent / section["file"]).resolve(), "waypoint {}"
        else:
            wp = Waypoints(np.asarray(section["waypoints"], dtype=float), None)
            where, field = p, "path.waypoints[{}]"
        pivot = pivot_at(planned.route, off[0])
        k = nearest_segment(wp.xy, off[1]) if pivot is None else pivot
        raise ConfigError(
            where,
            field.format(k),
            f"the route {'from here' if pivot is None else 'pivoting here'} leaves known "
            f"ground at arc length {off[0]:.2f} m: the base's footprint reaches "
            f"({off[1][0]:.2f}, {off[1][1]:.2f}) m, off the map or on an unknown (NaN) cell",
        )
    return RoutePath(route=planned.route, profile=planned.profile, limits=limits)


def route_path(
    robot: Robot,
    terrain: Terrain,
    waypoints: ArrayLike,
    *,
    speed: float,
    turn_radius: float,
    acceleration: float = ROUTE_DEFAULTS["acceleration"],
    lateral_acceleration: float = ROUTE_DEFAULTS["lateral_acceleration"],
) -> RoutePath:
    """A route through waypoints, as a problem file's ``path:`` section gives it.

    Args:
        robot: the robot (its tracks' speed and separation, its footprint).
        terrain: the ground the route must stay on.
        waypoints: (n, 2) of (x, y) or (n, 3) with a yaw [m, m, rad] in the map frame.
        speed: cruise speed [m/s].
        turn_radius: corner arcs' radius [m] (0: a pivot turn at every corner).
        acceleration: longitudinal acceleration limit [m/s^2].
        lateral_acceleration: lateral acceleration limit in the arcs [m/s^2].

    Raises:
        ConfigError: the route cannot be driven or leaves known ground (naming the field as
            a ``path:`` section's).
    """
    section = {
        "waypoints": np.asarray(waypoints, dtype=float).tolist(),
        "speed": float(speed),
        "turn_radius": float(turn_radius),
        "acceleration": float(acceleration),
        "lateral_acceleration": float(lateral_acceleration),
    }
    return route_path_from_section("<code>", section, robot, terrain)
