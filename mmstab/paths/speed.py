"""A speed profile along a route that the tracks can follow.

The reference speed is ``speed`` on straight lines; it is lowered where the route curves,
so that neither track exceeds ``headroom`` times its speed limit (on an arc of curvature
kappa the outer track runs at ``v (1 + |kappa| b / 2)``) and the lateral acceleration
``v^2 |kappa|`` stays within ``lateral_acceleration``; changes of speed are limited to
``acceleration``. The route starts and ends at rest. Time follows from the profile
(``dt = 2 ds / (v_i + v_{i+1})``, exact for constant acceleration).

In a pivot turn (``mmstab.paths.geometry``) the parameter is the distance the tracks run,
so ``v = ds/dt`` is each track's speed (in opposite directions) and the base's yaw rate is
``v / pivot_radius``. The base stops before a pivot and starts again after it (``v = 0`` at
both ends: the tracks reverse one side there), the tracks run at most ``speed`` in it (as on
a line; ``speed`` is within ``headroom`` of their limit), and ``acceleration`` bounds their
change of speed. There is no lateral acceleration: the base centre stands still.

**Turn limits.** A :class:`TurnLimit` caps the base's yaw rate over a stretch of arc length
(a corner, pivot or arc): there ``v <= yaw_rate / |d yaw / ds|`` (``pivot_radius x
yaw_rate`` in a pivot, ``yaw_rate / |kappa|`` on an arc). They are data: the stability
layer decides them (a turn slowed so that it does not slide, ``mmstab.runs.time_law``);
without any, the profile is the speeds' alone.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from mmstab.paths.geometry import FloatArray, Route


class SpeedLimits(NamedTuple):
    """What the base may do along a route.

    Attributes:
        speed: reference speed on straight lines [m/s].
        acceleration: largest change of speed [m/s^2].
        lateral_acceleration: largest v^2 |kappa| [m/s^2].
        track_speed: the tracks' largest surface speed, sprocket radius x speed limit [m/s].
        track_separation: distance between the track centres b [m].
        headroom: share of ``track_speed`` the reference may use (the rest is for feedback).
    """

    speed: float
    acceleration: float
    lateral_acceleration: float
    track_speed: float
    track_separation: float
    headroom: float = 0.8


class TurnLimit(NamedTuple):
    """A cap on the base's yaw rate over a stretch of the route (one corner).

    Attributes:
        start_s: where the stretch starts [m] (the route's parameter).
        end_s: where it ends [m].
        yaw_rate: the largest |yaw rate| there [rad/s] (> 0).
    """

    start_s: float
    end_s: float
    yaw_rate: float


class SpeedProfile(NamedTuple):
    """Speed along a route sampled by arc length.

    Attributes:
        s: arc lengths (n,) [m].
        v: speed (n,) [m/s] (0 at both ends).
        t: time at each sample (n,) [s].
        v_limit: the curvature limit before acceleration limits (n,) [m/s].
    """

    s: FloatArray
    v: FloatArray
    t: FloatArray
    v_limit: FloatArray

    @property
    def duration(self) -> float:
        """Time to drive the route [s]."""
        return float(self.t[-1])

    def s_at(self, t: FloatArray) -> FloatArray:
        """Arc length reached at times ``t`` [s] (constant acceleration between samples)."""
        t = np.clip(np.asarray(t, dtype=float), 0.0, self.duration)
        i = np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self.t) - 2)
        tau = t - self.t[i]
        dt = self.t[i + 1] - self.t[i]
        a = (self.v[i + 1] - self.v[i]) / np.where(dt > 0, dt, 1.0)
        return np.minimum(self.s[i] + self.v[i] * tau + 0.5 * a * tau**2, self.s[i + 1])


def straight_limit(limits: SpeedLimits) -> float:
    """The fastest the base may drive straight ahead under ``limits`` [m/s]."""
    return limits.headroom * limits.track_speed


def curvature_limit(limits: SpeedLimits, kappa: FloatArray) -> FloatArray:
    """Speed allowed by the tracks and the lateral acceleration at curvatures ``kappa`` [m/s]."""
    k = np.abs(np.asarray(kappa, dtype=float))
    tracks = straight_limit(limits) / (1.0 + k * limits.track_separation / 2)
    lateral = np.sqrt(limits.lateral_acceleration / np.maximum(k, 1e-12))
    return np.minimum.reduce([np.full_like(k, limits.speed), tracks, lateral])


def pivot_limit(limits: SpeedLimits) -> float:
    """The tracks' speed in a pivot turn [m/s]: ``speed``, within what they allow."""
    return min(limits.speed, straight_limit(limits))


def _limit_at(
    route: Route, limits: SpeedLimits, s: FloatArray, turns: tuple[TurnLimit, ...] = ()
) -> FloatArray:
    """The speed allowed at arc lengths ``s`` [m]: curvature, pivot, ``turns`` [m/s]."""
    smp = route.sample(s)
    v = np.where(smp.pivot, pivot_limit(limits), curvature_limit(limits, smp.curvature))
    yaw_per_m = np.abs(smp.rate[:, 2])
    for turn in turns:
        inside = (s >= turn.start_s) & (s <= turn.end_s) & (yaw_per_m > 0)
        cap = turn.yaw_rate / np.where(inside, yaw_per_m, 1.0)
        v = np.where(inside, np.minimum(v, cap), v)
    return v


def _stations(route: Route, ds: float) -> tuple[FloatArray, FloatArray]:
    """The profile's arc lengths [m] and those where it is at rest (ends, pivots' ends) [m].

    Without pivots, ``route.resample(ds)``. With them, the pivots' ends are stations too
    (the base is at rest there), and one more between two rest stations with none between.
    """
    s = route.resample(ds)
    spans = route.pivot_spans
    if not len(spans):
        return s, s[[0, -1]]
    rest = np.unique(np.concatenate([s[[0, -1]], spans.ravel()]))
    near = np.min(np.abs(s[:, None] - rest[None, :]), axis=1) < 1e-9
    s = np.union1d(s[~near], np.concatenate([rest, 0.5 * (rest[:-1] + rest[1:])]))
    return s, rest


def speed_profile(
    route: Route, limits: SpeedLimits, ds: float = 0.01, turns: tuple[TurnLimit, ...] = ()
) -> SpeedProfile:
    """The speed profile of ``route`` under ``limits``, sampled every ``ds`` [m] or finer.

    ``turns``: yaw-rate caps over stretches of the route (module text); none: the speeds'.

    Raises:
        ValueError: ``limits.speed`` above what the tracks allow on a straight line, or a
            turn limit's yaw rate not > 0.
    """
    if any(not t.yaw_rate > 0 for t in turns):
        raise ValueError(f"a turn limit's yaw rate must be > 0 rad/s: {turns}")
    if limits.speed > straight_limit(limits) + 1e-12:
        raise ValueError(
            f"speed {limits.speed:.3f} m/s is above the tracks' {straight_limit(limits):.3f} m/s "
            f"({limits.headroom:.0%} of their limit)"
        )
    s, rest = _stations(route, ds)
    # the limit over each interval: arcs start/end exactly at piece boundaries, so take the
    # tighter of the two ends and the interval's midpoint
    mid = 0.5 * (s[:-1] + s[1:])
    v_mid = _limit_at(route, limits, mid, turns)
    v_cap = _limit_at(route, limits, s, turns)
    v_cap[:-1] = np.minimum(v_cap[:-1], v_mid)
    v_cap[1:] = np.minimum(v_cap[1:], v_mid)
    v = v_cap.copy()
    v[np.searchsorted(s, rest)] = 0.0
    step = np.diff(s)
    for i in range(1, len(s)):  # accelerate no faster than allowed
        v[i] = min(v[i], np.sqrt(v[i - 1] ** 2 + 2 * limits.acceleration * step[i - 1]))
    for i in range(len(s) - 2, -1, -1):  # brake no harder than allowed
        v[i] = min(v[i], np.sqrt(v[i + 1] ** 2 + 2 * limits.acceleration * step[i]))
    dt = 2 * step / np.maximum(v[:-1] + v[1:], 1e-12)
    return SpeedProfile(s=s, v=v, t=np.concatenate([[0.0], np.cumsum(dt)]), v_limit=v_cap)
