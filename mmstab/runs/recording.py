"""Runs as robot recordings (MCAP, ROS 2 bag, ROS 1 bag) with standard messages.

A plan, a tracked run or an online run written for RViz and Foxglove, with the URDF that
``mmstab urdf`` exports (its joint names ``arm_joint_i``, its frames ``base_link`` and
``arm_frame_i``):

- ``/joint_states`` (``sensor_msgs/JointState``): the arm's posture [rad];
- ``/tf`` (``tf2_msgs/TFMessage``): ``odom`` -> ``base_link`` (the resting pose) and
  ``base_link`` -> ``arm_frame_i`` (the arm's link frames);
- ``/mu`` (``std_msgs/Float64``): the force-angle measure μ [N rad];
- ``/support_polygon`` (``visualization_msgs/Marker``, a closed line strip in ``odom``):
  the support polygon, coloured by μ (red at μ <= 0, green at the run's μ_max and above);
- ``/arm_trajectory`` (``trajectory_msgs/JointTrajectory``, once, at the start): the
  postures of a plan with their times.

The output path's suffix picks the format (:mod:`mmstab.core.bags`); written atomically.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from scipy.spatial.transform import Rotation

from mmstab.core.bags import ROS1, BagWriter, bag_kind
from mmstab.model.robot import FloatArray, Robot
from mmstab.terrain import Terrain
from mmstab.terrain.gridmap import ros_header, ros_time, typestore

ODOM, BASE = "odom", "base_link"
TOPICS = {
    "/joint_states": "sensor_msgs/msg/JointState",
    "/tf": "tf2_msgs/msg/TFMessage",
    "/mu": "std_msgs/msg/Float64",
    "/support_polygon": "visualization_msgs/msg/Marker",
    "/arm_trajectory": "trajectory_msgs/msg/JointTrajectory",
}


class RunFrames(NamedTuple):
    """A run, sample by sample, as the recording shows it.

    Attributes:
        t: times (N,) [s].
        G_T_B: resting base poses (N, 4, 4) in the map frame ``odom``.
        q: arm postures (N, n) [rad].
        mu: μ (N,) [N rad] (NaN where unknown).
        polygons: support polygon per sample (m_i, 3) in ``odom`` [m] (empty: none).
    """

    t: FloatArray
    G_T_B: FloatArray
    q: FloatArray
    mu: FloatArray
    polygons: list[FloatArray]


def frames_at(
    terrain: Terrain, robot: Robot, t: FloatArray, poses: FloatArray, q: FloatArray, mu: FloatArray
) -> RunFrames:
    """A run's samples as frames: the base rested on ``terrain`` at each pose.

    Args:
        terrain: the ground (its map frame is the recording's ``odom``).
        robot: the robot.
        t: times (N,) [s].
        poses: base poses (x, y, yaw) (N, 3) in the terrain's map frame.
        q: arm postures (N, n) [rad].
        mu: μ (N,) [N rad].

    Each state's body pose and support polygon are its own rest's, under its overall CoM
    (:meth:`Terrain.support`): the support its μ is computed on.
    """
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    q = np.asarray(q, dtype=float)
    # each state rests under its own CoM: the body and polygon drawn are those of its μ
    com = np.asarray(robot.overall_com(robot.arm_com(q)), dtype=float).reshape(-1, 3)
    stands = [terrain.support(robot, p, com_body=c if np.isfinite(c).all() else None)
              for p, c in zip(poses, com, strict=True)]  # fmt: skip
    G_T_B = np.array([s.G_T_B for s in stands]).reshape(-1, 4, 4)
    return RunFrames(np.asarray(t, dtype=float), G_T_B, q, np.asarray(mu, dtype=float),
                     [s.polygon_G for s in stands])  # fmt: skip


def joint_names(robot: Robot) -> list[str]:
    """The URDF's arm joint names (``mmstab.model.urdf``)."""
    return [f"arm_joint_{i}" for i in range(len(robot.kinematics.links))]


def write_run(path: str | os.PathLike[str], robot: Robot, frames: RunFrames, mu_max: float) -> Path:
    """Write a run (module text).

    Args:
        path: ``.mcap``, ``.bag`` or a ROS 2 bag directory.
        robot: the robot (joint names, link frames).
        frames: the run.
        mu_max: μ coloured full green [N rad].
    """
    ros1 = bag_kind(path) == ROS1
    store = typestore(ros1)
    B_T_R = robot.kinematics.link_frames(frames.q)  # (N, n, 4, 4)
    names = joint_names(robot)
    with BagWriter(path, store) as w:
        w.write("/arm_trajectory", TOPICS["/arm_trajectory"], float(frames.t[0]),
                _trajectory(store, ros1, frames, names))  # fmt: skip
        for i, t in enumerate(frames.t):
            t = float(t)
            w.write("/joint_states", TOPICS["/joint_states"], t,
                    _joint_state(store, ros1, t, names, frames.q[i]))  # fmt: skip
            if np.isfinite(frames.G_T_B[i]).all():  # no pose where the ground was unknown
                transforms = [transform_stamped(store, ros1, t, ODOM, BASE, frames.G_T_B[i])]
                transforms += [
                    transform_stamped(store, ros1, t, BASE, f"arm_frame_{j}", B_T_R[i, j])
                    for j in range(len(names))
                ]
                tf = store.types[TOPICS["/tf"]](transforms=transforms)
                w.write("/tf", TOPICS["/tf"], t, tf)
            w.write("/mu", TOPICS["/mu"], t, store.types[TOPICS["/mu"]](data=float(frames.mu[i])))
            if len(frames.polygons[i]):
                marker = _polygon(store, ros1, t, frames.polygons[i], frames.mu[i], mu_max)
                w.write("/support_polygon", TOPICS["/support_polygon"], t, marker)
    return Path(path)


def _joint_state(store: Any, ros1: bool, t: float, names: list[str], q: FloatArray) -> Any:
    empty = np.zeros(0)
    return store.types[TOPICS["/joint_states"]](
        header=ros_header(store, ros1, t, ""), name=names, position=np.asarray(q, dtype=float),
        velocity=empty, effort=empty,
    )  # fmt: skip


def transform_stamped(
    store: Any, ros1: bool, t: float, parent: str, child: str, T: FloatArray
) -> Any:
    """``geometry_msgs/TransformStamped`` of ``parent_T_child`` (4, 4) at ``t`` [s].

    Also the odometry's pose (:mod:`mmstab.outputs.recording`): one quaternion convention.
    """
    types = store.types
    x, y, z, w = Rotation.from_matrix(T[:3, :3]).as_quat()
    p = T[:3, 3]
    return types["geometry_msgs/msg/TransformStamped"](
        header=ros_header(store, ros1, t, parent),
        child_frame_id=child,
        transform=types["geometry_msgs/msg/Transform"](
            translation=types["geometry_msgs/msg/Vector3"](x=p[0], y=p[1], z=p[2]),
            rotation=types["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w),
        ),
    )


def mu_colour(mu: float, mu_max: float) -> tuple[float, float, float]:
    """RGB of μ [N rad]: red at μ <= 0, through yellow, green at ``mu_max`` and above."""
    if not np.isfinite(mu):
        return (0.5, 0.5, 0.5)
    f = float(np.clip(mu / mu_max, 0.0, 1.0))
    return (min(1.0, 2.0 * (1.0 - f)), min(1.0, 2.0 * f), 0.0)


def _polygon(store: Any, ros1: bool, t: float, poly: FloatArray, mu: float, mu_max: float) -> Any:
    types = store.types
    point = types["geometry_msgs/msg/Point"]
    closed = np.vstack([poly, poly[:1]])
    r, g, b = mu_colour(float(mu), mu_max)
    pose = types["geometry_msgs/msg/Pose"](
        position=point(x=0.0, y=0.0, z=0.0),
        orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
    )
    marker = types[TOPICS["/support_polygon"]]
    fields = {
        "header": ros_header(store, ros1, t, ODOM),
        "ns": "support_polygon",
        "id": 0,
        "type": 4,  # LINE_STRIP
        "action": 0,
        "pose": pose,
        "scale": types["geometry_msgs/msg/Vector3"](x=0.01, y=0.0, z=0.0),
        "color": types["std_msgs/msg/ColorRGBA"](r=r, g=g, b=b, a=1.0),
        "lifetime": ros_time(store, 0.0, "Duration"),
        "frame_locked": False,
        "points": [point(x=p[0], y=p[1], z=p[2]) for p in closed],
        "colors": [],
        "text": f"{mu:.1f}",
        "mesh_resource": "",
        "mesh_use_embedded_materials": False,
    }
    fields.update(_marker_extras(store, marker))
    known = marker.__dataclass_fields__  # ROS 1's Marker lacks ROS 2's later fields
    return marker(**{k: v for k, v in fields.items() if k in known})


def _marker_extras(store: Any, marker: Any) -> dict[str, Any]:
    """Fields newer Marker definitions add (empty texture, mesh file)."""
    types, names = store.types, marker.__dataclass_fields__
    out: dict[str, Any] = {}
    if "texture" in names:
        out["texture_resource"] = ""
        out["texture"] = types["sensor_msgs/msg/CompressedImage"](
            header=ros_header(store, False, 0.0, ""), format="", data=np.zeros(0, dtype=np.uint8)
        )
        out["uv_coordinates"] = []
    if "mesh_file" in names:
        out["mesh_file"] = types["visualization_msgs/msg/MeshFile"](
            filename="", data=np.zeros(0, dtype=np.uint8)
        )
    return out


def _trajectory(store: Any, ros1: bool, frames: RunFrames, names: list[str]) -> Any:
    types = store.types
    point = types["trajectory_msgs/msg/JointTrajectoryPoint"]
    empty = np.zeros(0)
    points = []
    for t, q in zip(frames.t - frames.t[0], frames.q, strict=True):
        when = ros_time(store, float(t), "Duration")
        points.append(point(positions=np.asarray(q, dtype=float), velocities=empty,
                            accelerations=empty, effort=empty, time_from_start=when))  # fmt: skip
    return types[TOPICS["/arm_trajectory"]](
        header=ros_header(store, ros1, float(frames.t[0]), BASE), joint_names=names, points=points
    )
