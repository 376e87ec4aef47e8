"""3-D drawing of the robot on the ground (matplotlib ``mplot3d``), from the collision geometry.

Every body the collision checker knows is drawn from the same shapes
(:mod:`mmstab.viz.meshes`: the base boxes and the four arm links, capsules as low-poly
cylinders with caps), placed by ``G_T_B`` (the body frame's pose in G, e.g.
``Terrain.G_T_B(pose)``); without it the drawing is in B. The ground under it, paths on the
ground and the axis limits are :mod:`mmstab.viz.ground`'s (re-exported here).

Each body is one ``Poly3DCollection`` whose ``gid`` is its name (``body``, ``track_left``,
..., ``arm_link_0`` ... ``arm_link_3``), so figures and tests can find them.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from mpl_toolkits.mplot3d.art3d import Poly3DCollection
from numpy.typing import ArrayLike

from mmstab.model.robot import Capsule, FloatArray, Robot
from mmstab.terrain import Terrain
from mmstab.viz.ground import (
    GROUND_RANK,
    OVERLAY_RANK,
    PATH_RANK,
    Extent,
    LayerLines,
    LayerPolys,
    clip_to_ground,
    draw_ground,
    draw_path_on_ground,
    set_equal_aspect,
)
from mmstab.viz.meshes import (
    CAPSULE_SIDES,
    SUPPORT_LIFT,
    box_faces,
    capsule_faces,
    geometry_faces,
    mesh_points,
    robot_meshes,
    support_polygon_G,
    transform_points,
)

__all__ = [
    "ARM_COLOR",
    "BASE_COLOR",
    "CAPSULE_SIDES",
    "GROUND_RANK",
    "OVERLAY_RANK",
    "PATH_RANK",
    "SUPPORT_LIFT",
    "TRACK_COLOR",
    "Extent",
    "LayerLines",
    "LayerPolys",
    "box_faces",
    "capsule_faces",
    "clip_to_ground",
    "draw_ground",
    "draw_path_on_ground",
    "draw_poses_on_ground",
    "draw_robot",
    "draw_support_polygon",
    "geometry_faces",
    "mesh_points",
    "robot_meshes",
    "set_equal_aspect",
    "support_polygon_G",
    "transform_points",
]

#: Default face colours (matplotlib colour specs) of the base, tracks/flippers and arm.
BASE_COLOR = "#8c9479"
TRACK_COLOR = "#3a3a3a"
ARM_COLOR = "#e08a1e"


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
