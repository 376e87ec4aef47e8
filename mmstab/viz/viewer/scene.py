"""What the viewer draws, as plain arrays: robot meshes, the stability picture of one instant.

Pure functions of a robot, a ground (:mod:`mmstab.viz.viewer.ground`) and a pose: no server,
no browser, so each piece is testable on its own.

- :func:`robot_body_meshes`: triangle meshes of the robot's nine collision bodies, each in
  its own frame (the body frame B for the base bodies, the DH frame R_i for arm link
  i), so a frame is posed by one transform per instant (``G_T_B``, ``B_T_R[i]``).
- :func:`instant`: at one base pose and arm posture, the body pose, link frames, support
  polygon, overall CoM, its projection along gravity onto the support plane, the tip-over
  axis closest to tipping (the one that sets the force-angle measure) and μ.
- :func:`mu_color`: μ as a colour, red (tipping, μ <= 0) to green (μ at the scale).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import trimesh
from numpy.typing import ArrayLike

from mmstab.model.robot import Box, Capsule, FloatArray, Geometry, Robot
from mmstab.model.urdf import axis_to_z_rotation
from mmstab.stability.static import axis_angles
from mmstab.stability.support import loaded_support
from mmstab.terrain.base import GRAVITY_G
from mmstab.viz.viewer.ground import LINE_LIFT, Ground, resting_poses, transform

#: Colours (RGB 0-255) of the base body, tracks/flippers and arm links.
BASE_RGB = (140, 148, 121)
TRACK_RGB = (58, 58, 58)
ARM_RGB = (224, 138, 30)
#: Colour map of the margin: 0 (tipping) .. mu scale (as stable as parked on the flat).
MU_CMAP = "RdYlGn"
#: Arm display modes: the arm as planned/tracked, held stowed, or removed.
ARM_MODES = ("planned", "stowed", "arm removed")


class BodyMesh(NamedTuple):
    """One collision body as a triangle mesh in its own frame.

    Attributes:
        name: ``body``, ``track_left``, ..., ``arm_link_0`` ... ``arm_link_3``.
        link: ``None`` for a base body (mesh in B), else the arm link index i (mesh in R_i).
        vertices: (V, 3) [m].
        faces: (F, 3) vertex indices, outward normals.
        rgb: colour (0-255).
    """

    name: str
    link: int | None
    vertices: FloatArray
    faces: np.ndarray
    rgb: tuple[int, int, int]


def geometry_mesh(geometry: Geometry, sections: int = 24) -> trimesh.Trimesh:
    """A box or capsule of the robot description as a watertight mesh in its owning frame.

    Args:
        geometry: the shape.
        sections: segments around a capsule's circumference.
    """
    if isinstance(geometry, Box):
        return trimesh.creation.box(extents=geometry.size, transform=geometry.frame_T_shape)
    cap: Capsule = geometry
    T = np.eye(4)
    if cap.length > 0:
        T[:3, :3] = axis_to_z_rotation(cap.p1 - cap.p0)
    T[:3, 3] = cap.center
    return trimesh.creation.capsule(
        height=cap.length, radius=cap.radius, count=[sections, sections // 2], transform=T
    )


def robot_body_meshes(robot: Robot) -> list[BodyMesh]:
    """The robot's collision bodies: the base bodies, then the arm links."""
    out = []
    for name, box in robot.base.collision_boxes().items():
        rgb = BASE_RGB if name == "body" else TRACK_RGB
        m = geometry_mesh(box)
        out.append(BodyMesh(name, None, np.asarray(m.vertices), np.asarray(m.faces), rgb))
    for i, link in enumerate(robot.links):
        m = geometry_mesh(link.geometry)
        out.append(
            BodyMesh(f"arm_link_{i}", i, np.asarray(m.vertices), np.asarray(m.faces), ARM_RGB)
        )
    return out


class Instant(NamedTuple):
    """The robot and its stability at one base pose and arm posture, in G.

    Attributes:
        pose: base pose (x [m], y [m], yaw [rad]) in the map frame M.
        q: arm joint angles (4,) [rad], or ``None`` with the arm removed.
        G_T_B: resting body pose in G (4, 4).
        B_T_R: arm link frames in B (4, 4, 4), or ``None`` with the arm removed.
        gravity_G: gravity in G (3,) [m/s^2].
        com_G: overall CoM (base + arm, or the base alone) (3,) [m].
        com_projection_G: the CoM moved along gravity onto the support plane (3,) [m].
        polygon_G: support polygon vertices, counter-clockwise about its normal (n, 3) [m].
        axis: index j of the closest tip-over axis (polygon vertex j to j + 1).
        axis_G: that axis's end points (2, 3) [m].
        angles: signed force angles theta_j of every axis (n,) [rad].
        mu: the state's one μ [N rad] (:func:`~mmstab.stability.support.loaded_support`;
            min_j theta_j |f_r| without a tool wrench).
    """

    pose: FloatArray
    q: FloatArray | None
    G_T_B: FloatArray
    B_T_R: FloatArray | None
    gravity_G: FloatArray
    com_G: FloatArray
    com_projection_G: FloatArray
    polygon_G: FloatArray
    axis: int
    axis_G: FloatArray
    angles: FloatArray
    mu: float


def arm_posture(robot: Robot, mode: str, q: ArrayLike) -> FloatArray | None:
    """The arm posture shown in a mode of :data:`ARM_MODES`: ``q``, stowed, or ``None``."""
    if mode == "planned":
        return np.asarray(q, dtype=float)
    if mode == "stowed":
        return np.asarray(robot.stowed, dtype=float)
    if mode == "arm removed":
        return None
    raise ValueError(f"arm mode must be one of {ARM_MODES}, got {mode!r}")


def instant(robot: Robot, ground: Ground, pose: ArrayLike, q: ArrayLike | None) -> Instant:
    """The stability picture at one base pose and arm posture.

    The state's own support: the base rested under this state's overall CoM
    (``ground.support(robot, pose, com_body)``; on a heightmap the arm's CoM moves the rest
    and decides which contacts carry the load), the polygon the hull of the contacts that
    carry it. μ is mmstab's one μ of the state
    (:func:`mmstab.stability.support.loaded_support`: what plan, rest and track report); the
    angles are the force angles (:func:`mmstab.stability.static.axis_angles`) of that
    polygon for the overall CoM under f_r = m g, the smallest of which, times |f_r|, is μ
    (a tool's wrench, where the robot has one, enters μ only).

    Args:
        robot: the robot.
        ground: the terrain.
        pose: base pose (x [m], y [m], yaw [rad]) in M.
        q: arm joint angles (4,) [rad]; ``None`` = the arm removed.
    """
    p = np.asarray(pose, dtype=float).reshape(3)
    if q is None:
        qa, B_T_R, arm_com = None, None, None
        mass, com_B = robot.base.mass, np.asarray(robot.base.com, dtype=float)
    else:
        qa = np.asarray(q, dtype=float).reshape(4)
        B_T_R = robot.kinematics.link_frames(qa)
        arm_com = np.asarray(robot.arm_com(qa), dtype=float)
        mass, com_B = robot.total_mass, np.asarray(robot.overall_com(arm_com), dtype=float)
    stand = ground.support(robot, p, com_body=com_B)
    G_T_B, polygon_G = np.asarray(stand.G_T_B, float), np.asarray(stand.polygon_G, float)
    gravity_G = np.asarray(GRAVITY_G, dtype=float)
    com_G = transform(G_T_B, com_B)
    polygon_G, normal = oriented_polygon(polygon_G, com_G)
    angles = np.atleast_1d(np.asarray(axis_angles(polygon_G, com_G, mass * gravity_G), float))
    j = int(np.argmin(angles))
    loaded = loaded_support(robot, ground, p, arm_com, None if qa is None else qa[None])
    # the CoM moved along gravity until it meets the support plane (through the centroid)
    along = float(normal @ gravity_G)
    centre = polygon_G.mean(axis=0)
    step = float(normal @ (centre - com_G)) / along if abs(along) > 1e-12 else 0.0
    return Instant(
        pose=p,
        q=qa,
        G_T_B=G_T_B,
        B_T_R=B_T_R,
        gravity_G=gravity_G,
        com_G=com_G,
        com_projection_G=com_G + step * gravity_G,
        polygon_G=polygon_G,
        axis=j,
        axis_G=polygon_G[[j, (j + 1) % len(polygon_G)]],
        angles=angles,
        mu=float(loaded.mu[0]),
    )


def oriented_polygon(polygon: ArrayLike, com: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """A convex polygon's vertices ordered counter-clockwise about its normal toward ``com``.

    The force-angle measure needs that order (:mod:`mmstab.stability.static`); a terrain may give
    either. The normal is Newell's (robust for slightly non-planar contacts).

    Args:
        polygon: ordered vertices (n, 3) [m], either way round.
        com: a point on the side the normal must face, e.g. the CoM (3,) [m].

    Returns:
        The vertices (n, 3) [m], possibly reversed, and the unit normal (3,).
    """
    v = np.asarray(polygon, dtype=float)
    nxt = np.roll(v, -1, axis=0)
    normal = np.cross(v, nxt).sum(axis=0)  # Newell: 2 x area x unit normal
    normal /= np.linalg.norm(normal)
    if normal @ (np.asarray(com, dtype=float) - v.mean(axis=0)) < 0:
        return v[::-1].copy(), -normal
    return v, normal


def mu_color(mu: float, scale: float) -> tuple[int, int, int]:
    """μ [N rad] as RGB (0-255): red at or below 0, yellow half way, green at ``scale``."""
    from matplotlib import colormaps

    s = float(np.clip(mu / scale, 0.0, 1.0)) if scale > 0 else 0.0
    r, g, b, _ = colormaps[MU_CMAP](s)
    return int(round(255 * r)), int(round(255 * g)), int(round(255 * b))


def polygon_fan(polygon: ArrayLike) -> np.ndarray:
    """Triangles (n - 2, 3) of a convex polygon's vertices (n, 3), fanned from vertex 0."""
    n = len(np.asarray(polygon))
    return np.array([[0, k, k + 1] for k in range(1, n - 1)], dtype=np.uint32)


def route_points(ground: Ground, poses: ArrayLike) -> FloatArray:
    """The base route: the body origins at the resting poses, lifted off the ground (N, 3) [m].

    Args:
        ground: the terrain.
        poses: base poses (N, 3) of (x [m], y [m], yaw [rad]) in M.
    """
    T = resting_poses(ground, poses)
    return T[:, :3, 3] + LINE_LIFT * T[:, :3, 2]


def targets_G(ground: Ground, poses: ArrayLike, com_body: ArrayLike) -> FloatArray:
    """Planned arm CoMs, given in the body frame at their base poses, placed in G (K, 3) [m].

    Args:
        ground: the terrain.
        poses: the plan's base poses (K, 3) in M [m, m, rad].
        com_body: the planned arm CoMs in B (K, 3) [m].
    """
    T = resting_poses(ground, poses)
    c = np.asarray(com_body, dtype=float).reshape(-1, 3)
    return np.einsum("kij,kj->ki", T[:, :3, :3], c) + T[:, :3, 3]
