"""Task references along the base circle: ξ_des and its rate for the tracking controller.

Everything is a function of the path fraction s ∈ [0, 1) (one lap; s = t / lap_time for a
constant-speed lap), vectorised over s, and returns the value and its derivative d/ds (so the
feed-forward is ξ̇_ref = d ξ_des/ds / lap_time).

**One placement.** Body points are placed in the map frame M by the terrain package's one
placement (:func:`mmstab.terrain.place_local`, the controller's task map evaluated in NumPy)
at the reference pose and its local ground; the rates are its Jacobians times the pose's and
the point's rates, d/ds place(pose(s), p(s)) = ∂place/∂pose · pose'(s) + M_R_B · p'(s) (the
local ground's own rate is not included: zero on the ramp, ``docs/controller-terrain.md``).

- :func:`base_reference`: the base rows [g_bx, g_by, γ] of ξ: the control point a distance
  ``base_offset`` ahead of the circle's reference pose, and the tangent heading.
- :func:`arm_reference`: the arm-CoM rows [g_ax, g_ay, g_az] in M: the planned body-frame CoM
  targets interpolated along the lap (periodic cubic spline in s) and placed with the
  reference base pose, g_a^M(s) = place(pose(s), g_a^B(s)).
- :func:`posture_reference`: the arm posture reference q_ref(s): the plan's postures
  interpolated along the lap (the same periodic cubic spline), a full-turn joint (the turret)
  unwrapped so that it takes the short way between postures when its limits allow it.
- :func:`task_reference`: all of it at times t, as the controller's
  :class:`~mmstab.control.layout.StepReference` (ξ_des, ξ̇_ref, q_ref, q̇_ref), rates per second.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple, Protocol

import numpy as np
from numpy.typing import ArrayLike
from scipy.interpolate import CubicSpline

from mmstab.control.layout import StepReference
from mmstab.model.robot import FloatArray
from mmstab.paths.base import BasePath
from mmstab.terrain import Terrain, place_local

#: A joint whose range is at least a full turn less this [rad] is unwrapped (the turret).
FULL_TURN_TOL = 1e-6


class PlanLike(Protocol):
    """What the reference needs of a plan (the planner's ``Plan``)."""

    @property
    def fractions(self) -> FloatArray:
        """Path fractions (K,) in [0, 1), increasing."""
        ...

    @property
    def target_com(self) -> FloatArray:
        """Arm-CoM targets in the body frame (K, 3) [m]."""
        ...


class PathSample(NamedTuple):
    """A reference sampled at path fractions: ``value`` (N, n) and ``rate`` d/ds (N, n)."""

    value: FloatArray
    rate: FloatArray


def circle_pose(circle: BasePath, s: ArrayLike) -> PathSample:
    """Reference base pose (x, y, γ) in M at fractions s, and its derivative d/ds (N, 3).

    Any base path (:class:`mmstab.paths.base.BasePath`); a route's fraction is its time
    fraction.
    """
    value, rate = circle.pose_rate(s)
    return PathSample(value, rate)


def place_on_path(
    circle: BasePath,
    terrain: Terrain,
    s: ArrayLike,
    point_body: PathSample,
    pose_speed: ArrayLike | None = None,
) -> PathSample:
    """Body points placed in M with the reference base pose, and their rate d/ds.

    Args:
        circle: the base path.
        terrain: the ground (gives the local ground of each reference pose).
        s: path fractions (N,) [-].
        point_body: points in B (N, 3) [m] and their rates d/ds (N, 3) [m].
        pose_speed: the base pose's share of the rate (N,) [-] (0 where the base waits
            while the point moves); None: 1.

    Returns:
        The placed points (N, 3) [m] and d/ds = ∂place/∂pose · pose' + M_R_B · p' (N, 3) [m].
    """
    pose, dpose = circle_pose(circle, s)
    if pose_speed is not None:
        dpose = dpose * np.asarray(pose_speed, dtype=float)[:, None]
    placed = place_local(pose, terrain.local_ground(pose), point_body.value)
    rate = np.einsum("nij,nj->ni", placed.d_pose, dpose)
    rate += np.einsum("nij,nj->ni", placed.d_point, point_body.rate)
    return PathSample(placed.points, rate)


def base_reference(
    circle: BasePath, terrain: Terrain, s: ArrayLike, base_offset: float
) -> PathSample:
    """Base task rows [g_bx, g_by, γ] at fractions s (N, 3), and d/ds.

    Args:
        circle: the base path.
        terrain: the ground.
        s: path fractions (N,) [-].
        base_offset: control point ahead of the body origin [m] (as the controller's).
    """
    pose, dpose = circle_pose(circle, s)
    fixed = np.broadcast_to([base_offset, 0.0, 0.0], pose.shape)
    point = place_on_path(circle, terrain, s, PathSample(fixed, np.zeros_like(pose)))
    return PathSample(
        np.column_stack([point.value[:, :2], pose[:, 2]]),
        np.column_stack([point.rate[:, :2], dpose[:, 2]]),
    )


def initial_state(circle: BasePath, arm: ArrayLike, lateral_offset: float = 0.0) -> FloatArray:
    """A run's first state: the path's start pose, shifted sideways, sprockets at zero.

    Args:
        circle: the base path (its pose at s = 0).
        arm: the arm posture (n,) [rad] (e.g. the robot's stowed posture or a plan's first).
        lateral_offset: shift of the base to the left of the path [m].

    Returns:
        [x, y, γ, θ_l, θ_r, θ_0..θ_{n-1}] (5 + n,) [m, m, rad, rad...].
    """
    pose = circle.pose_at(0.0)[0]
    left = np.array([-np.sin(pose[2]), np.cos(pose[2])])
    arm = np.asarray(arm, dtype=float)
    if arm.ndim != 1 or arm.size == 0:
        raise ValueError(f"the arm posture must be (n,), got {arm.shape}")
    return np.r_[pose[:2] + lateral_offset * left, pose[2], 0.0, 0.0, arm]


def _check_fractions(f: FloatArray, values: FloatArray, name: str) -> None:
    if f.ndim != 1 or f.size == 0 or values.ndim != 2 or values.shape[0] != f.size:
        raise ValueError(f"plan fractions {f.shape} and {name} {values.shape} do not match")
    if f[0] < 0 or f[-1] >= 1 or np.any(np.diff(f) <= 0):
        raise ValueError("plan fractions must increase strictly within [0, 1)")


def periodic_spline(
    fractions: ArrayLike, values: ArrayLike, name: str = "values"
) -> Callable[[ArrayLike], PathSample]:
    """The periodic cubic spline (period 1 in s) through ``values`` (K, n) at ``fractions`` (K,).

    Args:
        fractions: path fractions (K,) increasing in [0, 1) [-].
        values: the knots' values (K, n) [any unit].
        name: what the values are, for messages.

    Returns:
        ``f(s) -> PathSample``: value (N, n) and d/ds (N, n) at fractions s (any real s).
    """
    f = np.asarray(fractions, dtype=float)
    v = np.asarray(values, dtype=float)
    _check_fractions(f, v, name)
    if f.size == 1:

        def constant(s: ArrayLike) -> PathSample:
            n = np.atleast_1d(np.asarray(s, dtype=float)).size
            return PathSample(np.tile(v[0], (n, 1)), np.zeros((n, v.shape[1])))

        return constant
    spline = CubicSpline(np.r_[f, f[0] + 1], np.vstack([v, v[:1]]), bc_type="periodic")
    dspline = spline.derivative()

    def periodic(s: ArrayLike) -> PathSample:
        s = np.atleast_1d(np.asarray(s, dtype=float))
        u = f[0] + np.mod(s - f[0], 1.0)  # into the spline's period [f0, f0 + 1)
        return PathSample(spline(u), dspline(u))

    return periodic


def periodic_polyline(
    fractions: ArrayLike, values: ArrayLike, name: str = "values"
) -> Callable[[ArrayLike], PathSample]:
    """Straight moves between consecutive ``values`` (K, n) at ``fractions`` (K,), period 1.

    Between two knots the value moves on the straight line joining them (a polyline that
    was checked stays checked), at rest at each knot: the time-scaling is the cubic
    smoothstep 3τ² − 2τ³ of the interval's fraction τ, so the rate is continuous (0 at the
    knots) and at most 1.5 times the interval's mean rate.

    Args:
        fractions: path fractions (K,) increasing in [0, 1) [-].
        values: the knots' values (K, n) [any unit].
        name: what the values are, for messages.

    Returns:
        ``f(s) -> PathSample``: value (N, n) and d/ds (N, n) at fractions s (any real s).
    """
    f = np.asarray(fractions, dtype=float)
    v = np.asarray(values, dtype=float)
    _check_fractions(f, v, name)
    x, y = np.r_[f, f[0] + 1], np.vstack([v, v[:1]])
    h, step = np.diff(x), np.diff(y, axis=0)

    def polyline(s: ArrayLike) -> PathSample:
        u = f[0] + np.mod(np.atleast_1d(np.asarray(s, dtype=float)) - f[0], 1.0)
        k = np.clip(np.searchsorted(x, u, side="right") - 1, 0, len(h) - 1)
        tau = np.clip((u - x[k]) / h[k], 0.0, 1.0)
        ease, rate = tau * tau * (3 - 2 * tau), 6 * tau * (1 - tau) / h[k]
        return PathSample(y[k] + ease[:, None] * step[k], rate[:, None] * step[k])

    return polyline


def arm_reference(
    plan: PlanLike, circle: BasePath, terrain: Terrain
) -> Callable[[ArrayLike], PathSample]:
    """The arm-CoM reference in M along the lap, from a plan's body-frame targets.

    Args:
        plan: ``fractions`` (K,) increasing in [0, 1) and ``target_com`` (K, 3) [m] in B.
        circle: the base path (gives the reference base pose at each s).
        terrain: the ground.

    Returns:
        ``ref(s) -> PathSample`` with g_a^M (N, 3) [m] and d g_a^M / ds (N, 3) [m].

    Raises:
        ValueError: fractions not increasing in [0, 1), or shapes that do not match.
    """
    if np.ndim(plan.target_com) != 2 or np.shape(plan.target_com)[1] != 3:
        raise ValueError(f"plan target_com {np.shape(plan.target_com)} must be (K, 3)")
    com_body = periodic_spline(plan.fractions, plan.target_com, "target_com")

    def reference(s: ArrayLike) -> PathSample:
        s = np.atleast_1d(np.asarray(s, dtype=float))
        return place_on_path(circle, terrain, s, com_body(s))

    return reference


def unwrap_postures(postures: ArrayLike, lower: ArrayLike, upper: ArrayLike) -> FloatArray:
    """Postures (K, 4) with each full-turn joint on the branch a periodic spline should use.

    A joint whose range ``upper − lower`` is at least 2π (the turret, [0, 2π]) is first put
    into its limits (an angle outside them moves into [lower, lower + 2π)), then unwrapped
    around the closed sequence (last posture back to the first) so that consecutive postures
    differ by at most π, and shifted by a multiple of 2π into its limits. If that short way
    does not fit the limits (it would cross the stop, e.g. 0.2 → 6.1 rad on [0, 2π]) or winds
    a net turn over the lap, the joint keeps the wrapped angles: the long way round, within
    the limits. Other joints are unchanged.

    Args:
        postures: arm postures (K, 4) [rad].
        lower: joint lower limits (4,) [rad].
        upper: joint upper limits (4,) [rad].
    """
    q = np.array(postures, dtype=float, ndmin=2)
    lo, hi = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    for j in np.flatnonzero(hi - lo >= 2 * np.pi - FULL_TURN_TOL):
        inside = (q[:, j] >= lo[j]) & (q[:, j] <= hi[j])
        wrapped = np.where(inside, q[:, j], lo[j] + np.mod(q[:, j] - lo[j], 2 * np.pi))
        closed = np.unwrap(np.r_[wrapped, wrapped[0]])
        q[:, j] = wrapped
        if abs(closed[-1] - closed[0]) > np.pi:  # a net turn per lap: no periodic short way
            continue
        short = closed[:-1]
        short = short + 2 * np.pi * np.ceil((lo[j] - short.min()) / (2 * np.pi) - FULL_TURN_TOL)
        if short.max() <= hi[j]:
            q[:, j] = short
    return q


def posture_reference(
    fractions: ArrayLike,
    postures: ArrayLike,
    lower: ArrayLike,
    upper: ArrayLike,
    *,
    linear: bool = False,
) -> Callable[[ArrayLike], PathSample]:
    """The arm posture reference q_ref(s) along the lap: the plan's postures interpolated.

    The postures are unwrapped (:func:`unwrap_postures`) and joined by the periodic cubic
    spline that :func:`arm_reference` uses for the CoMs, or with ``linear`` by straight
    joint moves at rest at each posture (:func:`periodic_polyline`: a plan whose moves
    between postures were checked, the roadmap's, is followed on those moves). Where the
    spline overshoots a joint limit between postures, the value is clipped to the limit
    and its rate set to zero.

    Args:
        fractions: path fractions (K,) increasing in [0, 1) [-].
        postures: arm postures at them (K, 4) [rad], within the limits.
        lower: joint lower limits (4,) [rad].
        upper: joint upper limits (4,) [rad].
        linear: straight moves between the postures (:func:`periodic_polyline`).

    Returns:
        ``ref(s) -> PathSample`` with q_ref (N, 4) [rad] and d q_ref / ds (N, 4) [rad].

    Raises:
        ValueError: fractions not increasing in [0, 1), or shapes that do not match.
    """
    lo, hi = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    interpolate = periodic_polyline if linear else periodic_spline
    spline = interpolate(fractions, unwrap_postures(postures, lo, hi), "postures")

    def reference(s: ArrayLike) -> PathSample:
        q, dq = spline(s)
        inside = (q >= lo) & (q <= hi)
        return PathSample(np.clip(q, lo, hi), np.where(inside, dq, 0.0))

    return reference


class ApproachLike(Protocol):
    """The arm's start-up reference over the first ``duration`` seconds (``approach.Approach``)."""

    @property
    def duration(self) -> float:
        """Its length [s]."""
        ...

    def posture(self, t: ArrayLike) -> PathSample:
        """q_ref (N, 4) [rad] and its rate (N, 4) [rad/s] at times t (N,) [s]."""
        ...

    def com_body(self, t: ArrayLike) -> PathSample:
        """Body-frame arm-CoM reference (N, 3) [m] and its rate (N, 3) [m/s] at times t."""
        ...


def task_reference(
    circle: BasePath,
    terrain: Terrain,
    lap_time: float,
    base_offset: float,
    arm: Callable[[ArrayLike], PathSample],
    posture: Callable[[ArrayLike], PathSample],
    t: ArrayLike,
    approach: ApproachLike | None = None,
    timing: Callable[[ArrayLike], PathSample] | None = None,
) -> StepReference:
    """The controller's reference at times t for a constant-speed lap (rates per second).

    Args:
        circle: the base path.
        terrain: the ground (the local ground of the reference poses is in the reference).
        lap_time: time for one lap [s].
        base_offset: base control point ahead of the body origin [m].
        arm: the arm-CoM reference (e.g. from :func:`arm_reference`).
        posture: the arm posture reference (e.g. from :func:`posture_reference`).
        t: times (N,) [s].
        approach: the arm's start-up reference; for t < ``approach.duration`` it replaces the
            arm-CoM rows (its body-frame CoM placed with the reference base pose) and the
            posture reference (at real times t).
        timing: real times t -> nominal times τ [s] and dτ/dt [-] (the time law, a wait at
            the start: :meth:`mmstab.control.approach.ArmReferences.nominal`); the
            references are taken at τ and their rates scaled by dτ/dt. None: τ = t.

    Returns:
        ξ_des (N, 6), ξ̇_ref (N, 6) [m/s, rad/s], q_ref (N, 4) [rad], q̇_ref (N, 4) [rad/s],
        the local ground (N, 3); ``.pack()`` gives the (N, 23) rows the ``step`` Function takes.
    """
    t = np.atleast_1d(np.asarray(t, dtype=float))
    tau, speed = (t, np.ones_like(t)) if timing is None else timing(t)
    s, ds_dt = tau / lap_time, speed / lap_time
    base, arm_s, q = base_reference(circle, terrain, s, base_offset), arm(s), posture(s)
    ref = StepReference(
        xi_des=np.hstack([base.value, arm_s.value]),
        xi_dot_ref=np.hstack([base.rate, arm_s.rate]) * ds_dt[:, None],
        q_ref=np.array(q.value),
        q_dot_ref=q.rate * ds_dt[:, None],
        ground=terrain.local_ground(circle_pose(circle, s).value),
    )
    if approach is not None and np.any(early := t < approach.duration):
        g_B, dg_B = approach.com_body(t[early])
        point = PathSample(g_B, dg_B * lap_time)
        placed = place_on_path(circle, terrain, s[early], point, speed[early])
        ref.xi_des[early, 3:], ref.xi_dot_ref[early, 3:] = placed.value, placed.rate / lap_time
        ref.q_ref[early], ref.q_dot_ref[early] = approach.posture(t[early])
    return ref
