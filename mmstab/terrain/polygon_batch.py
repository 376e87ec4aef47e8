"""Many support hulls seen along one direction at once (the along-samples path).

:func:`hulls_along_batch` gives, for N point sets, the polygon
:func:`mmstab.terrain.polygon.hull_along` gives for each, up to where its vertex list
starts: all sets are wrapped at once (gift wrapping from the lowest-left point, the
smallest left turn, the farthest of equal turns), then each ring is checked. The
force-angle μ on a polygon is the minimum over its edges of a per-edge angle, so it does
not depend on the vertex the list starts at, as long as
:func:`mmstab.terrain.polygon.merge_close` drops nothing (which vertex of a close pair it
keeps does depend on the start). A set is flagged not ``ok``, for its caller to run
:func:`hull_along` on it, unless:

- it has 3 points or more whose 2-D spread is not nearly a line (the ratio of the
  covariance's eigenvalues, in closed form, above 1e-12; ``hull_along`` raises below
  1e-18, its SVD's 1e-9 squared);
- every other point is strictly left of every ring edge (by 1e-9 of the set's size
  squared) or on the edge's line (within 1e-13, rounding) strictly between its ends: the
  ring is Qhull's hull but for points on an edge's line, which Qhull may keep as vertices
  and which change no axis beyond rounding;
- no two consecutive ring vertices are closer than ``tol`` in 3-D (the merge would act).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.terrain.polygon import MIN_EDGE, plane_axes

FloatArray = NDArray[np.float64]

#: Largest chunk of N * K^2 edge-point tests held at once.
_CHUNK = 4_000_000


class BatchHulls(NamedTuple):
    """N hulls, padded.

    Attributes:
        vertices: (N, H, 3) [m] the hull vertices, CCW about -direction, the first
            ``n_vertices[i]`` rows of row i valid (the rest NaN).
        n_vertices: (N,) vertices per hull.
        ok: (N,) the hull is the per-set one up to its start vertex; False: run
            :func:`mmstab.terrain.polygon.hull_along` on that set.
    """

    vertices: FloatArray
    n_vertices: NDArray[np.intp]
    ok: NDArray[np.bool_]


def hulls_along_batch(
    points: ArrayLike, mask: ArrayLike, direction: ArrayLike, tol: float = MIN_EDGE
) -> BatchHulls:
    """Hulls of N point sets seen along one ``direction`` (3,).

    Args:
        points: (N, K, 3) [m] the candidate points of each set.
        mask: (N, K) which candidates belong to each set.
        direction: the direction the sets are seen along (3,) (the net force) [any unit].
        tol: the merge distance of :func:`mmstab.terrain.polygon.merge_close` [m].
    """
    pts = np.asarray(points, dtype=float)
    keep = np.asarray(mask, dtype=bool)
    n_sets = keep.shape[0]
    m = keep.sum(axis=1)
    k = int(m.max()) if n_sets else 0
    out = np.full((n_sets, max(k, 1), 3), np.nan)
    count = np.zeros(n_sets, dtype=np.intp)
    ok = np.zeros(n_sets, dtype=bool)
    if k < 3:
        return BatchHulls(out, count, ok)
    order = np.argsort(~keep, axis=1, kind="stable")[:, :k]
    P = np.take_along_axis(pts, order[..., None], axis=1)  # (N, k, 3), the set first
    valid = np.arange(k)[None, :] < m[:, None]
    u, v = plane_axes(direction)
    step = max(1, _CHUNK // (k * k))
    for lo in range(0, n_sets, step):
        sl = slice(lo, min(n_sets, lo + step))
        _chunk(P[sl], valid[sl], u, v, tol, out[sl], count[sl], ok[sl])
    return BatchHulls(out, count, ok)


def _chunk(
    P: FloatArray,
    valid: NDArray[np.bool_],
    u: FloatArray,
    v: FloatArray,
    tol: float,
    out: FloatArray,
    count: NDArray[np.intp],
    ok: NDArray[np.bool_],
) -> None:
    n, k = valid.shape
    m = valid.sum(axis=1)
    Pz = np.where(valid[..., None], P, 0.0)
    centre = Pz.sum(axis=1) / np.maximum(m, 1)[:, None]
    rel = np.where(valid[..., None], P - centre[:, None, :], 0.0)
    x, y = rel @ u, rel @ v  # (n, k)
    size2 = np.maximum(np.max(x * x + y * y, axis=1), 1e-300)  # (n,)
    # the 2-D spread's principal axes (closed form of the 2x2 covariance's eigenvalues)
    w = np.maximum(m, 1)
    a, b, c = (x * x).sum(1) / w, (x * y).sum(1) / w, (y * y).sum(1) / w
    big = 0.5 * (a + c) + np.sqrt(0.25 * (a - c) ** 2 + b * b)
    small = (a * c - b * b) / np.where(big > 0, big, 1.0)
    good = (m >= 3) & (big > 0) & (small > 1e-12 * big)
    rows = np.arange(n)
    # gift wrapping from the lowest-left point: the smallest left turn, the farthest of ties
    xs = np.where(valid, x, np.inf)
    ys = np.where(valid, y, np.inf)
    start = np.lexsort((ys, xs), axis=1)[:, 0]
    idx = np.zeros((n, k + 1), dtype=np.intp)
    idx[:, 0] = start
    h = np.zeros(n, dtype=np.intp)
    cur = start.copy()
    ex, ey = np.zeros(n), -np.ones(n)
    for step in range(1, k + 1):
        wx, wy = x - x[rows, cur][:, None], y - y[rows, cur][:, None]
        r2 = wx * wx + wy * wy
        ang = np.arctan2(ex[:, None] * wy - ey[:, None] * wx, ex[:, None] * wx + ey[:, None] * wy)
        ang = np.where(ang < 0, ang + 2 * np.pi, ang)
        ang = np.where(valid & (r2 > 0), ang, np.inf)
        tie = ang <= ang.min(axis=1, keepdims=True) + 1e-10
        nxt = np.argmax(np.where(tie, r2, -1.0), axis=1)
        open_ = h == 0
        idx[:, step] = np.where(open_, nxt, idx[:, step])
        h = np.where(open_ & (nxt == start), step, h)
        ex, ey = x[rows, nxt] - x[rows, cur], y[rows, nxt] - y[rows, cur]
        cur = nxt
        if not open_.any():
            break
    good &= h >= 3
    hh = np.maximum(h, 1)
    H = int(hh.max())  # the edges: at most the longest ring's
    ring = np.arange(H)[None, :] < hh[:, None]
    a_i = idx[:, :H]
    b_i = np.take_along_axis(idx, np.where(ring, np.arange(1, H + 1)[None, :], 0), axis=1)
    # every point strictly left of every edge, or on its line strictly between its ends
    ax, ay = np.take_along_axis(x, a_i, 1), np.take_along_axis(y, a_i, 1)  # (n, H)
    dx, dy = np.take_along_axis(x, b_i, 1) - ax, np.take_along_axis(y, b_i, 1) - ay
    px, py = x[:, None, :] - ax[..., None], y[:, None, :] - ay[..., None]  # [n, edge, o]
    cross = dx[..., None] * py - dy[..., None] * px
    t = (dx[..., None] * px + dy[..., None] * py) / np.maximum(dx * dx + dy * dy, 1e-300)[..., None]
    s2 = size2[:, None, None]
    end = (np.arange(k)[None, None, :] == a_i[..., None]) | (
        np.arange(k)[None, None, :] == b_i[..., None]
    )
    on = (np.abs(cross) <= 1e-13 * s2) & (t > 1e-9) & (t < 1 - 1e-9)
    clean = (cross > 1e-9 * s2) | on | end | ~valid[:, None, :]
    good &= (clean | ~ring[..., None]).all(axis=(1, 2))
    verts = np.take_along_axis(P, a_i[..., None], axis=1)  # (n, H, 3)
    nxt3 = np.take_along_axis(P, b_i[..., None], axis=1)
    short = ring & (np.linalg.norm(nxt3 - verts, axis=2) < tol)
    good &= ~short.any(axis=1)
    out[:, :H] = np.where((ring & good[:, None])[..., None], verts, np.nan)
    count[:] = np.where(good, h, 0)
    ok[:] = good
