"""The rests the Newton rounds did not settle, found as the minimum of the potential energy.

Lowered at ``(x, y, yaw)``, the body rests at the attitude ``a = (roll, pitch)`` where the CoM
is lowest: ``V(a) = max_k f_k(a) + (G_R_B(a) g_o)_z`` [m] (``f_k`` the lift candidate k
needs to touch, :mod:`mmstab.terrain.rest.poses`; ``g_o`` the CoM in B). The solver's rounds
(supporting triangle, then a Newton step on it) reach that minimum in a few rounds where the
ground is smooth under the touching candidates. Where a candidate sits on a kerb's edge or a
ditch's rim, the ground's slope jumps under it, the Newton step overshoots onto another
triangle and back, and the rounds can end far from the rest: 5-10 degrees of pitch and
centimetres of CoM height above it on the validation routes' kerbs, with the CoM outside the
contacts they end on (μ < 0 for a robot that stands).

:func:`polish` takes those rows (valid, not settled, not tipped) to the minimum of ``V`` by
sequential linear programming in a trust region (the classic method for a maximum of smooth
functions): at ``a``, each lift and the CoM's height linearised (the ground's slope under
each candidate included), the step ``d`` within ``|d| <= delta`` that minimises
``max_k (f_k + J_k d) + g . d`` is a linear programme in ``(d, t)``; the step is taken if
``V`` falls by at least a tenth of what the model predicts, and ``delta`` shrinks otherwise.
It ends where the model predicts no decrease (a stationary point of ``V``: the CoM above the
triangle, or the edge, the touching candidates span), which is the rest the rounds were
looking for; a row that does not end within :data:`MAX_ROUNDS` keeps the rounds' answer and
stays unsettled.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import linprog

from mmstab.terrain.heightmap import FloatArray, Heightmap
from mmstab.terrain.rest.geometry import heights, jacobian, lift, rotations
from mmstab.terrain.rest.types import BoolArray, RestSettings

#: Trust-region rounds per row before it is left unsettled.
MAX_ROUNDS = 200
#: The first trust region's half-width [rad], and the largest.
FIRST_DELTA, MAX_DELTA = 0.02, 0.1
#: A model decrease below this [m] is none: the attitude is stationary.
FLAT = 1e-13
#: The trust region's half-width [rad] below which the attitude is stationary.
SMALLEST_DELTA = 1e-10


def energy(
    hm: Heightmap, c: FloatArray, com: FloatArray, pose: FloatArray, att: FloatArray
) -> FloatArray:
    """``V`` [m] at attitudes ``att`` (m, 2) [rad] of one pose (3,), CoM ``com`` (3,) in B [m].

    Infinite where a candidate needs ground off the map.
    """
    m = att.shape[0]
    xy, yaw = np.tile(pose[:2], (m, 1)), np.full(m, pose[2])
    f, valid = heights(hm, c, xy, yaw, att)
    R = rotations(yaw, att[:, 0], att[:, 1])[0]
    return np.where(valid, f.max(axis=1) + R[:, 2, :] @ com, np.inf)


def lowest(
    hm: Heightmap, c: FloatArray, com: FloatArray, pose: FloatArray, att: FloatArray
) -> tuple[FloatArray, bool]:
    """The attitude (2,) [rad] of V's minimum reached from ``att`` (2,), and whether it ended.

    Args:
        hm: the ground.
        c: (K, 3) contact candidates in B [m].
        com: the overall CoM in B (3,) [m].
        pose: (x, y, yaw) in G [m, m, rad].
        att: the start (roll, pitch) [rad].
    """
    a = np.asarray(att, dtype=float).copy()
    v = float(energy(hm, c, com, pose, a[None])[0])
    if not np.isfinite(v):
        return a, False
    delta, every = FIRST_DELTA, np.arange(c.shape[0])[None]
    for _ in range(MAX_ROUNDS):
        f, _, grad, ok, m = lift(hm, c, com[None], pose[None, :2], pose[None, 2], a[None])
        z = float(f[0].max())
        J = jacobian(hm, m, pose[None, :2], every)[0]  # (K, 2), the ground's slope included
        # min over (d, t) of t + g.d with f_k + J_k d <= t and |d_i| <= delta
        lp = linprog(
            [grad[0, 0], grad[0, 1], 1.0],
            A_ub=np.c_[J, -np.ones(len(J))], b_ub=-f[0],
            bounds=[(-delta, delta), (-delta, delta), (None, None)], method="highs",
        )  # fmt: skip
        predicted = z - lp.fun if lp.status == 0 else 0.0
        if lp.status != 0 or predicted <= FLAT:
            return a, True
        d = lp.x[:2]
        v_new = float(energy(hm, c, com, pose, (a + d)[None])[0])
        rho = (v - v_new) / predicted
        if rho > 0.1:
            a, v = a + d, v_new
            if rho > 0.75 and np.abs(d).max() >= 0.99 * delta:
                delta = min(2.0 * delta, MAX_DELTA)
        else:
            delta *= 0.25
            if delta < SMALLEST_DELTA:
                return a, True
    return a, False


def polish(
    hm: Heightmap,
    c: FloatArray,
    com: FloatArray,
    p: FloatArray,
    att: FloatArray,
    f: FloatArray,
    valid: BoolArray,
    converged: BoolArray,
    tips: BoolArray,
    settings: RestSettings,
) -> tuple[FloatArray, FloatArray, BoolArray, BoolArray]:
    """The solver's answer with its unsettled rows taken to V's minimum (module text).

    Args:
        hm: the ground.
        c: (K, 3) contact candidates in B [m].
        com: (N, 3) overall CoM in B [m].
        p: (N, 3) poses (x, y, yaw) in G [m, m, rad].
        att: (N, 2) the rounds' attitudes [rad].
        f: (N, K) the lifts there [m].
        valid: (N,) the ground under every candidate known.
        converged: (N,) the rounds settled.
        tips: (N,) the rounds found the robot tipping.
        settings: the solver's settings (``max_tilt``: beyond it the robot tips).

    Returns:
        attitudes, lifts, converged, tips (copies; the rows polished).
    """
    rows = np.flatnonzero(valid & ~converged & ~tips)
    if rows.size == 0:
        return att, f, converged, tips
    att, f, converged, tips = att.copy(), f.copy(), converged.copy(), tips.copy()
    for i in rows:
        a, ended = lowest(hm, c, com[i], p[i], att[i])
        if not ended:
            continue
        fi, ok = heights(hm, c, p[i : i + 1, :2], p[i : i + 1, 2], a[None])
        if not ok[0]:
            continue
        att[i], f[i], converged[i] = a, fi[0], True
        tips[i] = bool((np.abs(a) > settings.max_tilt).any())
    return att, f, converged, tips
