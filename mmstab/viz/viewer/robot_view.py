"""The viewer's moving scene: the robot and the stability picture of the instant shown.

:func:`add_robot_view` adds the nodes (``/robot`` posed by ``G_T_B``, its base bodies in B,
arm links posed by ``B_T_R[i]``; the support polygon, the overall CoM, its projection along
gravity and the closest tip-over axis) and :func:`draw_instant` moves them to an
:class:`~mmstab.viz.viewer.scene.Instant`. Needs ``viser`` (through the server handed in).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from mmstab.model.robot import Robot
from mmstab.viz.viewer.scene import Instant, polygon_fan, robot_body_meshes
from mmstab.viz.viewer.static import wxyz

#: The support polygon and the CoM's projection are drawn this far above the ground [m].
SUPPORT_LIFT = 3e-3
#: Opacity of the base bodies when seen through (the support polygon lies under them).
BASE_OPACITY = 0.45


@dataclass
class RobotView:
    """The handles of the moving scene nodes.

    Attributes:
        robot: ``/robot``, the body frame B.
        links: the arm links ``/robot/arm_link_i``, posed in B.
        base_bodies: the base bodies (body, tracks, flippers), fixed in B.
        support: the support polygon.
        com: the overall CoM.
        projection: the CoM's projection along gravity.
        gravity: the gravity line from the CoM to its projection.
        axis: the closest tip-over axis.
    """

    robot: Any
    links: list[Any]
    base_bodies: list[Any]
    support: Any
    com: Any
    projection: Any
    gravity: Any
    axis: Any


def add_robot_view(server: Any, robot: Robot) -> RobotView:
    """Add the robot's bodies and the stability nodes to ``server``'s scene (not posed yet)."""
    scene: Any = server.scene
    frame = scene.add_frame("/robot", show_axes=False)
    links: list[Any] = []
    base_bodies: list[Any] = []
    for body in robot_body_meshes(robot):
        handle = scene.add_mesh_simple(
            f"/robot/{body.name}",
            body.vertices,
            body.faces,
            color=body.rgb,
            flat_shading=body.link is None,
            opacity=BASE_OPACITY if body.link is None else None,
        )
        (base_bodies if body.link is None else links).append(handle)
    support = scene.add_mesh_simple(
        "/stability/support_polygon",
        np.zeros((3, 3)),
        np.array([[0, 1, 2]]),
        color=(0, 160, 0),
        opacity=0.55,
        side="double",
        cast_shadow=False,
    )
    com = scene.add_icosphere("/stability/com", radius=0.03, color=(20, 20, 20))
    projection = scene.add_icosphere("/stability/com_projection", radius=0.02, color=(120, 60, 160))
    gravity = scene.add_line_segments(
        "/stability/gravity_line", np.zeros((1, 2, 3)), (120, 60, 160), thickness=0.006
    )
    axis = scene.add_line_segments(
        "/stability/tip_axis", np.zeros((1, 2, 3)), (200, 0, 0), thickness=0.025
    )
    return RobotView(frame, links, base_bodies, support, com, projection, gravity, axis)


def draw_instant(server: Any, view: RobotView, now: Instant, rgb: Any) -> None:
    """Pose the robot at ``now`` and draw its support polygon in colour ``rgb``, atomically."""
    lift = SUPPORT_LIFT * now.G_T_B[:3, 2]  # off the ground along the body's z, to show
    with server.atomic():
        view.robot.position = now.G_T_B[:3, 3]
        view.robot.wxyz = wxyz(now.G_T_B[:3, :3])
        for i, handle in enumerate(view.links):
            handle.visible = now.B_T_R is not None
            if now.B_T_R is not None:
                handle.position = now.B_T_R[i][:3, 3]
                handle.wxyz = wxyz(now.B_T_R[i][:3, :3])
        view.support.vertices = (now.polygon_G + lift).astype(np.float32)
        view.support.faces = polygon_fan(now.polygon_G)
        view.support.color = rgb
        view.com.position = now.com_G
        view.projection.position = now.com_projection_G + lift
        view.gravity.points = np.array([[now.com_G, now.com_projection_G]], dtype=np.float32)
        view.axis.points = (now.axis_G + 2 * lift)[None].astype(np.float32)


def set_see_through(view: RobotView, see_through: bool) -> None:
    """Draw the base bodies translucent (the support polygon shows through) or opaque."""
    for handle in view.base_bodies:
        handle.opacity = BASE_OPACITY if see_through else None
