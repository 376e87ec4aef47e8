"""A recording as the robot lived it: each elevation map with the odometry received by then.

Odometry is ``nav_msgs/Odometry`` (its pose in the map's frame); the base pose the loop uses
is (x, y, yaw) of the last odometry message received before the map. A map that arrives
before any odometry is skipped (and counted). Times are from the recording's start [s].
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from typing import Any, NamedTuple

import numpy as np

from mmstab.core.files import ConfigError
from mmstab.model.robot import FloatArray
from mmstab.terrain.gridmap import GRIDMAP, GridMapFrame, from_message
from mmstab.terrain.recording import messages

ODOMETRY = "nav_msgs/msg/Odometry"


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


class MapUpdate(NamedTuple):
    """One map and the base pose the robot knew when it arrived.

    Attributes:
        time: the map's receive time from the recording's start [s].
        grid: the map (mmstab's layout).
        odometry: the last odometry received before it.
    """

    time: float
    grid: GridMapFrame
    odometry: Odometry


def yaw_of(q: Any) -> float:
    """Heading [rad] of a quaternion (x, y, z, w): rotation about z of its x axis."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def odometry_of(time: float, msg: Any) -> Odometry:
    """An ``nav_msgs/Odometry`` message as :class:`Odometry`."""
    p = msg.pose.pose
    pose = np.array([p.position.x, p.position.y, yaw_of(p.orientation)], dtype=float)
    return Odometry(time, msg.header.frame_id, pose, float(msg.twist.twist.linear.x))


def map_updates(
    path: str | os.PathLike[str], map_topic: str, odom_topic: str, counts: list[int] | None = None
) -> Iterator[MapUpdate]:
    """The recording's maps in receive order, each with the odometry known by then.

    Args:
        path: the recording (``.mcap``, ``.bag``, ROS 2 bag directory).
        map_topic: its ``grid_map_msgs/GridMap`` topic.
        odom_topic: its ``nav_msgs/Odometry`` topic.
        counts: if given, ``counts[0]`` counts the maps skipped before any odometry.

    Raises:
        ConfigError: as :func:`mmstab.terrain.recording.messages`; a map and the odometry
            in different frames.
    """
    last: Odometry | None = None
    for m in messages(path, {map_topic: GRIDMAP, odom_topic: ODOMETRY}):
        if m.topic == odom_topic:
            last = odometry_of(m.time, m.message)
            continue
        if last is None:
            if counts is not None:
                counts[0] += 1
            continue
        grid = from_message(m.message, f"{path} [{map_topic} at {m.time:.3f} s]")
        if grid.frame_id != last.frame_id:
            raise ConfigError(
                path,
                "frame_id",
                f"map in {grid.frame_id!r} but odometry in {last.frame_id!r} (no TF lookup)",
            )
        yield MapUpdate(m.time, grid, last)
