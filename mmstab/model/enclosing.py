"""The least capsule that holds a set of points (an arm link's shapes, ``urdf_arm``).

Along one axis direction the capsule is exact: its radius is the smallest circle holding the
points projected across the axis (Welzl's algorithm on a support set grown by the farthest
point outside), its segment the shortest that keeps every point within the radius. The
direction is searched from the points' principal axes (Nelder-Mead on two angles) for the
least volume. trimesh's ``minimum_cylinder`` is not used: for a 0.49 m capsule of radius
0.04 m it returned a flat disc of radius 0.285 m.
"""

from __future__ import annotations

import math

import numpy as np

from mmstab.model.robot import Capsule, FloatArray
from mmstab.model.urdf import axis_to_z_rotation

Point = tuple[float, float]


def _welzl(points: FloatArray) -> tuple[FloatArray, float]:
    """The smallest circle holding a few 2-D points (n, 2): centre, radius (Welzl, in order)."""
    pts = [(float(x), float(y)) for x, y in points]

    def two(a: Point, b: Point) -> tuple[float, float, float]:
        cx, cy = (a[0] + b[0]) / 2, (a[1] + b[1]) / 2
        return cx, cy, math.hypot(a[0] - cx, a[1] - cy)

    def three(a: Point, b: Point, c: Point) -> tuple[float, float, float]:
        (ax, ay), (bx, by), (cx, cy) = a, b, c
        d = 2 * (ax * (by - cy) + bx * (cy - ay) + cx * (ay - by))
        if abs(d) < 1e-18:  # collinear: the farthest pair's circle
            return max((two(a, b), two(a, c), two(b, c)), key=lambda t: t[2])
        a2, b2, c2 = ax * ax + ay * ay, bx * bx + by * by, cx * cx + cy * cy
        ux = (a2 * (by - cy) + b2 * (cy - ay) + c2 * (ay - by)) / d
        uy = (a2 * (cx - bx) + b2 * (ax - cx) + c2 * (bx - ax)) / d
        return ux, uy, math.hypot(ax - ux, ay - uy)

    def out(p: Point, c: tuple[float, float, float]) -> bool:
        return math.hypot(p[0] - c[0], p[1] - c[1]) > c[2] * (1 + 1e-12) + 1e-15

    c = (pts[0][0], pts[0][1], 0.0)
    for i in range(1, len(pts)):
        if out(pts[i], c):
            c = (pts[i][0], pts[i][1], 0.0)
            for j in range(i):
                if out(pts[j], c):
                    c = two(pts[i], pts[j])
                    for k in range(j):
                        if out(pts[k], c):
                            c = three(pts[i], pts[j], pts[k])
    return np.array(c[:2]), c[2]


def _circle(points: FloatArray) -> tuple[FloatArray, float]:
    """The smallest circle holding 2-D points (n, 2): centre, radius.

    Welzl's circle of a support set, grown by the farthest point outside it until none is:
    the circle then holds all points and is the least for a subset, so for all.
    """
    far = int(np.argmax(np.linalg.norm(points - points[0], axis=1)))
    support = [points[0], points[far]]
    while True:
        centre, radius = _welzl(np.array(support))
        gap = np.linalg.norm(points - centre, axis=1)
        k = int(np.argmax(gap))
        if gap[k] <= radius * (1 + 1e-12) + 1e-15:
            return centre, radius
        support.append(points[k])


def _capsule_along(pts: FloatArray, u: FloatArray) -> tuple[float, Capsule]:
    """The smallest capsule along direction u holding the points, and its volume [m^3]."""
    R = axis_to_z_rotation(u)
    e1, e2, u = R[:, 0], R[:, 1], R[:, 2]
    flat = np.c_[pts @ e1, pts @ e2]
    centre2, radius = _circle(flat)
    t = pts @ u
    rho = np.linalg.norm(flat - centre2, axis=1)
    h = np.sqrt(np.maximum(radius**2 - rho**2, 0.0))
    t0, t1 = float(np.min(t + h)), float(np.max(t - h))
    if t0 > t1:
        t0 = t1 = (t0 + t1) / 2
    foot = centre2[0] * e1 + centre2[1] * e2
    volume = np.pi * radius**2 * (t1 - t0) + 4 / 3 * np.pi * radius**3
    return float(volume), Capsule(float(radius), foot + t0 * u, foot + t1 * u)


def enclosing_capsule(points: FloatArray, reach: float = 0.0) -> Capsule:
    """A capsule that holds all the points: the least volume over axis directions.

    Along a direction the capsule is exact (the smallest circle of the projected points,
    the shortest segment); the direction is searched from the points' principal axes
    (Nelder-Mead on two angles).

    Args:
        points: (n, 3) [m].
        reach: how far the shapes reach past their points [m] (added to the radius).
    """
    import trimesh
    from scipy.optimize import minimize

    pts = np.asarray(points, dtype=float)
    if np.ptp(pts, axis=0).max() < 1e-9:
        return Capsule(reach + 1e-9, pts[0].copy(), pts[0].copy())
    try:
        pts = np.asarray(trimesh.convex.convex_hull(pts).vertices, dtype=float)
    except Exception:  # flat points: all of them
        pass

    def direction(angles: FloatArray) -> FloatArray:
        th, ph = angles
        return np.array([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])

    best = None
    for axis in np.linalg.svd(pts - pts.mean(axis=0))[2]:
        start = np.array([np.arccos(np.clip(axis[2], -1, 1)), np.arctan2(axis[1], axis[0])])
        res = minimize(lambda a: _capsule_along(pts, direction(a))[0], start,
                       method="Nelder-Mead", options={"xatol": 1e-6, "fatol": 1e-12})  # fmt: skip
        found = _capsule_along(pts, direction(res.x))
        if best is None or found[0] < best[0]:
            best = found
    assert best is not None
    capsule = best[1]
    return Capsule(capsule.radius + reach + 1e-9, capsule.p0, capsule.p1)
