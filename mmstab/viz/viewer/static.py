"""The static part of the viewer's scene: lights, terrain, routes, the plan's targets."""

from __future__ import annotations

from typing import Any

import numpy as np

from mmstab.model.robot import FloatArray
from mmstab.runs.store import Run
from mmstab.viz.viewer.ground import (
    Extent,
    Ground,
    extent_around,
    grid_lines,
    polyline_segments,
    terrain_mesh,
)
from mmstab.viz.viewer.scene import route_points, targets_G

#: Colour of the planned arm-CoM targets.
TARGET_RGB = (190, 0, 170)
#: Margin of the terrain patch around the route [m].
TERRAIN_MARGIN = 1.0


def wxyz(R: FloatArray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix (3, 3)."""
    from viser import transforms

    return np.asarray(transforms.SO3.from_matrix(np.asarray(R, dtype=float)).wxyz)


def _wrap(angle: float) -> float:
    return float(np.pi - np.mod(np.pi - angle, 2 * np.pi))


def _wrap_pose(pose: FloatArray) -> FloatArray:
    return np.array([pose[0], pose[1], _wrap(pose[2])])


def add_static_scene(
    server: Any, problem: Any, ground: Ground, run: Run | None
) -> tuple[Extent, FloatArray]:
    """Add what does not change with time; return the terrain's extent and the reference poses.

    Args:
        server: the ``viser.ViserServer``.
        problem: the problem (its path gives the reference route).
        ground: its terrain.
        run: the stored run shown, or ``None``.
    """
    scene: Any = server.scene
    scene.set_up_direction("+z")
    # plain lights, no environment map: its image-based lighting takes seconds to set
    # up in software WebGL (remote desktops, CI) and washes out the terrain's colours
    scene.configure_environment_map(hdri=None)
    scene.add_light_hemisphere(
        "/lights/sky", sky_color=(255, 255, 255), ground_color=(120, 110, 100), intensity=2.0
    )
    path = problem.base_path  # the circle or a route: the same calls
    reference = path.poses(240)
    poses_for_extent = reference if run is None else np.vstack([reference, run.poses])
    extent = extent_around(poses_for_extent, TERRAIN_MARGIN, getattr(ground, "bounds", None))
    mesh = terrain_mesh(ground, extent)
    import trimesh

    tm = trimesh.Trimesh(mesh.vertices, mesh.faces, vertex_colors=mesh.colors, process=False)
    scene.add_mesh_trimesh("/terrain", tm, cast_shadow=False)
    scene.add_line_segments(
        "/terrain/grid", grid_lines(ground, extent), (150, 150, 140), thickness=0.004
    )
    loop = route_points(ground, np.vstack([reference, reference[:1]]) if path.closed else reference)
    scene.add_line_segments(
        "/route/reference", polyline_segments(loop), (70, 70, 70), thickness=0.012
    )
    if run is not None:
        travelled = route_points(ground, run.poses)
        scene.add_line_segments(
            "/route/travelled", polyline_segments(travelled), (31, 119, 180), thickness=0.012
        )
        plan_poses = path.pose_at(run.plan_fractions)
        targets = targets_G(ground, plan_poses, run.plan_target_com)
        scene.add_point_cloud(
            "/plan/arm_com_targets",
            targets.astype(np.float32),
            TARGET_RGB,
            point_size=0.04,
            point_shape="circle",
        )
    return extent, reference
