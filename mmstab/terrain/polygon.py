"""Ordering 3-D contact points into a support polygon, seen along a direction.

The polygon of contacts that need not be coplanar is their convex hull seen along the net
force (gravity): the contacts on the hull of their projection onto the plane normal to it,
kept at their 3-D positions, counter-clockwise about the opposite ("up") direction.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import ConvexHull, QhullError

FloatArray = NDArray[np.float64]


def _cross(a: ArrayLike, b: ArrayLike) -> FloatArray:
    """``np.cross`` of two 3-vectors: the same floats in a sixth of its time (no axis moves)."""
    a0, a1, a2 = (float(x) for x in np.asarray(a, dtype=float))
    b0, b1, b2 = (float(x) for x in np.asarray(b, dtype=float))
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def plane_axes(direction: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Unit axes (u, v) normal to ``direction`` (3,): (u, v, -direction) right-handed."""
    d = np.asarray(direction, dtype=float)
    up = -d / np.linalg.norm(d)
    u = _cross(up, (1.0, 0.0, 0.0) if abs(up[0]) < 0.9 else (0.0, 1.0, 0.0))
    u /= np.linalg.norm(u)
    v = _cross(up, u)  # (u, v, up) right-handed: CCW in (u, v) is CCW about up
    return u, v


def hull_along(points: ArrayLike, direction: ArrayLike) -> FloatArray:
    """Hull vertices of ``points`` (n, 3) seen along ``direction`` (3,), CCW about -direction.

    Raises:
        ValueError: fewer than 3 points, or all on one line seen along ``direction``.
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3 or pts.shape[0] < 3:
        raise ValueError(f"support points must be (n>=3, 3), got {pts.shape}")
    u, v = plane_axes(direction)
    rel = pts - pts.mean(axis=0)
    flat = np.stack([rel @ u, rel @ v], axis=1)
    _, sing, _ = np.linalg.svd(flat - flat.mean(axis=0))
    if sing[1] < 1e-9 * max(sing[0], 1e-300):
        raise ValueError("support points are collinear seen along the force: no polygon")
    try:
        hull = ConvexHull(flat)
    except QhullError as exc:
        raise ValueError(f"degenerate support polygon: {exc}") from None
    kept = merge_close(pts[hull.vertices])
    if len(kept) < 3:
        raise ValueError("support points are collinear seen along the force: no polygon")
    return kept


#: Hull vertices closer than this [m] are one contact (:func:`merge_close`).
MIN_EDGE = 1e-3


def merge_close(vertices: FloatArray, tol: float = MIN_EDGE) -> FloatArray:
    """The ordered polygon ``vertices`` (n, 3) [m] without edges shorter than ``tol`` [m].

    Two contacts a fraction of a millimetre apart (a simulated wheel's contact and its
    nearest point, two of a heightfield's contacts under one wheel) make a hull edge whose
    direction is their rounding noise: its tip-over axis, and so the force angle about it,
    means nothing (0.64 rad on a 0.07 mm edge where its 52 cm neighbour gives 0.91). Of two
    vertices within ``tol`` the first is kept.
    """
    out = [vertices[0]]
    for p in vertices[1:]:
        if np.linalg.norm(p - out[-1]) >= tol:
            out.append(p)
    while len(out) > 1 and np.linalg.norm(out[-1] - out[0]) < tol:
        out.pop()
    return np.asarray(out)


def extreme_pair(points: ArrayLike) -> FloatArray:
    """The two contacts farthest apart along their main horizontal direction (2 or 1, 3)."""
    pts = np.asarray(points, dtype=float)
    d = pts - pts.mean(axis=0)
    axis = np.linalg.svd(d[:, :2])[2][0] if len(d) > 1 else np.array([1.0, 0.0])
    s = d[:, :2] @ axis
    pair = pts[[int(np.argmin(s)), int(np.argmax(s))]]
    return pair[:1] if np.linalg.norm(pair[1] - pair[0]) < 1e-9 else pair


def support_vertices(points: ArrayLike, direction: ArrayLike) -> tuple[FloatArray, bool]:
    """``(vertices, is_line)``: the hull seen along ``direction``, or the extreme pair."""
    pts = np.asarray(points, dtype=float)
    if len(pts) == 0:
        return np.zeros((0, 3)), True
    try:
        return hull_along(pts, direction), False
    except ValueError:
        return extreme_pair(pts), True
