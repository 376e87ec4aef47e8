"""The ground in 3-D drawings: its patch and grid, paths on it, depth layers, axis limits.

mplot3d paints collections by their projected depth; the ground and the paths on it are
drawn at fixed depth ranks instead (:class:`LayerPolys`, :class:`LayerLines`) so the robot
standing on them stays in front. The ground is sampled only on its map
(:func:`clip_to_ground`).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection
from numpy.typing import ArrayLike

from mmstab.terrain import Terrain
from mmstab.viz.meshes import SUPPORT_LIFT, transform_points

#: Depth ranks for mplot3d's painter's sort (larger = drawn earlier): ground, then path, ...
GROUND_RANK, PATH_RANK, OVERLAY_RANK = np.inf, 1e12, -np.inf


class LayerPolys(Poly3DCollection):
    """A ``Poly3DCollection`` drawn at a fixed depth rank rather than by its projected depth.

    mplot3d orders collections by their nearest point, so a large ground patch would be
    painted over the robot standing on it. ``GROUND_RANK`` keeps it behind everything;
    ``OVERLAY_RANK`` paints on top (the support polygon, seen through the robot).
    """

    def __init__(self, verts: Any, rank: float, **kwargs: Any):
        super().__init__(verts, **kwargs)
        self.rank = rank

    def do_3d_projection(self) -> float:
        """Project as usual; report the fixed rank."""
        super().do_3d_projection()
        return self.rank


class LayerLines(Line3DCollection):
    """A ``Line3DCollection`` drawn at a fixed depth rank (see :class:`LayerPolys`)."""

    def __init__(self, segments: Any, rank: float, **kwargs: Any):
        super().__init__(segments, **kwargs)
        self.rank = rank

    def do_3d_projection(self) -> float:
        """Project as usual; report the fixed rank."""
        super().do_3d_projection()
        return self.rank


class Extent(NamedTuple):
    """A rectangle in the map frame M: x from ``x_min`` to ``x_max``, y likewise [m]."""

    x_min: float
    x_max: float
    y_min: float
    y_max: float


def clip_to_ground(terrain: Terrain, extent: Extent | ArrayLike) -> Extent | None:
    """A rectangle of M [m] cut to the ground's map (``terrain.bounds``).

    Drawings around the robot reach past its contacts (the arm, a margin); on a heightmap
    that can be off the map, where the ground has no height. Returns None when nothing of
    the rectangle is on the map.
    """
    e = Extent(*(float(v) for v in np.asarray(extent, dtype=float)))
    b = terrain.bounds
    if b is None:
        return e
    cut = Extent(max(e.x_min, b[0]), min(e.x_max, b[1]), max(e.y_min, b[2]), min(e.y_max, b[3]))
    return cut if cut.x_min < cut.x_max and cut.y_min < cut.y_max else None


def draw_ground(
    ax3d: Any,
    terrain: Terrain,
    extent: Extent | ArrayLike,
    color: Any = "0.85",
    alpha: float = 0.6,
    grid: float | None = 0.5,
) -> list[Any]:
    """Draw a rectangle of the ground (and a grid on it) in G.

    The rectangle is cut to the map (:func:`clip_to_ground`): the ground is never sampled
    off it.

    Args:
        ax3d: matplotlib 3-D axes.
        terrain: the ground (its ``surface_G`` and ``bounds``).
        extent: ``(x_min, x_max, y_min, y_max)`` in the map frame M [m].
        color: face colour of the plane.
        alpha: its opacity in [0, 1].
        grid: spacing of grid lines in S [m]; ``None`` for none.

    Returns:
        The artists: the plane patch (gid ``ground``), then the grid lines (gid
        ``ground_grid``); none when the rectangle is off the map.
    """
    e = clip_to_ground(terrain, extent)
    if e is None:
        return []
    corners_G = terrain.surface_G(
        [e.x_min, e.x_max, e.x_max, e.x_min], [e.y_min, e.y_min, e.y_max, e.y_max]
    )
    patch = LayerPolys([corners_G], GROUND_RANK, facecolors=color)
    patch.set_alpha(alpha)
    patch.set_edgecolor("0.5")
    patch.set_gid("ground")
    ax3d.add_collection3d(patch)
    artists: list[Any] = [patch]
    if grid:
        xs = np.arange(np.ceil(e.x_min / grid) * grid, e.x_max + 1e-9, grid)
        ys = np.arange(np.ceil(e.y_min / grid) * grid, e.y_max + 1e-9, grid)
        segments_M = [[[x, e.y_min], [x, e.y_max]] for x in xs]
        segments_M += [[[e.x_min, y], [e.x_max, y]] for y in ys]
        seg = np.array(segments_M).reshape(-1, 2, 2)
        segments_G = terrain.surface_G(seg[..., 0], seg[..., 1])
        lines = LayerLines(segments_G, GROUND_RANK, colors="0.7", linewidths=0.5)
        lines.set_gid("ground_grid")
        ax3d.add_collection3d(lines)
        artists.append(lines)
    return artists


def draw_path_on_ground(
    ax3d: Any, terrain: Terrain, points_S: ArrayLike, color: Any = "0.35", **kwargs: Any
) -> Line3DCollection:
    """Draw a polyline given in the map frame M, (n, 2) or (n, 3) [m], on the ground (gid ``path``).

    Args:
        ax3d: matplotlib 3-D axes.
        terrain: the ground.
        points_S: polyline vertices in M [m] (on the ground, lifted slightly, if only x, y
            are given).
        color: line colour.
        **kwargs: passed to ``Line3DCollection`` (``linestyles``, ``linewidths``, ...).
    """
    p = np.asarray(points_S, dtype=float)
    if p.shape[1] == 2:
        up_G = terrain.G_T_M()[:3, 2]
        p_G = terrain.surface_G(p[:, 0], p[:, 1]) + SUPPORT_LIFT * up_G
    else:
        p_G = transform_points(terrain.G_T_M(), p)
    kwargs = {"linestyles": "--", "linewidths": 1.0, **kwargs}
    lines = LayerLines([p_G], PATH_RANK, colors=color, **kwargs)
    lines.set_gid("path")
    ax3d.add_collection3d(lines)
    return lines


def set_equal_aspect(ax3d: Any, points: ArrayLike, margin: float = 0.05, zoom: float = 1.0) -> None:
    """Fit the 3-D axes' limits to ``points`` (n, 3) [m] with equal scale on x, y and z.

    Args:
        ax3d: matplotlib 3-D axes.
        points: points to hold (n, 3) [m].
        margin: padding, as a fraction of the largest extent.
        zoom: magnification of the 3-D box within the axes (``Axes3D.set_box_aspect``).
    """
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    lo, hi = p.min(axis=0), p.max(axis=0)
    pad = margin * float((hi - lo).max())
    lo, hi = lo - pad, hi + pad
    ax3d.set_xlim(lo[0], hi[0])
    ax3d.set_ylim(lo[1], hi[1])
    ax3d.set_zlim(lo[2], hi[2])
    ax3d.set_box_aspect(tuple(np.maximum(hi - lo, 1e-6)), zoom=zoom)
