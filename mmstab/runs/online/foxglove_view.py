"""``mmstab node --foxglove``: the node's answers live in Foxglove (its WebSocket protocol).

A ``foxglove-sdk`` WebSocket server (``ws://127.0.0.1:8765`` by default; open it in
Foxglove with "Open connection") carries, per answer, the channels ``mmstab follow``'s
``online.mcap`` has where they fit (``mmstab.runs.recording.TOPICS``), in Foxglove's own
schemas:

* ``/tf`` (``foxglove.FrameTransforms``): ``base_link`` in the map's frame (the resting pose);
* ``/joint_states`` (``foxglove.JointStates``): the arm's posture;
* ``/mu`` (JSON ``{"data": μ}``): μ now [N rad] (NaN as null: not covered or stale);
* ``/support_polygon`` (``foxglove.SceneUpdate``): the support polygon coloured by μ (red at
  0, green at the stowed arm's μ on flat ground), the CoM, its projection and the tip axis;
  deleted when the answer is stale or the map does not cover the robot;
* ``/map`` (``foxglove.Grid``): the elevation map (NaN: unknown);
* ``/verdicts`` (JSON): each verdict's level and message, and the reason when stale.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from mmstab.core.problem import Problem
from mmstab.runs.online.live import LiveAnswer
from mmstab.runs.recording import joint_names, mu_colour
from mmstab.stability.static import mu_max
from mmstab.terrain.heightmap import Heightmap

BASE = "base_link"


def _time(t: float) -> Any:
    from foxglove.messages import Timestamp

    sec = int(math.floor(t))
    return Timestamp(sec=sec, nsec=min(int(round((t - sec) * 1e9)), 999_999_999))


def _point(p: Any) -> Any:
    from foxglove.messages import Point3

    return Point3(x=float(p[0]), y=float(p[1]), z=float(p[2]))


class FoxgloveView:
    """The live view's server and channels (module text).

    Args:
        problem: the node's problem (its robot).
        host: the address to serve on.
        port: the port [-].
    """

    def __init__(self, problem: Problem, host: str = "127.0.0.1", port: int = 8765) -> None:
        import foxglove
        from foxglove.channels import (
            FrameTransformsChannel,
            GridChannel,
            JointStatesChannel,
            SceneUpdateChannel,
        )

        self.context = ctx = foxglove.Context()
        self.server = foxglove.start_server(name="mmstab node", host=host, port=port, context=ctx)
        self.names = joint_names(problem.robot)
        self.mu_max = float(mu_max(problem.robot))
        self.tf = FrameTransformsChannel("/tf", context=ctx)
        self.joints = JointStatesChannel("/joint_states", context=ctx)
        self.mu = foxglove.Channel("/mu", context=ctx)
        self.support = SceneUpdateChannel("/support_polygon", context=ctx)
        self.map = GridChannel("/map", context=ctx)
        self.verdicts = foxglove.Channel("/verdicts", context=ctx)

    @property
    def port(self) -> int:
        """The port the server listens on."""
        return int(self.server.port)

    def answer(self, a: LiveAnswer) -> None:
        """Send one answer (module text)."""
        from foxglove.messages import (
            JointState,
            JointStates,
            SceneEntityDeletion,
            SceneEntityDeletionType,
            SceneUpdate,
        )

        ts = _time(a.stamp)
        log_time = int(a.stamp * 1e9)
        st = a.step
        mu = None if st is None or not math.isfinite(st.mu) else float(st.mu)
        self.mu.log({"data": mu}, log_time=log_time)
        self.verdicts.log(
            {
                "reason": a.reason,
                "verdicts": {v.name: {"level": v.level, "message": v.message} for v in a.verdicts},
            },
            log_time=log_time,
        )
        if a.heightmap is not None:
            self.map.log(grid_message(a.heightmap, a.frame_id, ts), log_time=log_time)
        if st is not None:
            self.joints.log(
                JointStates(
                    timestamp=ts,
                    joints=[
                        JointState(name=n, position=float(q))
                        for n, q in zip(self.names, st.q, strict=True)
                    ],
                ),
                log_time=log_time,
            )
        if a.scene is None or st is None:  # nothing to stand on: delete, never keep old
            self.support.log(
                SceneUpdate(
                    deletions=[SceneEntityDeletion(timestamp=ts, type=SceneEntityDeletionType.All)]
                ),
                log_time=log_time,
            )
            return
        self._tf(a, ts, log_time)
        self._support(a, ts, log_time)

    def _tf(self, a: LiveAnswer, ts: Any, log_time: int) -> None:
        """``base_link`` at the resting pose in the map's frame."""
        from foxglove.messages import FrameTransform, FrameTransforms, Quaternion, Vector3

        st = a.step
        assert st is not None
        T = st.G_T_B
        x, y, z, w = quaternion(T[:3, :3])
        self.tf.log(
            FrameTransforms(
                transforms=[
                    FrameTransform(
                        timestamp=ts,
                        parent_frame_id=a.frame_id,
                        child_frame_id=BASE,
                        translation=Vector3(x=T[0, 3], y=T[1, 3], z=T[2, 3]),
                        rotation=Quaternion(x=x, y=y, z=z, w=w),
                    )
                ]
            ),
            log_time=log_time,
        )

    def _support(self, a: LiveAnswer, ts: Any, log_time: int) -> None:
        """The support polygon coloured by μ, the CoM, its projection, the tip axis."""
        from foxglove.messages import (
            Color,
            LinePrimitive,
            LinePrimitiveLineType,
            Pose,
            Quaternion,
            SceneEntity,
            SceneUpdate,
            SpherePrimitive,
            Vector3,
        )

        st = a.step
        assert st is not None and a.scene is not None
        sc = a.scene
        r, g, b = mu_colour(float(st.mu), self.mu_max)
        closed = np.vstack([sc.polygon, sc.polygon[:1]])
        blue, magenta = Color(r=0.1, g=0.3, b=1.0, a=1.0), Color(r=1.0, g=0.0, b=1.0, a=1.0)
        origin = Pose(position=Vector3(x=0.0, y=0.0, z=0.0), orientation=Quaternion(w=1.0))

        def sphere(p: Any, d: float) -> Any:
            at = Pose(position=Vector3(x=p[0], y=p[1], z=p[2]), orientation=Quaternion(w=1.0))
            return SpherePrimitive(pose=at, size=Vector3(x=d, y=d, z=d), color=blue)

        entity = SceneEntity(
            timestamp=ts,
            frame_id=a.frame_id,
            id="support",
            lines=[
                LinePrimitive(
                    type=LinePrimitiveLineType.LineStrip, pose=origin, thickness=0.02,
                    points=[_point(p) for p in closed], color=Color(r=r, g=g, b=b, a=1.0),
                ),
                LinePrimitive(
                    type=LinePrimitiveLineType.LineList, pose=origin, thickness=0.03,
                    points=[_point(p) for p in sc.tip_axis], color=magenta,
                ),
            ],
            spheres=[sphere(sc.com, 0.06), sphere(sc.com_ground, 0.04)],
        )  # fmt: skip
        self.support.log(SceneUpdate(entities=[entity]), log_time=log_time)

    def stop(self) -> None:
        """Stop the server."""
        self.server.stop()


def quaternion(R: np.ndarray) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a rotation matrix (3, 3)."""
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(R).as_quat()
    return float(x), float(y), float(z), float(w)


def grid_message(hm: Heightmap, frame_id: str, ts: Any) -> Any:
    """A ``foxglove.Grid`` of the heightmap's elevation (float32, row = +y, column = +x)."""
    from foxglove.messages import (
        Grid,
        PackedElementField,
        PackedElementFieldNumericType,
        Pose,
        Quaternion,
        Vector2,
        Vector3,
    )

    ny, nx = hm.elevation.shape
    res = float(hm.resolution)
    corner = np.asarray(hm.origin, dtype=float) - res / 2  # the grid's corner, not a centre
    return Grid(
        timestamp=ts,
        frame_id=frame_id,
        pose=Pose(position=Vector3(x=corner[0], y=corner[1], z=0.0), orientation=Quaternion(w=1.0)),
        column_count=nx,
        cell_size=Vector2(x=res, y=res),
        row_stride=4 * nx,
        cell_stride=4,
        fields=[
            PackedElementField(
                name="elevation", offset=0, type=PackedElementFieldNumericType.Float32
            )
        ],
        data=np.ascontiguousarray(hm.elevation, dtype="<f4").tobytes(),
    )
