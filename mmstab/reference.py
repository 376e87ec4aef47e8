"""Task references along the base circle: ξ_des and its rate for the tracking controller.

Everything is a function of the path fraction s ∈ [0, 1) (one lap; s = t / lap_time for a
constant-speed lap), vectorised over s, and returns the value and its derivative d/ds (so the
feed-forward is ξ̇_ref = d ξ_des/ds / lap_time):

- :func:`base_reference`: the base rows [g_bx, g_by, γ] of ξ: the control point a distance
  ``base_offset`` ahead of the circle's reference pose, and the tangent heading.
- :func:`arm_reference`: the arm-CoM rows [g_ax, g_ay, g_az] in S: the planned body-frame CoM
  targets interpolated along the lap (periodic cubic spline in s) and placed with the
  reference base pose, g_a^S(s) = [x, y, 0](s) + Rz(γ(s)) g_a^B(s).
- :func:`task_reference`: both, stacked into ξ_des (N, 6) and ξ̇_ref (N, 6) at times t.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple, Protocol

import numpy as np
from numpy.typing import ArrayLike
from scipy.interpolate import CubicSpline

from mmstab.robot import FloatArray
from mmstab.terrain import CirclePath


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


def circle_pose(circle: CirclePath, s: ArrayLike) -> PathSample:
    """Reference base pose (x, y, γ) in S at fractions s, and its derivative d/ds (N, 3)."""
    s = np.atleast_1d(np.asarray(s, dtype=float))
    dphi = circle.sign * 2 * np.pi  # d phi / ds [rad]
    phi = circle.start_angle + dphi * s
    rate = np.stack(
        [
            -circle.radius * np.sin(phi) * dphi,
            circle.radius * np.cos(phi) * dphi,
            np.full_like(s, dphi),
        ],
        axis=1,
    )
    return PathSample(circle.pose_at(s), rate)


def base_reference(circle: CirclePath, s: ArrayLike, base_offset: float) -> PathSample:
    """Base task rows [g_bx, g_by, γ] at fractions s (N, 3), and d/ds.

    Args:
        circle: the base path.
        s: path fractions (N,) [-].
        base_offset: control point ahead of the body origin [m] (as the controller's).
    """
    pose, dpose = circle_pose(circle, s)
    c, sn = np.cos(pose[:, 2]), np.sin(pose[:, 2])
    value = pose + base_offset * np.stack([c, sn, np.zeros_like(c)], axis=1)
    rate = dpose + base_offset * dpose[:, 2:3] * np.stack([-sn, c, np.zeros_like(c)], axis=1)
    return PathSample(value, rate)


def arm_reference(plan: PlanLike, circle: CirclePath) -> Callable[[ArrayLike], PathSample]:
    """The arm-CoM reference in S along the lap, from a plan's body-frame targets.

    Args:
        plan: ``fractions`` (K,) increasing in [0, 1) and ``target_com`` (K, 3) [m] in B.
        circle: the base path (gives the reference base pose at each s).

    Returns:
        ``ref(s) -> PathSample`` with g_a^S (N, 3) [m] and d g_a^S / ds (N, 3) [m].

    Raises:
        ValueError: fractions not increasing in [0, 1), or shapes that do not match.
    """
    f = np.asarray(plan.fractions, dtype=float)
    com = np.asarray(plan.target_com, dtype=float)
    if f.ndim != 1 or com.shape != (f.size, 3) or f.size == 0:
        raise ValueError(f"plan fractions {f.shape} and target_com {com.shape} do not match")
    if f[0] < 0 or f[-1] >= 1 or np.any(np.diff(f) <= 0):
        raise ValueError("plan fractions must increase strictly within [0, 1)")
    if f.size == 1:

        def com_body(s: FloatArray) -> PathSample:
            return PathSample(np.tile(com[0], (s.size, 1)), np.zeros((s.size, 3)))
    else:
        spline = CubicSpline(np.r_[f, f[0] + 1], np.vstack([com, com[:1]]), bc_type="periodic")
        dspline = spline.derivative()

        def com_body(s: FloatArray) -> PathSample:
            u = f[0] + np.mod(s - f[0], 1.0)  # into the spline's period [f0, f0 + 1)
            return PathSample(spline(u), dspline(u))

    def reference(s: ArrayLike) -> PathSample:
        s = np.atleast_1d(np.asarray(s, dtype=float))
        (pose, dpose), (g_B, dg_B) = circle_pose(circle, s), com_body(s)
        c, sn = np.cos(pose[:, 2]), np.sin(pose[:, 2])
        rotated = np.stack([c * g_B[:, 0] - sn * g_B[:, 1], sn * g_B[:, 0] + c * g_B[:, 1]], 1)
        d_rot = np.stack([c * dg_B[:, 0] - sn * dg_B[:, 1], sn * dg_B[:, 0] + c * dg_B[:, 1]], 1)
        value = np.column_stack([pose[:, :2] + rotated, g_B[:, 2]])
        # d/ds [Rz(γ) g] = γ' ẑ × (Rz g) + Rz g'
        turn = dpose[:, 2:3] * np.stack([-rotated[:, 1], rotated[:, 0]], axis=1)
        rate = np.column_stack([dpose[:, :2] + turn + d_rot, dg_B[:, 2]])
        return PathSample(value, rate)

    return reference


def task_reference(
    circle: CirclePath,
    lap_time: float,
    base_offset: float,
    arm: Callable[[ArrayLike], PathSample],
    t: ArrayLike,
) -> PathSample:
    """ξ_des (N, 6) and ξ̇_ref (N, 6) [per second] at times t for a constant-speed lap.

    Args:
        circle: the base path.
        lap_time: time for one lap [s].
        base_offset: base control point ahead of the body origin [m].
        arm: the arm-CoM reference (e.g. from :func:`arm_reference`).
        t: times (N,) [s].
    """
    s = np.atleast_1d(np.asarray(t, dtype=float)) / lap_time
    base, arm_s = base_reference(circle, s, base_offset), arm(s)
    return PathSample(
        np.hstack([base.value, arm_s.value]), np.hstack([base.rate, arm_s.rate]) / lap_time
    )
