"""Convex hulls and their half-spaces, built block by block so Ctrl-C reaches them."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import ConvexHull, QhullError
from scipy.spatial.distance import cdist

from mmstab.core.files import MmstabError
from mmstab.model.robot import FloatArray

#: Half-space slack of the membership tests [m].
HULL_TOL = 1e-9
#: Points per block when a cloud is reduced to its hull's candidates (``hull_candidates``).
HULL_BLOCK = 65536
#: A cloud whose smallest principal spread is below this share of the largest is flat.
FLAT_TOL = 1e-9


class HalfSpaces(NamedTuple):
    """A convex polytope ``{p : A p <= b}``.

    Attributes:
        A: outward facet normals (F, 3).
        b: offsets (F,) [m].
    """

    A: FloatArray
    b: FloatArray


def hull_candidates(points: FloatArray, block: int = HULL_BLOCK) -> FloatArray:
    """The points of a cloud that may be vertices of its convex hull (M, 3) [m].

    Each block's own hull vertices: a vertex of the whole hull is a vertex of the hull of
    any block holding it, so ``hull(candidates) = hull(points)`` (on the default grid the
    half-spaces come out identical). Qhull cannot be interrupted; one block takes tens of
    milliseconds, so a Ctrl-C is handled between blocks instead of after one long call on
    millions of points. A block without a hull (flat, too small) is kept whole.
    """
    if len(points) <= block:
        return points
    keep = []
    for s in range(0, len(points), block):
        b = points[s : s + block]
        try:
            keep.append(b[ConvexHull(b).vertices])
        except QhullError:
            keep.append(b)
    return np.vstack(keep)


def convex_hull(
    points: ArrayLike, what: str, advice: str = "refine the workspace grid"
) -> ConvexHull:
    """Convex hull of a 3-D cloud, or a clear error when the cloud is degenerate.

    Args:
        points: the cloud (N, 3) [m].
        what: what the cloud is, for the error message.
        advice: what to do about a flat cloud, for the error message.

    Raises:
        MmstabError: fewer than 4 points, or all on a plane or line.
    """
    pts = np.asarray(points, dtype=float)
    n = len(pts)
    if n < 4:
        raise MmstabError(
            f"{what}: {n} points cannot span a 3-D convex hull (need 4 not on a "
            "plane); refine the workspace grid"
        )
    pts = hull_candidates(pts)
    spread = np.linalg.svd(pts - pts.mean(axis=0), compute_uv=False)
    if spread[-1] <= FLAT_TOL * spread[0]:
        raise MmstabError(
            f"{what}: the {n} points lie on a plane or a line, so their convex hull "
            f"has no volume; {advice}"
        )
    try:
        return ConvexHull(pts)
    except QhullError as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else "Qhull failed"
        raise MmstabError(f"{what}: convex hull failed ({first})") from None


def halfspaces(hull: ConvexHull) -> HalfSpaces:
    """Half-space form of a hull; coplanar triangles' duplicate facets are merged."""
    eq = np.unique(np.round(hull.equations, 10), axis=0)
    return HalfSpaces(A=eq[:, :3], b=-eq[:, 3])


def hull_diameter(points: FloatArray, block: int = 2048) -> float:
    """Largest distance between two points of a cloud (N, 3) [m]."""
    best = 0.0
    for s in range(0, len(points), block):
        best = max(best, float(cdist(points[s : s + block], points).max()))
    return best


def _inside(points: FloatArray, hs: HalfSpaces, slack: float) -> NDArray[np.bool_]:
    """``all(A p <= b + slack)`` per point, in cache-sized blocks (no N x F temporary)."""
    block = min(max(2**17 // max(len(hs.b), 1), 16), 4096)
    if len(points) <= block:  # small batches (the planner's populations): one product
        return (points @ hs.A.T - hs.b).max(axis=1, initial=-np.inf) <= slack
    out = np.empty(len(points), dtype=bool)
    AT = np.ascontiguousarray(hs.A.T)
    buf = np.empty((block, len(hs.b)))
    for s in range(0, len(points), block):
        p = points[s : s + block]
        excess = buf[: len(p)]
        np.matmul(p, AT, out=excess)
        excess -= hs.b
        out[s : s + block] = excess.max(axis=1, initial=-np.inf) <= slack
    return out
