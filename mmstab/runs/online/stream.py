"""A recording as the robot lived it: each elevation map with the odometry received by then.

Odometry is ``nav_msgs/Odometry`` (its pose in the map's frame); the base pose the loop uses
is (x, y, yaw) of the last odometry message received before the map. A map that arrives
before any odometry is skipped (and counted). Times are from the recording's start [s].
A map in another frame than the odometry takes the odometry's pose through the recording's
TF (:mod:`mmstab.runs.online.frames`). Optionally the arm's measured posture: the last
``sensor_msgs/JointState`` received before the map, its positions picked by the arm's joint
names (those of ``mmstab urdf``).
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from typing import Any, NamedTuple

import numpy as np

from mmstab.core.files import ConfigError
from mmstab.model.robot import FloatArray
from mmstab.runs.online.frames import TF_MESSAGE, TF_TOPICS, TransformBuffer, planar, pose_matrix
from mmstab.terrain.gridmap import GRIDMAP, GridMapFrame, from_message
from mmstab.terrain.recording import messages, open_recording

ODOMETRY = "nav_msgs/msg/Odometry"
JOINT_STATE = "sensor_msgs/msg/JointState"


class Odometry(NamedTuple):
    """One odometry message.

    Attributes:
        time: receive time from the recording's start [s].
        frame_id: the frame its pose is in.
        pose: (x [m], y [m], yaw [rad]).
        speed: forward speed in the base frame [m/s].
    """

    time: float
    frame_id: str
    pose: FloatArray
    speed: float


class JointReading(NamedTuple):
    """The arm's measured posture.

    Attributes:
        time: receive time from the recording's start [s].
        q: the arm's joint positions, in the arm's joint order [rad].
    """

    time: float
    q: FloatArray


class MapUpdate(NamedTuple):
    """One map and the base pose (and arm posture) the robot knew when it arrived.

    Attributes:
        time: the map's receive time from the recording's start [s].
        grid: the map (mmstab's layout).
        odometry: the last odometry received before it.
        joints: the last joint state received before it (None: none, or not asked for).
    """

    time: float
    grid: GridMapFrame
    odometry: Odometry
    joints: JointReading | None = None


def yaw_of(q: Any) -> float:
    """Heading [rad] of a quaternion (x, y, z, w): rotation about z of its x axis."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def odometry_of(time: float, msg: Any) -> Odometry:
    """An ``nav_msgs/Odometry`` message as :class:`Odometry`."""
    p = msg.pose.pose
    pose = np.array([p.position.x, p.position.y, yaw_of(p.orientation)], dtype=float)
    return Odometry(time, msg.header.frame_id, pose, float(msg.twist.twist.linear.x))


def joints_of(
    path: str | os.PathLike[str], topic: str, time: float, msg: Any, names: list[str]
) -> JointReading:
    """A ``sensor_msgs/JointState`` message's positions of the joints ``names``, in order.

    Raises:
        ConfigError: a joint missing from the message, or fewer positions than names.
    """
    have = list(msg.name)
    where = f"{topic} at {time:.3f} s"
    if len(msg.position) != len(have):
        raise ConfigError(
            path, "position", f"{where}: {len(msg.position)} positions, {len(have)} names"
        )
    missing = [n for n in names if n not in have]
    if missing:
        raise ConfigError(path, "name", f"{where}: no joint {missing[0]!r} (has {have})")
    q = np.array([msg.position[have.index(n)] for n in names], dtype=float)
    return JointReading(time, q)


def map_updates(
    path: str | os.PathLike[str],
    map_topic: str,
    odom_topic: str,
    counts: list[int] | None = None,
    joints: tuple[str, list[str]] | None = None,
) -> Iterator[MapUpdate]:
    """The recording's maps in receive order, each with the odometry known by then.

    Args:
        path: the recording (``.mcap``, ``.bag``, ROS 2 bag directory).
        map_topic: its ``grid_map_msgs/GridMap`` topic.
        odom_topic: its ``nav_msgs/Odometry`` topic.
        counts: if given, ``counts[0]`` counts the maps skipped before any odometry.
        joints: if given, the ``sensor_msgs/JointState`` topic and the arm's joint names.

    Raises:
        ConfigError: as :func:`mmstab.terrain.recording.messages`; a map and the odometry
            in different frames; a joint state without one of the arm's joints.
    """
    last: Odometry | None = None
    arm: JointReading | None = None
    topics: dict[str, str | tuple[str, ...]] = {map_topic: GRIDMAP, odom_topic: ODOMETRY}
    if joints is not None:
        topics[joints[0]] = JOINT_STATE
    with open_recording(path) as reader:
        recorded = {c.topic for c in reader.connections}
    tf = TransformBuffer()
    topics.update({name: TF_MESSAGE for name in TF_TOPICS if name in recorded})
    for m in messages(path, topics):
        if m.topic == odom_topic:
            last = odometry_of(m.time, m.message)
            continue
        if m.topic in TF_TOPICS:
            tf.add(m.message)
            continue
        if joints is not None and m.topic == joints[0]:
            arm = joints_of(path, m.topic, m.time, m.message, joints[1])
            continue
        if last is None:
            if counts is not None:
                counts[0] += 1
            continue
        grid = from_message(m.message, f"{path} [{map_topic} at {m.time:.3f} s]")
        odom = last
        if grid.frame_id != last.frame_id:
            T = tf.lookup(grid.frame_id, last.frame_id)
            if T is None:
                raise ConfigError(
                    path,
                    "frame_id",
                    f"map in {grid.frame_id!r} but odometry in {last.frame_id!r}, and no "
                    f"transform between them on {' or '.join(TF_TOPICS)} by {m.time:.3f} s",
                )
            pose = planar(T @ pose_matrix(last.pose))
            odom = Odometry(last.time, grid.frame_id, pose, last.speed)
        yield MapUpdate(m.time, grid, odom, arm)
