"""Shared plotting helpers (matplotlib, headless-safe). Degrees appear only in labels."""

from __future__ import annotations

import os
from typing import Any

import matplotlib

if not os.environ.get("MPLBACKEND"):
    matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from numpy.typing import ArrayLike  # noqa: E402

from mmstab.model.robot import Robot  # noqa: E402
from mmstab.paths.circle import CirclePath
from mmstab.terrain import rot_z  # noqa: E402


def new_figure(*args: Any, **kwargs: Any) -> tuple[Any, Any]:
    """``plt.subplots`` with the project's defaults."""
    kwargs.setdefault("constrained_layout", True)
    return plt.subplots(*args, **kwargs)


def draw_base_topview(
    ax: Any, robot: Robot, pose: ArrayLike, color: str = "C0", label: str | None = None
) -> None:
    """Draw the base's track footprint and heading, seen from above (the map frame M).

    Args:
        ax: matplotlib 2-D axes.
        robot: the robot.
        pose: (x, y, yaw) in M [m, m, rad].
        color: matplotlib colour.
        label: optional text written at the pose.
    """
    x, y, h = np.asarray(pose, dtype=float)
    from mmstab.stability.static import base_polygon

    pts = base_polygon(robot).vertices[:, :2]
    R = rot_z(h)[:2, :2]
    world = np.vstack([pts, pts[:1]]) @ R.T + [x, y]
    ax.plot(world[:, 0], world[:, 1], color=color, lw=1.2)
    ax.arrow(x, y, 0.3 * np.cos(h), 0.3 * np.sin(h), head_width=0.06, color=color)
    if label:
        ax.annotate(label, (x, y), textcoords="offset points", xytext=(6, 6), fontsize=8)


def draw_circle(ax: Any, circle: CirclePath, **kwargs: Any) -> None:
    """Draw the circular path in the map frame M."""
    xy = circle.pose_at(np.linspace(0, 1, 200))[:, :2]
    ax.plot(xy[:, 0], xy[:, 1], **{"color": "0.6", "ls": "--", "lw": 1, **kwargs})


def arm_polyline(robot: Robot, q: ArrayLike, G_T_B: ArrayLike | None = None) -> np.ndarray:
    """The arm as a polyline through the mount and the link-frame origins, (5, 3) [m].

    Args:
        robot: the robot.
        q: arm posture (4,) [rad].
        G_T_B: pose of the body frame (4x4); default identity (body-frame points).
    """
    frames = robot.kinematics.link_frames(q)
    pts = np.vstack([robot.mount_T[:3, 3], frames[:, :3, 3]])
    T = np.eye(4) if G_T_B is None else np.asarray(G_T_B, dtype=float)
    return pts @ T[:3, :3].T + T[:3, 3]


def draw_arm_3d(
    ax: Any, robot: Robot, q: ArrayLike, G_T_B: ArrayLike | None = None, **kwargs: Any
) -> None:
    """Draw the arm as a stick figure on 3-D axes (body frame unless ``G_T_B`` given)."""
    pts = arm_polyline(robot, q, G_T_B)
    ax.plot(pts[:, 0], pts[:, 1], pts[:, 2], **{"color": "C2", "lw": 1.5, **kwargs})
