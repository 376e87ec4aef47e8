"""The ground under the MuJoCo robot model and the robot's start pose on it.

:mod:`mmstab.physics.robot_model` writes the MJCF; this module says what the ground is (a
plane through a planar terrain's map frame, or a heightmap) and where the robot starts.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from mmstab.core.files import MmstabError
from mmstab.model.robot import FloatArray, Robot, homogeneous
from mmstab.physics.heightfield import Heightmap, heightmap
from mmstab.physics.plane import fit_plane, tilted_frame
from mmstab.terrain.base import Terrain

#: What the robot stands on: an mmstab terrain, a bare heightmap, or None (the flat floor).
Ground = Terrain | Heightmap | None


def ground_heightmap(ground: Ground) -> Heightmap | None:
    """The heightmap of a heightmap ground (NaN cells refused), None for a planar one.

    Raises:
        MmstabError: a terrain that is neither planar (``kind == "ramp"``) nor a heightmap.
    """
    if ground is None or isinstance(ground, Heightmap):
        return ground
    grid = getattr(ground, "heightmap", None)
    if grid is not None:
        return heightmap(grid.elevation, grid.resolution, grid.origin)
    if ground.kind != "ramp":
        raise MmstabError(f"MuJoCo robot model: no ground model for terrain kind {ground.kind!r}")
    return None


def plane_T(ground: Ground) -> FloatArray:
    """Pose in G of a planar ground's map frame M (its plane is z_M = 0)."""
    return np.eye(4) if ground is None or isinstance(ground, Heightmap) else ground.G_T_M()


def start_pose(robot: Robot, ground: Ground, pose: ArrayLike, drop_height: float) -> FloatArray:
    """G_T_B (4, 4) at the start, ``drop_height`` above the ground, pose (x, y, heading) in M.

    On a plane: the terrain's resting pose (the tracks' flat runs on the plane), lifted
    along its normal. On a heightmap (M = G): the attitude of the plane fitted under the
    tracks, the lowest track sample ``drop_height`` [m] above the ground.
    """
    x, y, heading = (float(v) for v in np.asarray(pose, dtype=float))
    c, s = np.cos(heading), np.sin(heading)
    grid = ground_heightmap(ground)
    if grid is None:
        M_T_B = homogeneous([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]], [x, y, 0.0])
        G_T_B = plane_T(ground) @ M_T_B
        G_T_B[:3, 3] += drop_height * G_T_B[:3, 2]
        return G_T_B
    t = robot.base.tracks
    gx, gy = np.meshgrid(np.linspace(-t.length / 2, t.length / 2, 15), [-1.0, 1.0])
    body = np.stack([gx.ravel(), gy.ravel() * (t.separation + t.width) / 2], -1)
    xy = body @ np.array([[c, s], [-s, c]]) + [x, y]
    a, b, _ = fit_plane(xy, grid.height(xy))
    R = tilted_frame(a, b, heading)
    p = np.column_stack([body, np.zeros(len(body))]) @ R.T + [x, y, 0.0]
    z = float(np.max(grid.height(p[:, :2]) - p[:, 2])) + drop_height
    return homogeneous(R, [x, y, z])
