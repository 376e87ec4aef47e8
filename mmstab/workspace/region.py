"""The workspace V as a region of arm CoMs: membership, distance, the clouds it keeps."""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from mmstab.core.files import MmstabError
from mmstab.core.pool import run_interruptibly
from mmstab.model.robot import FloatArray
from mmstab.workspace.hulls import (
    HULL_TOL,
    HalfSpaces,
    _inside,
    convex_hull,
    halfspaces,
    hull_diameter,
)


@dataclass(frozen=True, eq=False)
class Workspace:
    """The arm-CoM workspace V and the clouds it was built from (body frame B).

    Attributes:
        grid: samples per joint (one per arm joint).
        valid_q: collision-free postures (Nv, n) [rad].
        valid_com: their arm CoMs (Nv, 3) [m].
        invalid_q: colliding postures (Ni, n) [rad].
        invalid_com: their arm CoMs (Ni, 3) [m].
        A_all: facet normals of hull(all CoMs) (F, 3); ``A_all p <= b_all`` inside.
        b_all: offsets (F,) [m].
        A_bad: facet normals of hull(invalid CoMs) (G, 3); G = 0 when no posture collides.
        b_bad: offsets (G,) [m].
        diameter: d_workspace, the diameter of hull(all CoMs) (Eq. 6) [m].
        build_seconds: wall time of the build (0 if unknown) [s].
        samples: 0 when every grid posture was labelled; else the number drawn from the grid
            (a grid over the size bound, :func:`mmstab.core.sizes.workspace_postures`).
        seed: the draw's seed (0 for a whole grid).
    """

    grid: tuple[int, ...]
    valid_q: FloatArray
    valid_com: FloatArray
    invalid_q: FloatArray
    invalid_com: FloatArray
    A_all: FloatArray
    b_all: FloatArray
    A_bad: FloatArray
    b_bad: FloatArray
    diameter: float
    build_seconds: float = 0.0
    samples: int = 0
    seed: int = 0

    def contains(self, points: ArrayLike) -> NDArray[np.bool_]:
        """Whether body-frame points lie in V: in hull(all) and not in hull(invalid).

        Args:
            points: (N, 3) or (3,) arm-CoM positions in the body frame [m].

        Returns:
            (N,) bool ((1,) for a single point).
        """
        pts = np.atleast_2d(np.asarray(points, dtype=float))
        inside = _inside(pts, HalfSpaces(self.A_all, self.b_all), HULL_TOL)
        if len(self.b_bad) and inside.any():
            inside[inside] = ~_inside(pts[inside], HalfSpaces(self.A_bad, self.b_bad), HULL_TOL)
        return inside

    @functools.cached_property
    def valid_in_V(self) -> NDArray[np.bool_]:
        """Which valid CoMs (rows of ``valid_com``) V contains (N,).

        Computed once: it tests every sample against both hulls.
        """
        return self.contains(self.valid_com)

    @functools.cached_property
    def valid_com_in_V(self) -> FloatArray:
        """The valid CoMs that V contains (M, 3) [m] (V drops some: see ``recall``)."""
        return self.valid_com[self.valid_in_V]

    def violation(self, points: ArrayLike) -> FloatArray:
        """How far body-frame points (N, 3) lie outside V, 0 inside [m].

        Outside hull(all): the largest facet violation; inside hull(invalid): the depth
        to its nearest facet. Facet normals are unit (Qhull), so both are distances to a
        facet plane (a lower bound on the distance to V). Ranks infeasible CMA samples.
        Zero exactly where :meth:`contains` is true (same products, same ``HULL_TOL``).
        """
        pts = np.atleast_2d(np.asarray(points, dtype=float))
        excess = (pts @ self.A_all.T - self.b_all).max(axis=1, initial=-np.inf)
        out = np.maximum(excess, 0.0)
        inside = excess <= HULL_TOL
        if len(self.b_bad):
            depth = (self.b_bad - pts @ self.A_bad.T).min(axis=1)
            in_bad = depth >= -HULL_TOL
            inside &= ~in_bad
            out = np.where(excess > HULL_TOL, out, np.maximum(depth, 0.0))
        return np.where(inside, 0.0, np.maximum(out, HULL_TOL))

    @functools.cached_property
    def _valid_tree(self) -> cKDTree:
        return run_interruptibly(cKDTree, self.valid_com)  # seconds for millions: Ctrl-C

    def nearest_valid_posture(self, point: ArrayLike) -> FloatArray:
        """The collision-free grid posture whose arm CoM is nearest to a point.

        Args:
            point: arm-CoM target (3,) or (N, 3) in the body frame [m].

        Returns:
            posture (4,) or (N, 4) [rad].
        """
        _, idx = self._valid_tree.query(np.asarray(point, dtype=float))
        return self.valid_q[idx].copy()

    @property
    def postures(self) -> int:
        """Number of grid postures."""
        return len(self.valid_q) + len(self.invalid_q)

    @property
    def how_sampled(self) -> str:
        """`` sampled of the AxBx... grid`` when drawn from a grid over the bound, else ``""``."""
        return f" sampled of the {'x'.join(map(str, self.grid))} grid" if self.samples else ""

    @functools.cached_property
    def volume_all(self) -> float:
        """Volume of hull(all CoMs) [m^3]."""
        return float(convex_hull(np.vstack([self.valid_com, self.invalid_com]), "all CoMs").volume)

    @functools.cached_property
    def volume_invalid(self) -> float:
        """Volume of hull(invalid CoMs) [m^3]; 0 when no posture collides."""
        if not len(self.b_bad):
            return 0.0
        return float(convex_hull(self.invalid_com, "invalid CoMs").volume)

    @property
    def volume_V(self) -> float:
        """Volume of V [m^3]: exact, since hull(invalid) lies inside hull(all)."""
        return self.volume_all - self.volume_invalid


def workspace_from_clouds(
    grid: Sequence[int],
    valid_q: ArrayLike,
    valid_com: ArrayLike,
    invalid_q: ArrayLike,
    invalid_com: ArrayLike,
    build_seconds: float = 0.0,
) -> Workspace:
    """Hulls, half-spaces and diameter of labelled CoM clouds.

    Args:
        grid: samples per joint.
        valid_q: collision-free postures (Nv, n) [rad], n = ``len(grid)``.
        valid_com: their arm CoMs (Nv, 3), body frame [m].
        invalid_q: colliding postures (Ni, n) [rad]; may be empty (then V = hull(all)).
        invalid_com: their arm CoMs (Ni, 3) [m].
        build_seconds: wall time of the labelling, recorded in the result [s].

    Raises:
        MmstabError: no valid posture, or a degenerate (flat, too small) cloud.
    """
    n = len(grid)
    vq, vc = np.asarray(valid_q, float).reshape(-1, n), np.asarray(valid_com, float).reshape(-1, 3)
    iq, ic = (
        np.asarray(invalid_q, float).reshape(-1, n),
        np.asarray(invalid_com, float).reshape(-1, 3),
    )
    if len(vc) == 0:
        raise MmstabError("no collision-free posture on the workspace grid: check the geometry")
    # on a grid of 3 or more angles a joint, a flat cloud is the arm's, not the grid's
    advice = (
        "refine the workspace grid"
        if min(grid) < 3
        else "the arm's joints move its CoM in a plane (one joint: on a circle), and the "
        "planner keeps the arm CoM within a volume: an arm of two joints or more about axes "
        "that are not all parallel"
    )
    hull_all = convex_hull(np.vstack([vc, ic]), "all arm CoMs", advice)
    hs_all = halfspaces(hull_all)
    if len(ic):
        hs_bad = halfspaces(convex_hull(ic, "invalid (colliding) arm CoMs"))
    else:
        hs_bad = HalfSpaces(np.zeros((0, 3)), np.zeros(0))
    return Workspace(
        grid=tuple(int(k) for k in grid),
        valid_q=vq,
        valid_com=vc,
        invalid_q=iq,
        invalid_com=ic,
        A_all=hs_all.A,
        b_all=hs_all.b,
        A_bad=hs_bad.A,
        b_bad=hs_bad.b,
        diameter=hull_diameter(hull_all.points[hull_all.vertices]),
        build_seconds=float(build_seconds),
    )
