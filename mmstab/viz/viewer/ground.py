"""The ground as the viewer sees it: the terrain interface, and the terrain as a mesh.

The viewer talks to the ground only through :class:`mmstab.terrain.Terrain`:
``G_T_M()``, ``G_T_B(poses)``, ``gravity_body(poses)``, ``support(robot, pose)`` and
``surface_G(x, y)`` (the terrain draws itself); an object with only ``G_T_M`` and a
``height(x, y)`` [m] in M is meshed through its height.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.model.robot import FloatArray
from mmstab.terrain import Terrain

#: Default size of a terrain mesh cell [m] (a heightmap's bumps need them small).
MESH_CELL = 0.1
#: Route and grid lines are drawn this far above the ground, to stay visible [m].
LINE_LIFT = 4e-3


#: What the viewer draws on: any :class:`mmstab.terrain.Terrain`.
Ground = Terrain


def problem_ground(problem: Any) -> Ground:
    """The ground of a problem (its terrain)."""
    return problem.terrain


def resting_poses(ground: Ground, poses: ArrayLike) -> FloatArray:
    """Body poses in G for base poses, always (N, 4, 4) (one pose gives N = 1)."""
    P = np.asarray(poses, dtype=float).reshape(-1, 3)
    return np.asarray(ground.G_T_B(P), dtype=float).reshape(-1, 4, 4)


def transform(T: ArrayLike, points: ArrayLike) -> FloatArray:
    """Apply a 4x4 transform to points (..., 3) [m]."""
    M = np.asarray(T, dtype=float)
    return np.asarray(points, dtype=float) @ M[:3, :3].T + M[:3, 3]


class Extent(NamedTuple):
    """A rectangle of the map frame M [m]."""

    x_min: float
    x_max: float
    y_min: float
    y_max: float


def extent_around(
    points_M: ArrayLike,
    margin: float,
    bounds: tuple[float, float, float, float] | None = None,
) -> Extent:
    """The rectangle of M holding ``points_M`` (n, >= 2) [m], grown by ``margin`` [m].

    ``bounds`` ``(x_min, x_max, y_min, y_max)`` [m] (a map's, ``Terrain.bounds``) cut it:
    the ground has no height off its map, so the mesh stays on it.
    """
    p = np.asarray(points_M, dtype=float)
    p = p.reshape(p.shape[0], -1)[:, :2]
    lo, hi = p.min(axis=0) - margin, p.max(axis=0) + margin
    if bounds is not None:
        lo = np.maximum(lo, [bounds[0], bounds[2]])
        hi = np.minimum(hi, [bounds[1], bounds[3]])
    return Extent(float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]))


def surface_points(ground: Ground, x: ArrayLike, y: ArrayLike, lift: float = 0.0) -> FloatArray:
    """Points of the ground surface over map coordinates ``x``, ``y`` (same shape) in G [m].

    ``ground.surface_G(x, y)`` if the ground has it; else the height is
    ``ground.height(x, y)`` [m] in M if it has that, else 0 (a plane).

    Args:
        ground: the terrain.
        x: map x coordinates [m].
        y: map y coordinates [m], same shape.
        lift: offset along M's z [m] (to draw lines just above the surface).

    Returns:
        (..., 3) points in G [m].
    """
    xa, ya = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
    surface = getattr(ground, "surface_G", None)
    if surface is not None:  # the terrain draws itself (mmstab.terrain.Terrain.surface_G)
        return np.asarray(surface(xa, ya), dtype=float) + lift * ground.G_T_M()[:3, 2]
    height = getattr(ground, "height", None)
    z = np.zeros_like(xa) if height is None else np.asarray(height(xa, ya), dtype=float)
    return transform(ground.G_T_M(), np.stack([xa, ya, z + lift], axis=-1))


class TerrainMesh(NamedTuple):
    """A triangle mesh of the ground in G.

    Attributes:
        vertices: (V, 3) [m].
        faces: (F, 3) vertex indices, counter-clockwise seen from above (normals up in M).
        colors: per-vertex RGB (V, 3) uint8, by height along G's z.
    """

    vertices: FloatArray
    faces: np.ndarray
    colors: np.ndarray


def terrain_mesh(ground: Ground, extent: Extent, cells: int | None = None) -> TerrainMesh:
    """Mesh the ground over a rectangle of M with ``cells`` x ``cells`` squares.

    Args:
        ground: the terrain.
        extent: the rectangle in M [m].
        cells: grid cells per side (>= 1); default about :data:`MESH_CELL` [m] each,
            10 to 200 per side.
    """
    if cells is None:
        span = max(extent.x_max - extent.x_min, extent.y_max - extent.y_min)
        cells = int(np.clip(np.ceil(span / MESH_CELL), 10, 200))
    xs = np.linspace(extent.x_min, extent.x_max, cells + 1)
    ys = np.linspace(extent.y_min, extent.y_max, cells + 1)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    vertices = surface_points(ground, X, Y).reshape(-1, 3)
    idx = np.arange((cells + 1) ** 2).reshape(cells + 1, cells + 1)
    a, b = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()  # (i, j), (i + 1, j)
    c, d = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()  # (i + 1, j + 1), (i, j + 1)
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return TerrainMesh(vertices, faces, height_colors(vertices[:, 2]))


def height_colors(z: ArrayLike) -> np.ndarray:
    """Earth tones from low (dark) to high (light) for heights ``z`` (n,) [m] -> (n, 3) uint8."""
    za = np.asarray(z, dtype=float)
    span = float(za.max() - za.min()) if za.size else 0.0
    s = (za - za.min()) / span if span > 1e-9 else np.full_like(za, 0.5)
    low, high = np.array([112.0, 132.0, 92.0]), np.array([232.0, 222.0, 190.0])
    return np.round(low + s[:, None] * (high - low)).astype(np.uint8)


def grid_lines(
    ground: Ground, extent: Extent, spacing: float = 0.5, samples: int = 40
) -> FloatArray:
    """Lines of constant map x and y every ``spacing`` [m], on the surface, as segments.

    Args:
        ground: the terrain.
        extent: the rectangle in M [m].
        spacing: grid spacing [m].
        samples: segments per line (they follow a curved surface).

    Returns:
        (S, 2, 3) segment end points in G [m], lifted by :data:`LINE_LIFT`.
    """
    xs = np.arange(np.ceil(extent.x_min / spacing), np.floor(extent.x_max / spacing) + 1) * spacing
    ys = np.arange(np.ceil(extent.y_min / spacing), np.floor(extent.y_max / spacing) + 1) * spacing
    u = np.linspace(0.0, 1.0, samples + 1)
    lines = []
    for x in xs:
        yy = extent.y_min + u * (extent.y_max - extent.y_min)
        lines.append(surface_points(ground, np.full_like(yy, x), yy, LINE_LIFT))
    for y in ys:
        xx = extent.x_min + u * (extent.x_max - extent.x_min)
        lines.append(surface_points(ground, xx, np.full_like(xx, y), LINE_LIFT))
    return polyline_segments(*lines)


def polyline_segments(*polylines: ArrayLike) -> FloatArray:
    """Segments (S, 2, 3) joining consecutive points of each polyline (n_i, 3)."""
    segs = [np.stack([p[:-1], p[1:]], axis=1) for p in map(np.asarray, polylines) if len(p) > 1]
    return np.concatenate(segs) if segs else np.zeros((0, 2, 3))
