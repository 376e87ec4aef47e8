"""3-D drawing of the robot on the ground (matplotlib ``mplot3d``), from the collision geometry.

Every body the collision checker knows is drawn from the same shapes: the five base boxes
(``Base.collision_boxes()``) and the four arm links (box or capsule in their DH frame R_i,
placed by ``ArmKinematics.link_frames``). Capsules are drawn as low-poly cylinders with
low-poly hemispherical caps. Points are mapped to the drawing frame by ``G_T_B`` (the
body frame's pose in G, e.g. ``Terrain.G_T_B(pose)``); without it the drawing is in B.

Each body is one ``Poly3DCollection`` whose ``gid`` is its name (``body``, ``track_left``,
..., ``arm_link_0`` ... ``arm_link_3``), so figures and tests can find them.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection
from numpy.typing import ArrayLike

from mmstab.model.robot import Box, Capsule, FloatArray, Geometry, Robot
from mmstab.model.urdf import axis_to_z_rotation
from mmstab.stability.static import base_polygon
from mmstab.terrain import Terrain

#: Default face colours (matplotlib colour specs) of the base, tracks/flippers and arm.
BASE_COLOR = "#8c9479"
TRACK_COLOR = "#3a3a3a"
ARM_COLOR = "#e08a1e"

#: Sides of the low-poly cylinders that stand for capsules.
CAPSULE_SIDES = 10

#: The support polygon is drawn this far above the ground, to stay visible [m].
SUPPORT_LIFT = 2e-3


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


def transform_points(T: ArrayLike, points: ArrayLike) -> FloatArray:
    """Apply a 4x4 transform to points (..., 3) [m]."""
    M = np.asarray(T, dtype=float)
    p = np.asarray(points, dtype=float)
    return p @ M[:3, :3].T + M[:3, 3]


def box_faces(box: Box) -> list[FloatArray]:
    """The six quads (4, 3) of a box, in its owning frame [m]."""
    c = box.corners()  # index = 4 * (sx > 0) + 2 * (sy > 0) + (sz > 0)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return [c[list(q)] for q in quads]


def capsule_faces(capsule: Capsule, sides: int = CAPSULE_SIDES) -> list[FloatArray]:
    """Low-poly capsule: a ``sides``-gon cylinder and two caps of one ring each [m].

    Args:
        capsule: the capsule, in its owning frame.
        sides: number of sides of the cylinder (>= 3).

    Returns:
        Quads (4, 3) in the owning frame: ``sides`` on the cylinder, then per cap ``sides``
        to a ring at 45 deg and ``sides`` triangles to the pole (the pole given twice, so
        that every polygon has four vertices: matplotlib's autoscaling reads the padding
        of ragged polygon lists as data).
    """
    axis = capsule.p1 - capsule.p0
    R = axis_to_z_rotation(axis) if capsule.length > 0 else np.eye(3)
    z = R[:, 2]
    phi = np.arange(sides) * 2 * np.pi / sides
    ring = capsule.radius * (np.outer(np.cos(phi), R[:, 0]) + np.outer(np.sin(phi), R[:, 1]))
    nxt = np.roll(np.arange(sides), -1)
    faces: list[FloatArray] = []
    a, b = capsule.p0 + ring, capsule.p1 + ring
    faces += [np.array([a[k], a[nxt[k]], b[nxt[k]], b[k]]) for k in range(sides)]
    s45 = np.sqrt(0.5)
    for end, sign in ((capsule.p0, -1.0), (capsule.p1, 1.0)):
        base = end + ring
        mid = end + ring * s45 + sign * z * capsule.radius * s45
        pole = end + sign * z * capsule.radius
        faces += [np.array([base[k], base[nxt[k]], mid[nxt[k]], mid[k]]) for k in range(sides)]
        # triangles as quads with a repeated pole: mplot3d mis-scales ragged polygon lists
        faces += [np.array([mid[k], mid[nxt[k]], pole, pole]) for k in range(sides)]
    return faces


def geometry_faces(geometry: Geometry) -> list[FloatArray]:
    """Polygons of a box or capsule in its owning frame [m]."""
    return box_faces(geometry) if isinstance(geometry, Box) else capsule_faces(geometry)


def robot_meshes(
    robot: Robot, q: ArrayLike, G_T_B: FloatArray | None = None
) -> dict[str, list[FloatArray]]:
    """Polygons of the robot's nine bodies at posture ``q``, in G (or B) [m].

    Args:
        robot: the robot.
        q: arm joint angles (4,) [rad].
        G_T_B: pose of the body frame in the drawing frame (4x4); ``None`` = identity.

    Returns:
        Body name -> list of polygons (k, 3): the five base bodies, then ``arm_link_0..3``.
    """
    T = np.eye(4) if G_T_B is None else np.asarray(G_T_B, dtype=float)
    out = {
        name: [transform_points(T, f) for f in box_faces(box)]
        for name, box in robot.base.collision_boxes().items()
    }
    B_T_R = robot.kinematics.link_frames(np.asarray(q, dtype=float))
    for i, link in enumerate(robot.links):
        G_T_R = T @ B_T_R[i]
        out[f"arm_link_{i}"] = [transform_points(G_T_R, f) for f in geometry_faces(link.geometry)]
    return out


def support_polygon_G(robot: Robot, G_T_B: FloatArray | None = None) -> FloatArray:
    """The base's support polygon (n, 3), CCW, lifted by ``SUPPORT_LIFT``, in G (or B) [m]."""
    T = np.eye(4) if G_T_B is None else np.asarray(G_T_B, dtype=float)
    vertices_B = base_polygon(robot).vertices + np.array([0.0, 0.0, SUPPORT_LIFT])
    return transform_points(T, vertices_B)


def draw_support_polygon(
    ax3d: Any,
    robot: Robot,
    G_T_B: FloatArray | None = None,
    color: Any = "tab:green",
    alpha: float = 0.35,
) -> Poly3DCollection:
    """Draw the support polygon as a filled patch on the ground (gid ``support_polygon``).

    It is painted over everything (``OVERLAY_RANK``), translucent, so that it shows through
    the base that stands on it.

    Args:
        ax3d: matplotlib 3-D axes.
        robot: the robot.
        G_T_B: pose of the body frame in the drawing frame (4x4); ``None`` = identity.
        color: face colour (e.g. coloured by the stability margin).
        alpha: opacity in [0, 1].
    """
    patch = LayerPolys(
        [support_polygon_G(robot, G_T_B)],
        OVERLAY_RANK,
        facecolors=color,
        edgecolors="k",
        linewidths=0.8,
    )
    patch.set_alpha(alpha)
    patch.set_gid("support_polygon")
    ax3d.add_collection3d(patch)
    return patch


def draw_robot(
    ax3d: Any,
    robot: Robot,
    q: ArrayLike,
    G_T_B: FloatArray | None = None,
    *,
    base_color: Any = BASE_COLOR,
    track_color: Any = TRACK_COLOR,
    arm_color: Any = ARM_COLOR,
    alpha: float = 1.0,
    edge_width: float = 0.2,
    support: bool = False,
    support_color: Any = "tab:green",
) -> list[Poly3DCollection]:
    """Draw the robot's nine bodies (and optionally its support polygon) on 3-D axes.

    Args:
        ax3d: matplotlib 3-D axes (``projection="3d"``).
        robot: the robot.
        q: arm joint angles (4,) [rad].
        G_T_B: pose of the body frame in the drawing frame (4x4), e.g. ``Terrain.G_T_B(pose)``;
            ``None`` draws in the body frame.
        base_color: face colour of the main body.
        track_color: face colour of tracks and flippers.
        arm_color: face colour of the arm links.
        alpha: opacity in [0, 1].
        edge_width: edge line width of the boxes [pt] (capsules are drawn without edges).
        support: also draw the support polygon (last artist, gid ``support_polygon``).
        support_color: its face colour.

    Returns:
        The artists: one ``Poly3DCollection`` per body (gid = body name), in the order of
        :func:`robot_meshes`, then the support polygon if asked for.
    """
    artists = []
    capsules = {
        f"arm_link_{i}" for i, ln in enumerate(robot.links) if isinstance(ln.geometry, Capsule)
    }
    for name, faces in robot_meshes(robot, q, G_T_B).items():
        if name == "body":
            color = base_color
        elif name.startswith("arm_"):
            color = arm_color
        else:
            color = track_color
        poly = Poly3DCollection(
            faces,
            facecolors=color,
            edgecolors="0.15",
            linewidths=0.0 if name in capsules else edge_width,
            shade=True,
            lightsource=None,
        )
        poly.set_alpha(alpha)
        poly.set_gid(name)
        ax3d.add_collection3d(poly)
        artists.append(poly)
    if support:
        artists.append(draw_support_polygon(ax3d, robot, G_T_B, color=support_color))
    return artists


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


def mesh_points(meshes: dict[str, list[FloatArray]]) -> FloatArray:
    """All polygon vertices of :func:`robot_meshes` stacked (n, 3) [m] (for axis limits)."""
    return np.concatenate([np.concatenate(faces) for faces in meshes.values()])


def draw_poses_on_ground(
    ax3d: Any,
    robot: Robot,
    terrain: Terrain,
    poses: ArrayLike,
    postures: ArrayLike,
    arm_colors: list[Any] | None = None,
    labels: list[str] | None = None,
    path_S: ArrayLike | None = None,
    margin: float = 0.3,
) -> list[list[Poly3DCollection]]:
    """Draw the robot at several base poses on a ground patch that holds them all.

    Args:
        ax3d: matplotlib 3-D axes.
        robot: the robot.
        terrain: the ground.
        poses: base poses (P, 3) of (x, y, heading) in S [m, m, rad].
        postures: arm joint angles (P, 4) [rad], one per pose.
        arm_colors: face colour of the arm at each pose; ``None`` = :data:`ARM_COLOR`.
        labels: text written above each pose's base; ``None`` for none.
        path_S: a path (n, 2) in M drawn dashed on the ground [m], e.g. the circle; or ``None``.
        margin: ground patch margin around the robots [m].

    Returns:
        Per pose, the artists of :func:`draw_robot` (nine bodies each).
    """
    P = np.asarray(poses, dtype=float).reshape(-1, 3)
    Q = np.asarray(postures, dtype=float).reshape(-1, len(robot.links))
    G_T_Bs = [terrain.G_T_B(p) for p in P]
    pts_G = np.concatenate(
        [mesh_points(robot_meshes(robot, q, T)) for q, T in zip(Q, G_T_Bs, strict=True)]
    )
    pts_S = transform_points(np.linalg.inv(terrain.G_T_M()), pts_G)
    lo, hi = pts_S.min(axis=0) - margin, pts_S.max(axis=0) + margin
    draw_ground(ax3d, terrain, Extent(lo[0], hi[0], lo[1], hi[1]))
    if path_S is not None:
        draw_path_on_ground(ax3d, terrain, path_S)
    out = []
    for k, (q, T) in enumerate(zip(Q, G_T_Bs, strict=True)):
        color = ARM_COLOR if arm_colors is None else arm_colors[k]
        out.append(draw_robot(ax3d, robot, q, T, arm_color=color))
        if labels is not None:
            top = transform_points(T, np.array([0.0, 0.0, 0.5]))
            ax3d.text(*top, labels[k], fontsize=8, ha="center", weight="bold", zorder=1e4)
    corners_S = np.array([[lo[0], lo[1], 0], [hi[0], hi[1], 0]])
    set_equal_aspect(ax3d, np.vstack([pts_G, transform_points(terrain.G_T_M(), corners_S)]))
    ax3d.set(xlabel="$x_G$ [m]", ylabel="$y_G$ [m]", zlabel="$z_G$ [m]")
    return out
