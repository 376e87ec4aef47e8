"""TF in a recording: the transform between the map's frame and the odometry's.

An elevation map is often published in another frame than the odometry (``map`` against
``odom``). The recording's ``tf2_msgs/TFMessage`` topics (``/tf``, and ``/tf_static`` whose
transforms never expire) give the transforms between frames; :class:`TransformBuffer` keeps
the latest of each parent/child pair and looks a transform up along the chain of frames
that joins two frames, as ``tf2`` does (without interpolation in time: the latest received
before the map). The base pose (x, y, yaw) in the odometry frame then becomes the base pose
in the map's frame, its heading the yaw of the composed rotation.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from mmstab.model.robot import FloatArray

TF_MESSAGE = "tf2_msgs/msg/TFMessage"
#: The TF topics read when the map and the odometry are in different frames.
TF_TOPICS = ("/tf", "/tf_static")


def matrix_of(transform: Any) -> FloatArray:
    """A ``geometry_msgs/Transform`` as a 4x4 matrix ``parent_T_child``."""
    r, p = transform.rotation, transform.translation
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat([r.x, r.y, r.z, r.w]).as_matrix()
    T[:3, 3] = [p.x, p.y, p.z]
    return T


def planar(T: FloatArray) -> FloatArray:
    """(x [m], y [m], yaw [rad]) of a 4x4 pose: its origin and the heading of its x axis."""
    return np.array([T[0, 3], T[1, 3], math.atan2(T[1, 0], T[0, 0])])


def pose_matrix(pose: FloatArray) -> FloatArray:
    """A planar pose (x [m], y [m], yaw [rad]) as a 4x4 matrix."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:2, 3] = pose[:2]
    return T


class TransformBuffer:
    """The latest transform of each parent -> child pair seen so far."""

    def __init__(self) -> None:
        self.edges: dict[tuple[str, str], FloatArray] = {}

    def add(self, message: Any) -> None:
        """Take a ``tf2_msgs/TFMessage``'s transforms (frame names without a leading '/')."""
        for ts in message.transforms:
            parent, child = ts.header.frame_id.lstrip("/"), ts.child_frame_id.lstrip("/")
            self.edges[(parent, child)] = matrix_of(ts.transform)

    def lookup(self, target: str, source: str) -> FloatArray | None:
        """``target_T_source`` (4, 4) along the frames' chain, or None if they are not joined."""
        target, source = target.lstrip("/"), source.lstrip("/")
        if target == source:
            return np.eye(4)
        links: dict[str, list[tuple[str, FloatArray]]] = {}
        for (parent, child), T in self.edges.items():  # both ways: T and its inverse
            links.setdefault(parent, []).append((child, T))
            links.setdefault(child, []).append((parent, np.asarray(np.linalg.inv(T), float)))
        seen = {target: np.eye(4)}  # frame -> target_T_frame
        todo = deque([target])
        while todo:
            frame = todo.popleft()
            for nxt, T in links.get(frame, []):
                if nxt not in seen:
                    seen[nxt] = seen[frame] @ T
                    if nxt == source:
                        return seen[nxt]
                    todo.append(nxt)
        return None
