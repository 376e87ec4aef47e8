"""The supporting triangle: a 2-D linear programme solved by simplex pivots, batched.

``min_{t,d} t - q . d  s.t.  t >= f_k + J_k . d`` for many problems at once: the facet
of the upper convex hull of the lifted points ``(J_k, f_k)`` above ``q``
(:mod:`mmstab.terrain.rest` uses it to pick the three contacts that carry the robot).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


def _bary(P: FloatArray, x: FloatArray) -> FloatArray:
    """Barycentric coordinates (n, 3) of points x (n, 2) in triangles P (n, 3, 2)."""
    a, b, c = P[:, 0], P[:, 1], P[:, 2]
    ab, ac, ax = b - a, c - a, x - a
    den = ab[:, 0] * ac[:, 1] - ab[:, 1] * ac[:, 0]
    den = np.where(np.abs(den) > 1e-300, den, 1e-300)
    lb = (ax[:, 0] * ac[:, 1] - ax[:, 1] * ac[:, 0]) / den
    lc = (ab[:, 0] * ax[:, 1] - ab[:, 1] * ax[:, 0]) / den
    return np.stack([1.0 - lb - lc, lb, lc], axis=1)


def _bary2(P: FloatArray, x: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
    """:func:`_bary` of two point sets (n, 2) in the same triangles (n, 3, 2)."""
    a, b, c = P[:, 0], P[:, 1], P[:, 2]
    ab, ac = b - a, c - a
    den = ab[:, 0] * ac[:, 1] - ab[:, 1] * ac[:, 0]
    den = np.where(np.abs(den) > 1e-300, den, 1e-300)
    out = []
    for pt in (x, y):
        ax = pt - a
        lb = (ax[:, 0] * ac[:, 1] - ax[:, 1] * ac[:, 0]) / den
        lc = (ab[:, 0] * ax[:, 1] - ab[:, 1] * ax[:, 0]) / den
        out.append(np.stack([1.0 - lb - lc, lb, lc], axis=1))
    return out[0], out[1]


def _plane(P: FloatArray, F: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(t (n,), d (n, 2)) of the plane ``value(J) = t - d . J`` through 3 lifted points."""
    a, b, c = P[:, 0], P[:, 1], P[:, 2]
    ab, ac = b - a, c - a
    den = ab[:, 0] * ac[:, 1] - ab[:, 1] * ac[:, 0]
    den = np.where(np.abs(den) > 1e-300, den, 1e-300)
    fb, fc = F[:, 1] - F[:, 0], F[:, 2] - F[:, 0]
    gx = (fb * ac[:, 1] - fc * ab[:, 1]) / den  # gradient of the plane's value over J
    gy = (-fb * ac[:, 0] + fc * ab[:, 0]) / den
    t = F[:, 0] - gx * a[:, 0] - gy * a[:, 1]
    return t, -np.stack([gx, gy], axis=1)


def support_lp(
    J: FloatArray,
    f: FloatArray,
    q: FloatArray,
    basis: NDArray[np.int_] | None = None,
    corners: NDArray[np.int_] | None = None,
) -> tuple[FloatArray, FloatArray, NDArray[np.int_], BoolArray]:
    """Solve ``min_{t,d} t - q . d  s.t.  t >= f_k + J_k . d`` for n problems at once.

    The dual is ``max sum_k w_k f_k`` over weights ``w >= 0``, ``sum w = 1``,
    ``sum w_k J_k = q``: the upper hull of the lifted points ``(J_k, f_k)`` above ``q``.
    Simplex pivots on triangles holding ``q``: the most violated point enters, the ratio
    test keeps ``q`` inside; a big-M triangle of artificial points starts it when no
    given triangle holds ``q``.

    Args:
        J: (n, K, 2) constraint slopes.
        f: (n, K) constraint values.
        q: (n, 2) the point whose supporting facet is sought (minus the objective slope).
        basis: (n, 3) a warm-start triangle of indices into K, or ``None``.
        corners: (4,) indices into K of a quadrilateral likely to hold ``q`` (the
            footprint's corners); a triangle of it that does is the cold start.

    Returns:
        ``(t (n,), d (n, 2), basis (n, 3), bounded (n,))``; ``bounded`` is False when ``q``
        lies outside the hull of the ``J_k`` (an artificial vertex stays in the basis).
    """
    n, K = f.shape
    rows = np.arange(n)
    fmax, fmin = f.max(axis=1), f.min(axis=1)
    scale = np.abs(J).max(axis=(1, 2)) + np.abs(q).max(axis=1) + 1.0
    ang = np.pi / 2 + 2 * np.pi / 3 * np.arange(3)
    art = q[:, None, :] + 100.0 * scale[:, None, None] * np.stack([np.cos(ang), np.sin(ang)], -1)
    big = 1e6 * (fmax - fmin + 1.0)
    P = np.concatenate([J, art], axis=1)
    F = np.concatenate([f, -np.repeat(big[:, None], 3, axis=1)], axis=1)
    start = np.tile(np.arange(K, K + 3), (n, 1))
    tries = [] if corners is None else [np.delete(corners, j) for j in range(4)]
    if basis is not None:
        tries.insert(0, basis)
    found = np.zeros(n, dtype=bool)
    for tri in tries:
        if found.all():
            break
        tri = np.broadcast_to(tri, (n, 3))
        lam = _bary(P[rows[:, None], tri], q)
        ok = ~found & (lam >= -1e-12).all(axis=1)
        start[ok] = tri[ok]
        found |= ok
    basis = start
    tol = 1e-12 * (np.maximum(fmax, -fmin) + 1.0)
    t = np.zeros(n)
    d = np.zeros((n, 2))
    idx = rows
    Ji, fi = J, f  # of the problems still pivoting (copies only once some are done)
    for _ in range(4 * K + 12):
        b = basis[idx]
        Pb = P[idx[:, None], b]
        ti, di = _plane(Pb, F[idx[:, None], b])
        t[idx], d[idx] = ti, di
        viol = fi + (Ji @ di[:, :, None])[:, :, 0] - ti[:, None]
        e = np.argmax(viol, axis=1)
        go = viol[np.arange(idx.size), e] > tol[idx]
        if not go.any():
            break
        if not go.all():
            idx, e, Pb, Ji, fi = idx[go], e[go], Pb[go], Ji[go], fi[go]
        lam, mu = _bary2(Pb, q[idx], Ji[np.arange(idx.size), e])
        pos = mu > 1e-12
        ratio = np.where(pos, lam / np.where(pos, mu, 1.0), np.inf)
        leave = np.argmin(ratio, axis=1)
        basis[idx, leave] = e
    bounded = (basis < K).all(axis=1)
    return t, d, basis, bounded
