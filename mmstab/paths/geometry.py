"""Route geometry: waypoints joined by straight lines, corners rounded by arcs or pivots.

Each corner of the waypoint polyline is replaced by the arc of radius ``turn_radius``
tangent to both of its segments (a fillet), so the route is tangent-continuous and its
curvature is 0 on the lines and ``±1/turn_radius`` on the arcs: bounded by construction.
The route is evaluated exactly (no sampling error) at any arc length.

**Pivot turns.** Given a ``pivot_radius`` (half the track separation, ``b / 2``), a corner
whose arc does not fit between its neighbours, and every corner when ``turn_radius`` is 0,
is a pivot instead: the base stops at the waypoint and turns on the spot (position fixed,
yaw from the leg before to the leg after, the shorter way), then drives the next leg. A
pivot has no length in x-y, so the route's parameter ``s`` is not the distance the base
centre travels there but the distance **the tracks run**: ``pivot_radius · |turn|`` (each
track's surface moves that far, in opposite directions). So ``s`` keeps increasing through
a pivot (the poses stay a function of one monotonic parameter), ``d yaw / ds = ±1 /
pivot_radius`` there, and a speed ``ds/dt`` is each track's speed on lines and in pivots
alike: the speed profile bounds the tracks with the same number (``mmstab.paths.speed``).
"""

from __future__ import annotations

import dataclasses
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


class Pivot(NamedTuple):
    """A turn on the spot at a waypoint.

    Attributes:
        point: the waypoint (2,) in M [m], where the pivot centre stands while the base turns.
        radius: the pivot radius, half the track separation [m]: the route's parameter
            advances by ``radius · |turn|`` (the distance each track runs).
        turn: signed turn, + = left (counter-clockwise) [rad].
        centre: the pivot centre's distance ahead of B's origin along x_B [m] (0: B's origin
            turns on the waypoint; else the origin swings about the waypoint at that radius,
            ``point − centre · [cos γ, sin γ]``; :func:`shift_pivot_centres`).
    """

    point: FloatArray
    radius: float
    turn: float
    centre: float = 0.0

    @property
    def length(self) -> float:
        """The distance each track runs while the base turns [m] (the parameter's share)."""
        return abs(self.turn) * self.radius


class Corner(NamedTuple):
    """An interior waypoint and how the route turns there (the route check's report).

    Attributes:
        waypoint: its index in the waypoint list.
        point: the waypoint (2,) in M [m].
        turn: signed turn from the leg before to the leg after, + = left [rad].
        pivot: whether the base turns on the spot there (else an arc, or no turn).
        radius_fit: largest arc radius that fits between its neighbours [m] (``inf`` when
            the corner was not refused an arc, 0 for ``turn_radius: 0``).
    """

    waypoint: int
    point: FloatArray
    turn: float
    pivot: bool
    radius_fit: float

    def describe(self, turn_radius: float) -> str:
        """One line: where, how far and why it pivots (``turn_radius`` [m])."""
        side = "left" if self.turn > 0 else "right"
        why = (
            "turn_radius 0"
            if turn_radius == 0
            else f"its {turn_radius:g} m arc does not fit between its neighbours; "
            f"a radius <= {self.radius_fit:.3f} m would"
        )
        return (
            f"corner {self.waypoint} at ({self.point[0]:.2f}, {self.point[1]:.2f}) m: pivot turn "
            f"of {np.degrees(abs(self.turn)):.0f} deg {side} ({why})"
        )


class RouteSample(NamedTuple):
    """Poses along a route and their derivative by arc length.

    Attributes:
        pose: (N, 3) of (x [m], y [m], yaw [rad]) in M; yaw continuous (not wrapped).
        rate: (N, 3) d pose / d s [1, 1, rad/m].
        curvature: (N,) signed curvature [1/m] (+ = turning left); in a pivot d yaw / ds,
            ``±1 / pivot_radius`` (the base centre stands still).
        pivot: (N,) whether the sample is in a pivot turn.
    """

    pose: FloatArray
    rate: FloatArray
    curvature: FloatArray
    pivot: NDArray[np.bool_]


@dataclass(frozen=True)
class Route:
    """A route of lines, arcs and pivots, evaluated by arc length ``s`` in [0, length] [m].

    Attributes:
        pieces: the pieces in driving order.
        start_yaw: the yaw of the first leg [rad].
        corners: the interior waypoints and how the route turns at each.
        turn_radius: the corner arcs' radius it was built with [m] (0: pivots only).
    """

    pieces: tuple[Line | Arc | Pivot, ...]
    start_yaw: float
    corners: tuple[Corner, ...] = ()
    turn_radius: float = float("nan")

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
        """Largest |curvature| along the route's arcs [1/m] (pivots are not curves)."""
        return max((1 / p.radius for p in self.pieces if isinstance(p, Arc)), default=0.0)

    @property
    def pivot_spans(self) -> FloatArray:
        """Arc lengths where each pivot starts and ends (P, 2) [m]."""
        starts = self.starts
        rows = [starts[k : k + 2] for k, p in enumerate(self.pieces) if isinstance(p, Pivot)]
        return np.array(rows, dtype=float).reshape(-1, 2)

    @property
    def turn_spans(self) -> tuple[tuple[Corner, float, float], ...]:
        """Each turning corner with where its arc or pivot starts and ends [m]."""
        starts = self.starts
        spans = [(starts[k], starts[k + 1]) for k, p in enumerate(self.pieces)
                 if not isinstance(p, Line)]  # fmt: skip
        turning = [c for c in self.corners if c.turn != 0]
        return tuple((c, float(a), float(b)) for c, (a, b) in zip(turning, spans, strict=True))

    def report(self) -> list[str]:
        """One line per pivot turn: the route check's account of what it did."""
        return [c.describe(self.turn_radius) for c in self.corners if c.pivot]

    def sample(self, s: ArrayLike) -> RouteSample:
        """Poses, their s-derivatives and curvature at arc lengths ``s`` [m] (clipped)."""
        s_m = np.clip(np.atleast_1d(np.asarray(s, dtype=float)), 0.0, self.length)
        starts = self.starts
        index = np.clip(np.searchsorted(starts, s_m, side="right") - 1, 0, len(self.pieces) - 1)
        pose = np.empty((len(s_m), 3))
        rate = np.empty((len(s_m), 3))
        kappa = np.zeros(len(s_m))
        pivot = np.zeros(len(s_m), dtype=bool)
        yaw0 = self.start_yaw + np.concatenate(
            [[0.0], np.cumsum([0.0 if isinstance(p, Line) else p.turn for p in self.pieces])]
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
            elif isinstance(piece, Pivot):
                sign, c = np.sign(piece.turn), piece.centre
                yaw = yaw0[k] + sign * u / piece.radius
                pose[rows, 0] = piece.point[0] - c * np.cos(yaw)
                pose[rows, 1] = piece.point[1] - c * np.sin(yaw)
                pose[rows, 2] = yaw
                rate[rows, 0] = c * np.sin(yaw) * sign / piece.radius
                rate[rows, 1] = -c * np.cos(yaw) * sign / piece.radius
                rate[rows, 2] = sign / piece.radius
                kappa[rows] = sign / piece.radius
                pivot[rows] = True
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
        return RouteSample(pose=pose, rate=rate, curvature=kappa, pivot=pivot)

    def resample(self, spacing: float) -> FloatArray:
        """Arc lengths from 0 to the end, evenly spaced by at most ``spacing`` [m]."""
        n = max(int(np.ceil(self.length / spacing)), 1)
        return np.linspace(0.0, self.length, n + 1)


class _Legs(NamedTuple):
    """The waypoint polyline.

    Attributes:
        points: the waypoints (n, 2) in M [m].
        dirs: unit directions of the legs (n-1, 2).
        lengths: the legs' lengths (n-1,) [m].
        turns: the signed turn at each interior waypoint (n-2,), + = left [rad].
    """

    points: FloatArray
    dirs: FloatArray
    lengths: FloatArray
    turns: FloatArray


def _legs(waypoints: ArrayLike) -> _Legs:
    """The polyline of ``waypoints`` (n, 2) [m], refused as :func:`route_from_waypoints` says."""
    w = np.asarray(waypoints, dtype=float)
    if w.ndim != 2 or w.shape[1] != 2 or len(w) < 2:
        raise RouteError("waypoints", f"need at least two [x, y] points, got shape {w.shape}")
    if not np.all(np.isfinite(w)):
        raise RouteError("waypoints", "waypoints must be finite numbers")
    seg = np.diff(w, axis=0)
    lengths = np.linalg.norm(seg, axis=1)
    for k, length in enumerate(lengths):
        if length < MIN_SEGMENT:
            raise RouteError(f"waypoints[{k + 1}]", f"repeats waypoint {k} (no segment between)")
    dirs = seg / lengths[:, None]
    cross = dirs[:-1, 0] * dirs[1:, 1] - dirs[:-1, 1] * dirs[1:, 0]
    turns = np.arctan2(cross, np.sum(dirs[:-1] * dirs[1:], axis=1))
    for k, turn in enumerate(turns):
        if abs(turn) > MAX_TURN:
            raise RouteError(f"waypoints[{k + 1}]", "the route reverses here; add a waypoint")
    return _Legs(w, dirs, lengths, turns)


class _Corners(NamedTuple):
    """How each corner turns.

    Attributes:
        tangent: distance from the corner to its arc's ends along each leg (C,) [m] (0 at a
            pivot).
        pivot: whether it pivots (C,).
        radius_fit: the largest arc radius that would fit there (C,) [m] (``inf``: no limit
            met).
    """

    tangent: FloatArray
    pivot: NDArray[np.bool_]
    radius_fit: FloatArray


def _choose_pivots(legs: _Legs, turn_radius: float, pivot_radius: float | None) -> _Corners:
    """Arcs where they fit, pivots where they do not (``turn_radius`` 0: every turn pivots).

    A leg too short for the arcs at its two ends gives up the sharper corner's arc (the one
    taking more of it) for a pivot; repeated until every leg holds its arcs. Without a
    ``pivot_radius`` the first such leg is refused, naming that corner.
    """
    turns, lengths = legs.turns, legs.lengths
    pivot = np.zeros(len(turns), dtype=bool) if turn_radius > 0 else turns != 0
    radius_fit = np.full(len(turns), np.inf if turn_radius > 0 else 0.0)
    while True:
        tangent = np.where(pivot, 0.0, turn_radius * np.tan(np.abs(turns) / 2))
        used = np.zeros(len(lengths))
        used[:-1] += tangent
        used[1:] += tangent
        over = np.flatnonzero(used > lengths + 1e-12)
        if len(over) == 0:
            return _Corners(tangent, pivot, radius_fit)
        k = int(over[0])
        ends = {c: tangent[c - 1] for c in (k, k + 1) if 1 <= c <= len(legs.points) - 2}
        corner = max(ends, key=lambda c: ends[c])  # the sharper corner of the two
        fit = turn_radius * lengths[k] / used[k]
        if pivot_radius is None:
            raise RouteError(
                f"waypoints[{corner}]",
                f"the turn needs a radius <= {fit:.3f} m to fit between its neighbours "
                f"({lengths[k]:.3f} m apart), below the route's turn_radius {turn_radius:.3f} m",
            )
        pivot[corner - 1], radius_fit[corner - 1] = True, fit


def route_from_waypoints(
    waypoints: ArrayLike, turn_radius: float, pivot_radius: float | None = None
) -> Route:
    """Join waypoints by lines and round every corner with an arc of ``turn_radius``.

    Args:
        waypoints: (n >= 2, 2) points in M [m], in driving order.
        turn_radius: radius of the corner arcs [m] (> 0; 0 with a ``pivot_radius``: a pivot
            turn at every corner).
        pivot_radius: half the track separation [m], or ``None``. Given, a corner whose arc
            does not fit between its neighbours is a pivot turn (module docstring);
            ``None``: such a corner is refused.

    Raises:
        RouteError: fewer than two points, a repeated point, a reversal, or (without a
            ``pivot_radius``) a corner whose arc does not fit between its neighbours
            (``field`` names the waypoint).
    """
    if pivot_radius is not None and not pivot_radius > 0:
        raise RouteError("pivot_radius", f"must be positive, got {pivot_radius}")
    legs = _legs(waypoints)
    if not (turn_radius > 0 or (turn_radius == 0 and pivot_radius is not None)):
        raise RouteError("turn_radius", f"must be positive, got {turn_radius}")
    w, dirs, lengths, turns = legs
    chosen = _choose_pivots(legs, turn_radius, pivot_radius)
    tangent = chosen.tangent
    pieces: list[Line | Arc | Pivot] = []
    for k in range(len(lengths)):
        t_in = tangent[k - 1] if k > 0 else 0.0
        t_out = tangent[k] if k < len(turns) else 0.0
        a = w[k] + dirs[k] * t_in
        b = w[k + 1] - dirs[k] * t_out
        if np.linalg.norm(b - a) > 0:
            pieces.append(Line(start=a, direction=dirs[k], length=float(np.linalg.norm(b - a))))
        if k < len(turns) and abs(turns[k]) > 0 and chosen.pivot[k]:
            pieces.append(Pivot(w[k + 1].copy(), float(pivot_radius or 0.0), float(turns[k])))
        elif k < len(turns) and abs(turns[k]) > 0:
            sign = np.sign(turns[k])
            normal = np.array([-dirs[k][1], dirs[k][0]]) * sign  # toward the arc's centre
            center = b + normal * turn_radius
            start_angle = float(np.arctan2(*(b - center)[::-1]))
            pieces.append(Arc(center, float(turn_radius), start_angle, float(turns[k])))
    corners = tuple(
        Corner(k + 1, w[k + 1].copy(), float(turns[k]), bool(chosen.pivot[k]), chosen.radius_fit[k])
        for k in range(len(turns))
    )
    return Route(
        pieces=tuple(pieces),
        start_yaw=float(np.arctan2(dirs[0][1], dirs[0][0])),
        corners=corners,
        turn_radius=float(turn_radius),
    )


def shift_pivot_centres(route: Route, centres: ArrayLike) -> Route:
    """The route with each pivot turning about a point ``centres[i]`` ahead of B's origin.

    A skid-steered base does not pivot about B's origin but about a point near its centre
    of mass (the skid model's level pivot, :mod:`mmstab.stability.skid`); a pivot about the
    origin is then a reference it cannot follow. Here that point stands on the waypoint:
    the line before the pivot ends ``c`` short of the waypoint (B's origin stops there, the
    pivot centre on the waypoint), the origin swings about the waypoint at radius ``c``
    while the heading turns, and the line after starts ``c`` behind the waypoint on the
    next leg's line. The legs stay on the waypoints' lines; the route's length is the same
    (the line before loses ``c``, the one after gains it), so only the pivot's span moves,
    by ``−c`` in arc length. A negative ``c`` (the centre behind the origin) overshoots the
    waypoint instead.

    Args:
        route: a route (its pivots at centre 0).
        centres: one distance per pivot piece, in driving order [m]; a pivot whose
            neighbours are not lines longer than ``|c|`` (an arc beside it) keeps centre 0.

    Raises:
        ValueError: not one centre per pivot.
    """
    c = np.asarray(centres, dtype=float).ravel()
    at = [k for k, p in enumerate(route.pieces) if isinstance(p, Pivot)]
    if len(c) != len(at):
        raise ValueError(f"{len(c)} pivot centres for the route's {len(at)} pivots")
    pieces = list(route.pieces)
    for k, centre in zip(at, c, strict=True):
        before = pieces[k - 1] if k > 0 else None
        after = pieces[k + 1] if k + 1 < len(pieces) else None
        fits = (isinstance(before, Line) and before.length > centre + MIN_SEGMENT
                and isinstance(after, Line) and after.length > -centre + MIN_SEGMENT)  # fmt: skip
        if not fits or centre == 0.0:
            continue
        pivot = pieces[k]
        assert isinstance(before, Line) and isinstance(after, Line) and isinstance(pivot, Pivot)
        pieces[k - 1] = before._replace(length=before.length - centre)
        pieces[k] = pivot._replace(centre=float(centre))
        pieces[k + 1] = after._replace(
            start=after.start - after.direction * centre, length=after.length + centre
        )
    return dataclasses.replace(route, pieces=tuple(pieces))
