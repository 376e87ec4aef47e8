"""The slip limit: where the tracks slide down the ground before the robot tips.

A rigid robot resting on its support carries its whole weight ``m g`` through the contacts.
In the body frame B (z up the support's normal), gravity splits into a normal part
``g_n = -g_B . z`` pressing the tracks on the ground and a tangential part ``g_t`` along it.
With Coulomb friction of coefficient ``friction`` (the same at every contact, isotropic),
the contacts can hold the tangential part only while it stays inside the friction cone of
the total normal force: ``|g_t| <= friction g_n``, i.e. while the tilt of the support
(the angle between gravity and -z_B) stays below ``atan(friction)``. Beyond, the robot
slides whichever way it heads (isotropic friction: the heading enters only through the
resting pose on uneven ground). Assumptions (``docs/stability.md``): quasi-static, the
arm's motion exerts no force on the base, no track drive force (brakes hold the tracks:
the tangential force comes from static friction alone), the ground does not deform or
give way, and the robot's normal is the one of its resting pose.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.terrain.base import DEFAULT_FRICTION, GRAVITY_G, Terrain

FloatArray = np.ndarray


class SlipLimit(NamedTuple):
    """The friction cone at resting poses.

    Attributes:
        tilt: (N,) angle between gravity and -z_B at each pose [rad].
        critical_tilt: ``atan(friction)`` [rad], the tilt at which the tracks slide.
        margin: (N,) ``critical_tilt - tilt`` [rad] (> 0: the tracks hold).
        slides: (N,) tilt beyond the critical tilt.
        friction: the friction coefficient [-].
    """

    tilt: FloatArray
    critical_tilt: float
    margin: FloatArray
    slides: np.ndarray
    friction: float


def support_tilt(gravity_body: ArrayLike) -> FloatArray:
    """Tilt of the support [rad]: angle between gravity (N, 3) or (3,) in B and -z_B.

    Args:
        gravity_body: gravity in the body frame [m/s^2].
    """
    g = np.atleast_2d(np.asarray(gravity_body, dtype=float))
    tangential = np.hypot(g[:, 0], g[:, 1])
    return np.arctan2(tangential, -g[:, 2])  # > pi/2 when the body is upside down


def slip_limit(gravity_body: ArrayLike, friction: float) -> SlipLimit:
    """The friction-cone check of a rigid robot on its support.

    Args:
        gravity_body: gravity in the body frame at each pose (N, 3) or (3,) [m/s^2].
        friction: Coulomb friction coefficient of tracks on ground [-] (> 0).
    """
    tilt = support_tilt(gravity_body)
    critical = float(np.arctan(friction))
    margin = critical - tilt
    return SlipLimit(tilt, critical, margin, ~(margin >= 0), float(friction))


def terrain_slip(terrain: Terrain, poses: ArrayLike) -> SlipLimit:
    """:func:`slip_limit` at resting poses (x [m], y [m], yaw [rad]) (N, 3) on a terrain.

    Uses ``terrain.friction`` (the problem's ``terrain.friction``).
    """
    return slip_limit(terrain.gravity_body(poses), terrain_friction(terrain))


def terrain_friction(terrain: Any) -> float:
    """The terrain's friction coefficient [-] (:data:`DEFAULT_FRICTION` when it has none)."""
    return float(getattr(terrain, "friction", DEFAULT_FRICTION))


def binding_limit(tip_slope: float, slip_slope: float) -> str:
    """Which limit binds first as the slope grows: ``slip`` or ``tip`` (ties: ``tip``).

    Args:
        tip_slope: slope at which the robot tips [rad].
        slip_slope: slope at which the tracks slide [rad].
    """
    return "slip" if slip_slope < tip_slope else "tip"


class ConeSlide(NamedTuple):
    """The slide a path's passes beyond the friction cone cost (:func:`cone_slide`), N samples.

    Attributes:
        excess: (N,) gravity's pull along the support's downhill direction beyond what
            friction holds, ``g (sin tilt - friction cos tilt)`` [m/s^2] (< 0: it holds).
        dwell: (N,) the time the path spends on each sample's cell [s] (inf: at rest).
        slide: (N,) the largest downhill slide within a ``window`` that ends while the path
            is on the sample's cell or up to ``window`` after it (the slide's coast) [m].
    """

    excess: FloatArray
    dwell: FloatArray
    slide: FloatArray


def cone_slide(
    tilt: ArrayLike, times: ArrayLike, friction: float, window: float, rests: bool = True
) -> ConeSlide:
    """The downhill slide within a window where a path passes supports beyond the cone.

    The static model's braked robot (:func:`slip_limit`: the tracks hold by Coulomb friction
    alone, the same coefficient sliding) on a support tilted ``tilt`` beyond ``atan(friction)``
    accelerates downhill relative to its command at ``g (sin tilt - friction cos tilt)``;
    on a support inside the cone friction decelerates a slide at the same expression's
    magnitude until it stops. Each sample holds for its cell of the path's time law (half way
    to its neighbours' times); the slide's speed integrates that acceleration cell by cell
    (never below zero), its distance the speed. With ``rests`` the path starts and ends at
    rest: the first and last cells last forever, so a support beyond the cone there slides
    indefinitely (``slide`` inf), as does any cell the path dwells on long enough.

    Args:
        tilt: (N,) the support's tilt at each sample [rad] (NaN: off the map, holds).
        times: (N,) when the path reaches each sample [s], non-decreasing.
        friction: Coulomb friction coefficient [-].
        window: the slide counts within this much time [s] (``physics.slip_window``).
        rests: the path is at rest before its first and after its last sample.
    """
    th = np.asarray(tilt, dtype=float)
    t = np.asarray(times, dtype=float)
    g = float(np.linalg.norm(GRAVITY_G))
    excess = np.where(np.isfinite(th), g * (np.sin(th) - friction * np.cos(th)), -g * friction)
    if th.size == 0:
        return ConeSlide(excess, np.zeros(0), np.zeros(0))
    mid = (t[1:] + t[:-1]) / 2
    start = np.r_[-np.inf if rests else t[0], mid]
    end = np.r_[mid, np.inf if rests else t[-1]]
    dwell = end - start
    n = len(th)
    if not (excess > 0).any():
        return ConeSlide(excess, dwell, np.zeros(n))
    if rests and (excess[0] > 0 or excess[-1] > 0):  # at rest on it: the slide never stops
        first = excess[0] > 0
        slide = np.zeros(n)
        slide[0 if first else -1] = np.inf
        if first and excess[-1] > 0:
            slide[-1] = np.inf
        if n > 2:
            slide[1:-1] = cone_slide(th[1:-1], t[1:-1], friction, window, rests=False).slide
        return ConeSlide(excess, dwell, slide)
    # a cell of infinite dwell inside the cone holds (the slide stops there)
    dt = np.where(np.isfinite(dwell), dwell, 0.0)
    t0 = np.where(np.isfinite(start), start, end)  # a rest cell: no motion, zero length
    v0, x0 = np.zeros(n), np.zeros(n)
    v, x = 0.0, 0.0
    for k in range(n):  # cell by cell: the speed at its start, the distance slid before it
        v0[k], x0[k] = v, x
        a = excess[k]
        stop = dt[k] if a >= 0 or v + a * dt[k] >= 0 else v / -a
        x += v * stop + 0.5 * a * stop * stop
        v = max(v + a * dt[k], 0.0)

    def slid(when: FloatArray) -> FloatArray:  # the distance slid by ``when`` [m]
        k = np.clip(np.searchsorted(t0, when, side="right") - 1, 0, n - 1)
        a = excess[k]
        tau = np.clip(when - t0[k], 0.0, dt[k])
        with np.errstate(divide="ignore", invalid="ignore"):
            tau = np.where((a < 0) & (v0[k] + a * tau < 0), v0[k] / -a, tau)
        return x0[k] + v0[k] * tau + 0.5 * a * tau * tau

    ends = np.r_[t0, t0 + dt]
    candidates = np.unique(np.r_[ends, ends + window])  # the window's ends where it peaks
    windowed = slid(candidates) - slid(candidates - window)
    slide = np.zeros(n)
    for k in range(n):
        inside = (candidates >= t0[k]) & (candidates <= t0[k] + dt[k] + window)
        slide[k] = windowed[inside].max(initial=0.0)
    return ConeSlide(excess, dwell, slide)
