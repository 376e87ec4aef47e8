"""A robot recording generated from a problem (``mmstab record``; ``docs/online.md``).

What a robot driving the problem's route would record, built from mmstab's own ground: a
robot-centric elevation map (``grid_map_msgs/GridMap``, layers ``elevation`` and
``variance``) that slides with the robot at ``record.rate``, and odometry
(``nav_msgs/Odometry``, the base resting on the ground) with TF at ``record.odom_rate``.
Like a real elevation map, the window holds only what the sensor sees: cells beyond
``record.range`` of the robot are unknown (NaN), and so are seeded occluded patches (discs
of ``OCCLUSION_RADIUS``, fixed on the ground as a real map's shadows are) covering about
``record.unknown`` of the ground; heights carry seeded Gaussian noise (``record.noise`` RMS)
that is the cell's own (a fused map's estimate: the same in every map that holds the cell),
and the map is a circular buffer whose start index moves with the robot. Everything is seeded
(``online.record.seed``): the same problem gives the same recording, byte for byte.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from mmstab.core.bags import ROS1, BagWriter, bag_kind
from mmstab.core.files import MmstabError
from mmstab.core.problem import Problem
from mmstab.model.robot import FloatArray
from mmstab.paths.route import RoutePath
from mmstab.runs.online.stream import ODOMETRY
from mmstab.runs.recording import transform_stamped
from mmstab.terrain.factory import as_heightmap
from mmstab.terrain.gridmap import GRIDMAP, GridMapFrame, to_message, typestore
from mmstab.terrain.heightmap import Heightmap
from mmstab.terrain.heightmap_terrain import HeightmapTerrain

FRAME, BASE_FRAME = "odom", "base_link"
#: Cell size of a ramp sampled as the recorded ground [m].
RAMP_RESOLUTION = 0.05
#: Receive delay of a map after its stamp [s]: it is built from the odometry of its stamp.
MAP_DELAY = 1e-3
#: Radius of an occluded (unknown) patch of the recorded ground [m].
OCCLUSION_RADIUS = 0.15


class RecordSettings(NamedTuple):
    """The ``online`` section's recording settings (``online.record``).

    Attributes:
        map_topic: GridMap topic.
        odom_topic: Odometry topic.
        rate: map rate [Hz].
        window: side of the square robot-centric map [m].
        range: sensor range around the robot [m]; cells beyond it are unknown.
        noise: height noise, RMS [m].
        unknown: fraction of the ground in occluded (unknown) patches [-].
        odom_rate: odometry and TF rate [Hz].
        seed: the noise's and dropouts' seed.
    """

    map_topic: str
    odom_topic: str
    rate: float
    window: float
    range: float
    noise: float
    unknown: float
    odom_rate: float
    seed: int

    @classmethod
    def of(cls, problem: Problem) -> RecordSettings:
        """The problem's ``online`` section (defaults filled in)."""
        online = problem.section("online")
        r = online["record"]
        return cls(
            online["map_topic"], online["odom_topic"], float(r["rate"]), float(r["window"]),
            float(r["range"]), float(r["noise"]), float(r["unknown"]), float(r["odom_rate"]),
            int(r["seed"]),
        )  # fmt: skip


class Recording(NamedTuple):
    """What :func:`record_route` wrote.

    Attributes:
        path: the recording.
        maps: GridMap messages.
        odometry: Odometry (and TF) messages.
        duration: recorded time [s].
        bytes: size on disk [B].
    """

    path: Path
    maps: int
    odometry: int
    duration: float
    bytes: int


def ground_of(problem: Problem, route: RoutePath, margin: float) -> Heightmap:
    """The problem's ground as a heightmap: its own, or the ramp sampled around the route.

    Args:
        problem: the problem.
        route: its route.
        margin: ground beyond the route's extent on every side [m].
    """
    terrain = problem.terrain
    if isinstance(terrain, HeightmapTerrain):
        return terrain.heightmap
    xy = route.route.sample(np.linspace(0.0, route.length, 256)).pose[:, :2]
    half = np.abs(xy).max(axis=0) + margin
    return as_heightmap(terrain, (2.0 * half[0], 2.0 * half[1]), RAMP_RESOLUTION)


def occlusions(ground: Heightmap, fraction: float, rng: np.random.Generator) -> FloatArray:
    """Unknown patches of the ground (persistent, as an elevation map's shadows are).

    Discs of radius ``OCCLUSION_RADIUS`` [m] at seeded places, as many as cover about
    ``fraction`` of the ground; returns a boolean mask in the ground's layout.
    """
    ny, nx = ground.elevation.shape
    res = ground.resolution
    r_cells = max(OCCLUSION_RADIUS / res, 1.0)
    count = int(round(fraction * nx * ny / (np.pi * r_cells**2)))
    centres = rng.random((count, 2)) * [nx, ny]
    mask = np.zeros((ny, nx), dtype=bool)
    iy, ix = np.mgrid[0:ny, 0:nx]
    for cx, cy in centres:  # a few hundred discs: once per recording
        lo_x, hi_x = int(max(cx - r_cells, 0)), int(min(cx + r_cells + 1, nx))
        lo_y, hi_y = int(max(cy - r_cells, 0)), int(min(cy + r_cells + 1, ny))
        sub = (ix[lo_y:hi_y, lo_x:hi_x] - cx) ** 2 + (iy[lo_y:hi_y, lo_x:hi_x] - cy) ** 2
        mask[lo_y:hi_y, lo_x:hi_x] |= sub <= r_cells**2
    return mask


def window_map(
    ground: Heightmap,
    hidden: FloatArray,
    xy: FloatArray,
    settings: RecordSettings,
) -> tuple[Heightmap, FloatArray, tuple[int, int]]:
    """The robot-centric map at base position ``xy`` [m]: heights, variance, start index.

    Args:
        ground: the whole ground.
        hidden: its occluded cells (:func:`occlusions`).
        xy: the robot's position [m].
        settings: the recording's settings (window, range, noise).

    Returns:
        (the window as a heightmap (NaN = unknown), its variance layer [m^2], the circular
        buffer's start index (outer, inner) [cells]).
    """
    res = ground.resolution
    n = max(int(round(settings.window / res)), 2)
    centre = np.round((xy - ground.origin) / res).astype(int)
    i0 = centre - n // 2  # (ix0, iy0): the window's -x/-y corner cell in the ground
    ny, nx = ground.elevation.shape
    iy, ix = np.mgrid[i0[1] : i0[1] + n, i0[0] : i0[0] + n]
    inside = (ix >= 0) & (ix < nx) & (iy >= 0) & (iy < ny)
    heights = np.full((n, n), np.nan)
    heights[inside] = np.where(
        hidden[iy[inside], ix[inside]], np.nan, ground.elevation[iy[inside], ix[inside]]
    )
    origin = ground.origin + res * i0
    cx, cy = origin[0] + res * (ix - i0[0]), origin[1] + res * (iy - i0[1])
    seen = np.hypot(cx - xy[0], cy - xy[1]) <= settings.range
    heights = np.where(seen, heights, np.nan)
    variance = np.where(np.isfinite(heights), settings.noise**2, np.nan)
    start = (int(-i0[0] % n), int(-i0[1] % n))  # the buffer rolls as the window moves
    return Heightmap(heights, res, origin, "recording window"), variance, start


def record_route(
    problem: Problem, out: str | os.PathLike[str], duration: float | None = None
) -> Recording:
    """Write the recording of a robot driving the problem's route (module text).

    Args:
        problem: a route problem on a heightmap (or the ramp, sampled).
        out: ``.mcap``, ``.bag`` or a ROS 2 bag directory (written atomically).
        duration: record only the first ``duration`` seconds [s]; default the whole route.

    Raises:
        MmstabError: the problem's path is not a route.
    """
    route = problem.route
    if route is None:
        raise MmstabError(f"{problem.path}: path: not a route (waypoints or file)")
    settings = RecordSettings.of(problem)
    T = route.duration if duration is None else min(float(duration), route.duration)
    ground = ground_of(problem, route, settings.window)
    rng = np.random.default_rng(settings.seed)
    hidden = occlusions(ground, settings.unknown, rng)
    # a fused map's error is the cell's estimate: the same in every map that holds the cell
    noisy = rng.normal(0.0, settings.noise, ground.elevation.shape)
    ground = Heightmap(ground.elevation + noisy, ground.resolution, ground.origin, ground.source)
    ros1 = bag_kind(out) == ROS1
    store = typestore(ros1)
    t_map = np.arange(0.0, T + 1e-9, 1.0 / settings.rate)
    t_odom = np.arange(0.0, T + 1e-9, 1.0 / settings.odom_rate)
    poses = route.pose_at(t_odom / route.lap_time)
    G_T_B = problem.terrain.G_T_B(poses)
    speed = route.speed_at_t(t_odom)
    events = sorted(
        [(t, 0, i) for i, t in enumerate(t_odom)] + [(t, 1, i) for i, t in enumerate(t_map)]
    )
    with BagWriter(out, store) as w:
        for t, kind, i in events:
            if kind == 0:
                odom, tf = _odometry(store, ros1, t, G_T_B[i], speed[i])
                w.write(settings.odom_topic, ODOMETRY, t, odom)
                w.write("/tf", "tf2_msgs/msg/TFMessage", t, tf)
                continue
            xy = route.pose_at(np.array([t / route.lap_time]))[0, :2]
            hm, variance, start = window_map(ground, hidden, xy, settings)
            frame = GridMapFrame(hm, FRAME, t, {"variance": variance})
            # received after the odometry it was built with (its stamp stays t)
            w.write(settings.map_topic, GRIDMAP, t + MAP_DELAY, to_message(frame, ros1, start))
    path = Path(out)
    size = sum(f.stat().st_size for f in path.rglob("*")) if path.is_dir() else path.stat().st_size
    return Recording(path, len(t_map), len(t_odom), float(T), int(size))


def _odometry(store: Any, ros1: bool, t: float, G_T_B: FloatArray, speed: float) -> tuple[Any, Any]:
    """nav_msgs/Odometry and its tf2_msgs/TFMessage at time t [s] for the resting pose."""
    T = store.types
    tf = transform_stamped(store, ros1, t, FRAME, BASE_FRAME, G_T_B)
    p = tf.transform.translation
    vec = T["geometry_msgs/msg/Vector3"]
    cov = np.zeros(36)
    odom = T[ODOMETRY](
        header=tf.header,
        child_frame_id=BASE_FRAME,
        pose=T["geometry_msgs/msg/PoseWithCovariance"](
            pose=T["geometry_msgs/msg/Pose"](
                position=T["geometry_msgs/msg/Point"](x=p.x, y=p.y, z=p.z),
                orientation=tf.transform.rotation,
            ),
            covariance=cov,
        ),
        twist=T["geometry_msgs/msg/TwistWithCovariance"](
            twist=T["geometry_msgs/msg/Twist"](
                linear=vec(x=float(speed), y=0.0, z=0.0), angular=vec(x=0.0, y=0.0, z=0.0)
            ),
            covariance=cov,
        ),
    )
    return odom, T["tf2_msgs/msg/TFMessage"](transforms=[tf])
