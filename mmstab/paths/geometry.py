"""Route geometry: waypoints joined by straight lines, corners rounded by circular arcs.

Each corner of the waypoint polyline is replaced by the arc of radius ``turn_radius``
tangent to both of its segments (a fillet), so the route is tangent-continuous and its
curvature is 0 on the lines and ``±1/turn_radius`` on the arcs: bounded by construction.
The route is evaluated exactly (no sampling error) at any arc length.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

#: Two consecutive waypoints closer than this are a repeated point [m].
MIN_SEGMENT = 1e-6
#: Turns sharper than this cannot be rounded (a reversal) [rad].
MAX_TURN = np.pi - 1e-3


class RouteError(ValueError):
    """A waypoint list that cannot become a route; ``field`` names the waypoint at fault."""

    def __init__(self, field: str, message: str):
        self.field = field
        super().__init__(message)


class Line(NamedTuple):
    """A straight piece: start point (2,) [m], unit direction (2,), length [m]."""

    start: FloatArray
    direction: FloatArray
    length: float


class Arc(NamedTuple):
    """A circular piece.

    Attributes:
        center: centre (2,) [m].
        radius: radius [m].
        start_angle: angle of the radius vector at the arc's start [rad].
        turn: signed turn, + = left (counter-clockwise) [rad].
    """

    center: FloatArray
    radius: float
    start_angle: float
    turn: float

    @property
    def length(self) -> float:
        """Arc length [m]."""
        return abs(self.turn) * self.radius


class RouteSample(NamedTuple):
    """Poses along a route and their derivative by arc length.

    Attributes:
        pose: (N, 3) of (x [m], y [m], yaw [rad]) in M; yaw continuous (not wrapped).
        rate: (N, 3) d pose / d s [1, 1, rad/m].
        curvature: (N,) signed curvature [1/m] (+ = turning left).
    """

    pose: FloatArray
    rate: FloatArray
    curvature: FloatArray


@dataclass(frozen=True)
class Route:
    """A route of lines and arcs, evaluated by arc length ``s`` in [0, length] [m]."""

    pieces: tuple[Line | Arc, ...]
    start_yaw: float

    @property
    def starts(self) -> FloatArray:
        """Arc length at which each piece starts, (P + 1,) with the total last [m]."""
        return np.concatenate([[0.0], np.cumsum([p.length for p in self.pieces])])

    @property
    def length(self) -> float:
        """Total arc length [m]."""
        return float(self.starts[-1])

    @property
    def max_curvature(self) -> float:
        """Largest |curvature| along the route [1/m]."""
        return max((1 / p.radius for p in self.pieces if isinstance(p, Arc)), default=0.0)

    def sample(self, s: ArrayLike) -> RouteSample:
        """Poses, their s-derivatives and curvature at arc lengths ``s`` [m] (clipped)."""
        s_m = np.clip(np.atleast_1d(np.asarray(s, dtype=float)), 0.0, self.length)
        starts = self.starts
        index = np.clip(np.searchsorted(starts, s_m, side="right") - 1, 0, len(self.pieces) - 1)
        pose = np.empty((len(s_m), 3))
        rate = np.empty((len(s_m), 3))
        kappa = np.zeros(len(s_m))
        yaw0 = self.start_yaw + np.concatenate(
            [[0.0], np.cumsum([p.turn if isinstance(p, Arc) else 0.0 for p in self.pieces])]
        )
        for k, piece in enumerate(self.pieces):
            rows = index == k
            if not rows.any():
                continue
            u = s_m[rows] - starts[k]
            if isinstance(piece, Line):
                pose[rows, :2] = piece.start + u[:, None] * piece.direction
                pose[rows, 2] = yaw0[k]
                rate[rows] = [piece.direction[0], piece.direction[1], 0.0]
            else:
                sign = np.sign(piece.turn)
                angle = piece.start_angle + sign * u / piece.radius
                pose[rows, 0] = piece.center[0] + piece.radius * np.cos(angle)
                pose[rows, 1] = piece.center[1] + piece.radius * np.sin(angle)
                pose[rows, 2] = yaw0[k] + sign * u / piece.radius
                rate[rows, 0] = -sign * np.sin(angle)
                rate[rows, 1] = sign * np.cos(angle)
                rate[rows, 2] = sign / piece.radius
                kappa[rows] = sign / piece.radius
        return RouteSample(pose=pose, rate=rate, curvature=kappa)

    def resample(self, spacing: float) -> FloatArray:
        """Arc lengths from 0 to the end, evenly spaced by at most ``spacing`` [m]."""
        n = max(int(np.ceil(self.length / spacing)), 1)
        return np.linspace(0.0, self.length, n + 1)


def _unit(v: FloatArray) -> FloatArray:
    return v / np.linalg.norm(v)


def route_from_waypoints(waypoints: ArrayLike, turn_radius: float) -> Route:
    """Join waypoints by lines and round every corner with an arc of ``turn_radius``.

    Args:
        waypoints: (n >= 2, 2) points in M [m], in driving order.
        turn_radius: radius of the corner arcs [m] (> 0).

    Raises:
        RouteError: fewer than two points, a repeated point, a reversal, or a corner whose
            arc does not fit between its neighbours (``field`` names the waypoint).
    """
    w = np.asarray(waypoints, dtype=float)
    if w.ndim != 2 or w.shape[1] != 2 or len(w) < 2:
        raise RouteError("waypoints", f"need at least two [x, y] points, got shape {w.shape}")
    if not np.all(np.isfinite(w)):
        raise RouteError("waypoints", "waypoints must be finite numbers")
    if not turn_radius > 0:
        raise RouteError("turn_radius", f"must be positive, got {turn_radius}")
    seg = np.diff(w, axis=0)
    lengths = np.linalg.norm(seg, axis=1)
    for k, length in enumerate(lengths):
        if length < MIN_SEGMENT:
            raise RouteError(f"waypoints[{k + 1}]", f"repeats waypoint {k} (no segment between)")
    dirs = seg / lengths[:, None]
    cross = dirs[:-1, 0] * dirs[1:, 1] - dirs[:-1, 1] * dirs[1:, 0]
    turns = np.arctan2(cross, np.sum(dirs[:-1] * dirs[1:], axis=1))
    tangent = turn_radius * np.tan(np.abs(turns) / 2)  # corner to arc ends, along each segment
    for k, turn in enumerate(turns):
        if abs(turn) > MAX_TURN:
            raise RouteError(f"waypoints[{k + 1}]", "the route reverses here; add a waypoint")
    used = np.zeros(len(lengths))
    used[:-1] += tangent
    used[1:] += tangent
    for k, (u, length) in enumerate(zip(used, lengths, strict=True)):
        if u > length + 1e-12:
            ends = {c: tangent[c - 1] for c in (k, k + 1) if 1 <= c <= len(w) - 2}
            corner = max(ends, key=lambda c: ends[c])  # the sharper corner of the two
            radius_fit = turn_radius * length / u
            raise RouteError(
                f"waypoints[{corner}]",
                f"the turn needs a radius <= {radius_fit:.3f} m to fit between its neighbours "
                f"({length:.3f} m apart), below the route's turn_radius {turn_radius:.3f} m",
            )
    pieces: list[Line | Arc] = []
    for k in range(len(lengths)):
        t_in = tangent[k - 1] if k > 0 else 0.0
        t_out = tangent[k] if k < len(turns) else 0.0
        a = w[k] + dirs[k] * t_in
        b = w[k + 1] - dirs[k] * t_out
        if np.linalg.norm(b - a) > 0:
            pieces.append(Line(start=a, direction=dirs[k], length=float(np.linalg.norm(b - a))))
        if k < len(turns) and abs(turns[k]) > 0:
            sign = np.sign(turns[k])
            normal = np.array([-dirs[k][1], dirs[k][0]]) * sign  # toward the arc's centre
            center = b + normal * turn_radius
            start_angle = float(np.arctan2(*(b - center)[::-1]))
            pieces.append(Arc(center, float(turn_radius), start_angle, float(turns[k])))
    return Route(pieces=tuple(pieces), start_yaw=float(np.arctan2(dirs[0][1], dirs[0][0])))
