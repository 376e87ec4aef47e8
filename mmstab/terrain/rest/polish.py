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
``max_k (f_k + J_k d) + g . d`` is a linear programme in ``(d, t)`` (:func:`box_minimax`);
the step is taken if ``V`` falls by at least a tenth of what the model predicts, and
``delta`` shrinks otherwise. It ends where the model predicts no decrease: a stationary
point of ``V``. With the touching contacts on smooth ground that is the rounds' own fixed
point (the CoM above the triangle, or the edge, they span). With a contact on a steep face
the minimum lets it slide down the face, and the contacts there may not hold the CoM
(μ < 0 at a settled rest): the robot would rock off the pose, which the plan's rock check
(:mod:`mmstab.stability.rock`) judges. A row that does not end within :data:`MAX_ROUNDS`
keeps the rounds' answer and stays unsettled.

The C backend (``RestSettings.backend``) runs the same rounds in ``kernel.c``
(``mmstab_polish``, 20-100 times faster); its step's minimax takes the pieces in one at a
time, from the highest at d = 0, each time the one highest at the minimiser found so far,
until none rises above them there: the minimiser of the few it took (at most 96; beyond,
the row keeps the rounds' answer) is the whole function's. Both give the same rests to
1e-8 rad (tested).
"""

from __future__ import annotations

from functools import lru_cache
from itertools import combinations

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from mmstab.terrain.heightmap import FloatArray, Heightmap
from mmstab.terrain.rest.geometry import heights, jacobian, lift, rotations
from mmstab.terrain.rest.kernel import polish_kernel
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


#: Pieces above which :func:`box_minimax` hands the programme to HiGHS (the vertices grow as
#: the cube of the pieces; HiGHS costs about a millisecond a call whatever their number).
MAX_PIECES = 32


@lru_cache(maxsize=MAX_PIECES + 1)
def triples(m: int) -> np.ndarray:
    """The index triples of m pieces (C(m, 3), 3), m <= MAX_PIECES (made on first use)."""
    return np.array(list(combinations(range(m), 3)), dtype=int).reshape(-1, 3)


def upper_hull(J: FloatArray, a: FloatArray) -> BoolArray:
    """(K,) the pieces ``a_k + J_k . d`` that are the largest at some d: upper-hull vertices.

    The largest piece at d maximises ``(d, 1) . (J_k, a_k)``, so it is a vertex of a facet of
    the points' hull whose normal points up; a degenerate set (Qhull cannot build its hull:
    fewer than 5 points, or all on a plane) keeps every piece.
    """
    keep = np.ones(len(a), dtype=bool)
    if len(a) < 5:
        return keep
    try:
        hull = ConvexHull(np.c_[J, a])
    except QhullError:
        return keep
    keep[:] = False
    keep[np.unique(hull.simplices[hull.equations[:, 2] > 0])] = True
    return keep


def box_minimax(
    a: FloatArray, J: FloatArray, g: FloatArray, delta: float
) -> tuple[FloatArray, float]:
    """``min over |d_i| <= delta of max_k (a_k + J_k . d) + g . d``: the step and its value.

    A convex piecewise-linear function of two variables takes its least value over the box at
    a vertex of its pieces' arrangement: a corner of the box, where two pieces meet on an
    edge of it, or where three meet. Only pieces that can be the largest somewhere in the box
    are kept (their range over the box reaches the largest lower bound, and the point
    ``(J_k, a_k)`` is a vertex of the points' upper hull, :func:`upper_hull`); the vertices
    are enumerated and the least kept. Beyond :data:`MAX_PIECES` pieces HiGHS solves the linear
    programme in ``(d, t)`` instead (the test holds one against the other).

    Args:
        a: (K,) the pieces' values at d = 0 [m].
        J: (K, 2) their gradients [m/rad].
        g: (2,) the linear term's gradient [m/rad].
        delta: the box's half-width [rad] (> 0).
    """
    reach = np.abs(J).sum(axis=1) * delta
    keep = a + reach >= np.max(a - reach) - 1e-15
    keep &= upper_hull(J, a)
    a, J = a[keep], J[keep]
    m = len(a)
    if m > MAX_PIECES:
        from scipy.optimize import linprog  # here: SciPy's optimize costs 0.1 s to import

        lp = linprog(
            [g[0], g[1], 1.0], A_ub=np.c_[J, -np.ones(m)], b_ub=-a,
            bounds=[(-delta, delta), (-delta, delta), (None, None)], method="highs",
        )  # fmt: skip
        if lp.status != 0:  # HiGHS gave up: no step (the caller reads it as stationary)
            return np.zeros(2), float(a.max())
        return np.asarray(lp.x[:2], dtype=float), float(lp.fun)
    points = [np.array([[-delta, -delta], [-delta, delta], [delta, -delta], [delta, delta]])]
    if m > 1:
        i, j = np.triu_indices(m, 1)
        n, c = J[i] - J[j], a[j] - a[i]  # the pieces i, j meet on n . d = c
        for axis in (0, 1):  # ... which crosses the edges d_axis = +-delta
            other = 1 - axis
            ok = np.abs(n[:, other]) > 1e-300
            for side in (-delta, delta):
                d = np.empty((int(ok.sum()), 2))
                d[:, axis] = side
                d[:, other] = (c[ok] - n[ok, axis] * side) / n[ok, other]
                points.append(d)
    if m > 2:
        tri = triples(m)
        A = np.stack([J[tri[:, 0]] - J[tri[:, 1]], J[tri[:, 0]] - J[tri[:, 2]]], axis=1)
        b = np.stack([a[tri[:, 1]] - a[tri[:, 0]], a[tri[:, 2]] - a[tri[:, 0]]], axis=1)
        det = A[:, 0, 0] * A[:, 1, 1] - A[:, 0, 1] * A[:, 1, 0]
        ok = np.abs(det) > 1e-300
        A, b, det = A[ok], b[ok], det[ok]
        x = (A[:, 1, 1] * b[:, 0] - A[:, 0, 1] * b[:, 1]) / det  # Cramer's rule
        y = (A[:, 0, 0] * b[:, 1] - A[:, 1, 0] * b[:, 0]) / det
        points.append(np.stack([x, y], axis=1))
    d = np.concatenate(points)
    d = d[(np.abs(d) <= delta * (1 + 1e-12)).all(axis=1)]
    d = np.clip(d, -delta, delta)
    value = (d @ J.T + a).max(axis=1) + d @ g
    k = int(np.argmin(value))
    return d[k], float(value[k])


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
        d, model = box_minimax(f[0], J, grad[0], delta)  # the model's best step in the box
        predicted = z - model
        if not predicted > FLAT:
            return a, True
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
        attitudes, lifts, converged, tips: the arrays given, the rows polished written in
        place (the solver's own arrays: no copy of the lifts, (N, K), for a few rows).
    """
    rows = np.flatnonzero(valid & ~converged & ~tips)
    if rows.size == 0:
        return att, f, converged, tips
    if settings.backend == "c":  # the same rounds in C (kernel.c: mmstab_polish)
        a, fr, reached, tipped = polish_kernel(
            hm.elevation, hm.origin, hm.resolution, c, com[rows], p[rows], settings.max_tilt,
            att[rows],
        )  # fmt: skip
        done = rows[reached]
        att[done], f[done], converged[done] = a[reached], fr[reached], True
        tips[done] = tipped[reached]
        return att, f, converged, tips
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
