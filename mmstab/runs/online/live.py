"""The online loop fed live, message by message (what ``mmstab node`` runs, without ROS).

:class:`LiveFollower` takes the robot's messages as they arrive (GridMap, Odometry,
JointState, TFMessage: ROS 2's message objects, or ``rosbags``' that have the same fields)
with the wall clock, and answers each map with :meth:`Follower.update
<mmstab.runs.online.follow.Follower.update>`, the step ``mmstab follow`` runs on a
recording. What it adds is the live part:

* the odometry of a map is the newest one **stamped** at or before the map's stamp (a
  recording's order is its stamps' order; live, the two topics race), waiting at most
  ``odom_wait`` for it; so is the arm's measured joint state (``joints_topic``), which is
  then the controller's state and μ's posture; without joint states the arm's posture is
  the loop's own integration, as in ``follow``;
* the times the loop sees are the map stamps from the first map's (so the controller's
  period is the time between map stamps, as ``follow`` has it from a recording);
* the guard (:mod:`mmstab.runs.online.guard`): a stale, malformed or unjoinable input gives
  a stale answer with its reason, never the last safe one.

Each answer also carries the verdicts (:func:`~mmstab.runs.online.guard.verdicts`) and the
scene (:class:`Scene`: support polygon, CoM, its projection, the tip axis) the node
publishes.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from mmstab.core.files import ConfigError
from mmstab.model.robot import FloatArray
from mmstab.runs.online.follow import Follower, FollowStep
from mmstab.runs.online.frames import TransformBuffer, planar, pose_matrix
from mmstab.runs.online.guard import (
    UNMAPPED,
    GuardSettings,
    ReasonLog,
    Verdict,
    map_fault,
    stale_verdicts,
    verdicts,
)
from mmstab.runs.online.rosenv import stamp_of
from mmstab.runs.online.stream import JointReading, MapUpdate, Odometry, joints_of, odometry_of
from mmstab.stability.climb import climb_limit
from mmstab.stability.static import axis_angles
from mmstab.terrain.base import GRAVITY_G
from mmstab.terrain.gridmap import from_message
from mmstab.terrain.heightmap import Heightmap, OffMapError
from mmstab.terrain.heightmap_terrain import HeightmapTerrain

#: Odometry and joint states kept to pick the one of a map's stamp [messages].
BUFFER = 200


class Scene(NamedTuple):
    """What the robot stands on, in the map frame [m].

    Attributes:
        polygon: the support polygon's vertices (m, 3).
        com: the overall CoM (3,).
        com_ground: the CoM projected along gravity onto the support's plane (3,).
        tip_axis: the polygon edge of the smallest force angle, its two ends (2, 3) (a line
            support: its ends; none: (0, 3)).
    """

    polygon: FloatArray
    com: FloatArray
    com_ground: FloatArray
    tip_axis: FloatArray


class LiveAnswer(NamedTuple):
    """The answer to one map (or the watchdog's).

    Attributes:
        stamp: the map's header stamp [s] (the watchdog's: its wall time).
        frame_id: the map's frame.
        step: the loop's step (None: stale).
        verdicts: the verdicts (all STALE when stale).
        reason: why it is stale (None: fresh).
        scene: the support and CoM (None: stale or not covered).
        watchdog: the watchdog's answer (no map for a while), not a map's.
        heightmap: the map as the loop read it (None: stale).
    """

    stamp: float
    frame_id: str
    step: FollowStep | None
    verdicts: list[Verdict]
    reason: str | None
    scene: Scene | None
    watchdog: bool = False
    heightmap: Heightmap | None = None


class LiveFollower:
    """The loop's state between live messages (module text).

    Args:
        follower: the online loop (:func:`~mmstab.runs.online.follow.build_follower`).
        guard: the freshness limits.
        joint_names: the arm's joint names, in its order (those of ``mmstab urdf``).
        margin: μ below it tips [N rad].
        wants_joints: a map also waits (``odom_wait`` at most) for the joint state of its
            stamp (a joint state topic is subscribed).
    """

    def __init__(
        self,
        follower: Follower,
        guard: GuardSettings,
        joint_names: list[str],
        margin: float,
        wants_joints: bool = False,
    ) -> None:
        self.follower, self.guard, self.names, self.margin = follower, guard, joint_names, margin
        self.wants_joints = wants_joints
        self.robot = follower.robot
        self.odom: deque[tuple[float, Odometry]] = deque(maxlen=BUFFER)
        self.joints: deque[tuple[float, JointReading]] = deque(maxlen=BUFFER)
        self.tf = TransformBuffer()
        self.t0: float | None = None  # the first map's stamp: the loop's time base
        self.last_stamp: float | None = None
        self.last_map_wall: float | None = None
        self.last_watchdog: float | None = None
        #: maps waiting for their odometry, in arrival order: (map, stamp, deadline)
        self.pending: deque[tuple[Any, float, float]] = deque()
        self.fault: str | None = None  # an input's fault since the last map
        self.log = ReasonLog(guard.log_period)
        #: called with (stamp [s], frame, command [rad/s], planned posture [rad] or None) as
        #: soon as the loop's step has them, before the verdicts: the node publishes there
        self.on_step: Callable[[float, str, FloatArray, FloatArray | None], None] | None = None

    # ------------------------------------------------------------------ inputs
    def on_odometry(self, msg: Any) -> None:
        """Keep an ``nav_msgs/Odometry`` (a NaN pose is a fault, not kept)."""
        t = stamp_of(msg)
        odom = odometry_of(t, msg)
        if not np.isfinite(odom.pose).all():
            self.fault = f"malformed odometry at {t:.3f} s: pose {odom.pose.tolist()}"
            return
        self.odom.append((t, odom))

    def on_joints(self, msg: Any, topic: str) -> None:
        """Keep a ``sensor_msgs/JointState`` as the arm's measured posture."""
        t = stamp_of(msg)
        try:
            reading = joints_of(topic, topic, t, msg, self.names)
        except ConfigError as e:
            self.fault = f"malformed joint state: {e}"
            return
        self.joints.append((t, reading))

    def on_tf(self, msg: Any) -> None:
        """Keep a ``tf2_msgs/TFMessage``'s transforms (the latest of each pair)."""
        self.tf.add(msg)

    def on_map(self, msg: Any, now: float) -> list[LiveAnswer]:
        """A ``grid_map_msgs/GridMap`` arrived at wall time ``now`` [s]: answers due now.

        A map waits (behind the maps already waiting) until the odometry of its stamp has
        arrived or ``odom_wait`` is over: a busy node's callbacks may take the next map
        before the odometry received before it.
        """
        self.last_map_wall = now
        try:
            stamp = stamp_of(msg)
        except (AttributeError, TypeError) as e:
            return [self._stale(0.0, "", f"malformed map: no header stamp ({e})")]
        if now - stamp > self.guard.max_map_age:  # old: stale, whatever came before it
            return [self._answer(msg, stamp, now)]
        if self.last_stamp is not None and stamp <= self.last_stamp:
            out = self.flush(now)
            self._restart()
            self.last_stamp = stamp
            return [
                *out,
                self._stale(stamp, _frame(msg), "map stamp went back: publisher restarted"),
            ]
        self.last_stamp = stamp
        self.pending.append((msg, stamp, now + self.guard.odom_wait))
        return self.poll(now)

    def spare(self) -> float:
        """The last answered map's spare time (:meth:`Follower.spare`), once its answer is out.

        Returns its wall time [s] (0 when there is nothing to do).
        """
        return self.follower.spare()

    def _ready(self, stamp: float) -> bool:
        """The odometry (and joint state) of the map's stamp have arrived."""
        if not self.odom or self.odom[-1][0] < stamp:
            return False
        return not self.wants_joints or (bool(self.joints) and self.joints[-1][0] >= stamp)

    def poll(self, now: float) -> list[LiveAnswer]:
        """Answer the waiting maps, in order, whose odometry arrived or whose wait is over."""
        out = []
        while self.pending:
            msg, stamp, deadline = self.pending[0]
            if not (self._ready(stamp) or now >= deadline):
                break
            self.pending.popleft()
            out.append(self._answer(msg, stamp, now))
        return out

    def flush(self, now: float) -> list[LiveAnswer]:
        """Answer every waiting map with what has arrived."""
        out = []
        while self.pending:
            msg, stamp, _ = self.pending.popleft()
            out.append(self._answer(msg, stamp, now))
        return out

    def watchdog(self, now: float) -> LiveAnswer | None:
        """A stale answer when no map came for ``max_map_age`` of wall time, else None.

        Given at most once every ``max_map_age`` [s] while no map comes.
        """
        if self.pending:
            return None
        since = None if self.last_map_wall is None else now - self.last_map_wall
        if since is not None and since <= self.guard.max_map_age:
            return None
        if self.last_watchdog is not None and now - self.last_watchdog < self.guard.max_map_age:
            return None
        self.last_watchdog = now
        why = "no map received" if since is None else f"no map for {since:.2f} s"
        return self._stale(now, "", why)._replace(watchdog=True)

    # ------------------------------------------------------------------ answers
    def _restart(self) -> None:
        """The inputs' clock went back: what was received before is of another run."""
        self.odom.clear()
        self.joints.clear()
        self.tf = TransformBuffer()
        self.t0 = None
        self.follower.last_time = None
        self.follower.s = None
        self.pending.clear()

    def _stale(self, stamp: float, frame: str, reason: str) -> LiveAnswer:
        return LiveAnswer(stamp, frame, None, stale_verdicts(reason), reason, None)

    def _answer(self, msg: Any, stamp: float, now: float) -> LiveAnswer:
        frame = _frame(msg)
        if self.fault is not None:
            fault, self.fault = self.fault, None
            return self._stale(stamp, frame, fault)
        why = map_fault(self.guard, now, stamp, self.odom[-1][0] if self.odom else None)
        if why is not None:
            return self._stale(stamp, frame, why)
        odom = _at(self.odom, stamp)
        if odom is None:
            return self._stale(stamp, frame, "no odometry stamped at or before the map")
        try:
            grid = from_message(msg, f"map at {stamp:.3f} s")
        except (ConfigError, AttributeError, ValueError, TypeError, IndexError) as e:
            return self._stale(stamp, frame, f"malformed map: {e}")
        if grid.frame_id != odom.frame_id:
            T = self.tf.lookup(grid.frame_id, odom.frame_id)
            if T is None:
                return self._stale(
                    stamp,
                    frame,
                    f"no transform from {odom.frame_id!r} to the map's {grid.frame_id!r}",
                )
            odom = Odometry(
                odom.time, grid.frame_id, planar(T @ pose_matrix(odom.pose)), odom.speed
            )
        if self.t0 is None:
            self.t0 = stamp
        base = self.t0
        odom = odom._replace(time=odom.time - base)
        joints = _at(self.joints, stamp)
        if joints is not None:
            joints = joints._replace(time=joints.time - base)
        if self.on_step is not None:
            hook = self.on_step
            self.follower.on_command = lambda qdot, q_ref: hook(stamp, frame, qdot, q_ref)
        step = self.follower.update(MapUpdate(stamp - base, grid, odom, joints))
        self.follower.on_command = None
        stalls: bool | str | None = None
        scene = None
        if step.covered:
            terrain = HeightmapTerrain(grid.heightmap, friction=self.follower.friction)
            stalls = self._stalls(terrain.with_robot(self.robot), step)
            scene = self.scene(step)
        v = verdicts(
            step.covered, step.mu, self.margin, step.tilt, self.follower.friction, stalls,
            "high_centred" in step.flags, step.arm_height,
        )  # fmt: skip
        return LiveAnswer(stamp, frame, step, v, None, scene, heightmap=grid.heightmap)

    def _stalls(self, terrain: HeightmapTerrain, step: FollowStep) -> bool | str | None:
        """The step ahead within the route's planned spacing: can the tracks climb it?

        :data:`~mmstab.runs.online.guard.UNMAPPED` when the ground ahead is not on the map.
        """
        lookahead = self.follower._spacing()
        try:
            lim = climb_limit(
                self.robot, terrain, step.pose[None], self.follower.friction, lookahead
            )
        except OffMapError:
            return UNMAPPED
        if not bool(lim.step[0]):
            return None
        com = self.robot.overall_com(np.asarray(self.robot.arm_com(step.q), dtype=float))
        return not bool(np.asarray(lim.climbs(com[None]))[0])

    def scene(self, step: FollowStep) -> Scene:
        """The support polygon, CoM, its projection and the tip axis in the map frame.

        All of the state's own support (its rest under its overall CoM, the contacts that
        carry the load): the tip axis is that polygon's edge of the smallest force angle
        under m g, the edge that sets the step's μ.
        """
        robot = self.robot
        arm_com = np.asarray(robot.arm_com(step.q), dtype=float)
        com_body = np.asarray(robot.overall_com(arm_com), dtype=float).reshape(3)
        T = step.G_T_B
        com = T[:3, :3] @ com_body + T[:3, 3]
        poly = step.polygon
        centre = poly.mean(axis=0) if len(poly) else T[:3, 3]
        n = T[:3, 2]
        drop = float(np.dot(com - centre, n) / n[2]) if abs(n[2]) > 1e-9 else 0.0
        ground = com - np.array([0.0, 0.0, drop])
        if len(poly) >= 3:
            theta = axis_angles(poly, com, robot.total_mass * GRAVITY_G)
            j = int(np.argmin(theta))
            axis = poly[[j, (j + 1) % len(poly)]]
        else:  # a line (its two ends) or no support
            axis = poly[:2].copy()
        return Scene(poly, com, ground, axis)


def _frame(msg: Any) -> str:
    try:
        return str(msg.header.frame_id)
    except AttributeError:
        return ""


def _at(buffer: deque[tuple[float, Any]], stamp: float) -> Any:
    """The newest entry stamped at or before ``stamp`` (None: none)."""
    for t, item in reversed(buffer):
        if t <= stamp + 1e-9:
            return item
    return None
