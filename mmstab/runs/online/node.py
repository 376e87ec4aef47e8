"""``mmstab node``: the online loop as a ROS 2 node on the robot's own topics.

Subscribes (names from the problem's ``online`` section, each a ROS parameter too):
``map_topic`` (``grid_map_msgs/GridMap``), ``odom_topic`` (``nav_msgs/Odometry``),
``joints_topic`` (``sensor_msgs/JointState``, when set: the arm's measured posture is the
controller's state and μ's), ``/tf`` and ``/tf_static`` (``tf2_msgs/TFMessage``). Answers
each map with :class:`~mmstab.runs.online.live.LiveFollower` (the step of ``mmstab
follow``) and publishes, each stamped with the map's stamp:

* ``arm_target_topic`` (``trajectory_msgs/JointTrajectory``): the planned posture the step
  steers toward (one point, the arm's joint names);
* ``command_topic`` (``std_msgs/Float64MultiArray``): the controller's joint speeds
  (tracks left, right, then the arm's joints) [rad/s], on every answer and again at
  ``control_rate`` [Hz] between maps; zeros while the answer is stale;
* ``diagnostics_topic`` (``diagnostic_msgs/DiagnosticArray``): ``mmstab: stability`` (μ,
  planned μ, tilt, progress, the posture and command, the loop's map-to-answer latency) and
  one status per verdict (tip, slide, step, high-centred, arm-contact, coverage), all STALE
  with the reason when the inputs are not fresh (:mod:`mmstab.runs.online.guard`);
* ``markers_topic`` (``visualization_msgs/MarkerArray``): the support polygon coloured by μ,
  the CoM, its projection on the support and the tip axis (all of the state's own support,
  the one its μ is computed on).

The queued re-plans and the moves ahead run after the answer is published (the map's
spare time, :meth:`~mmstab.runs.online.follow.Follower.spare`): the answer waits for
nothing it does not need.

Run through :func:`~mmstab.runs.online.rosenv.ensure_ros_env` (the CLI does), as rclpy
needs its libraries set before the process starts.
"""

from __future__ import annotations

import gc
import re
import time
from typing import Any

import numpy as np

from mmstab.core.problem import Problem
from mmstab.planner.plan import unfreeze_long_lived
from mmstab.runs.online.follow import FollowSettings, build_follower
from mmstab.runs.online.guard import VERDICTS, GuardSettings
from mmstab.runs.online.live import LiveAnswer, LiveFollower
from mmstab.runs.online.rosenv import NodeTopics, time_msg
from mmstab.runs.recording import joint_names, mu_colour
from mmstab.runs.verdict import planner_margin
from mmstab.stability.static import mu_max

#: Names of the command's entries before the arm's joints.
TRACKS = ("track_left", "track_right")


def reason_key(reason: str) -> str:
    """A reason without its numbers: the same fault logged once, whatever its age."""
    return re.sub(r"-?[0-9][0-9.e+-]*", "#", reason)


class MmstabNode:
    """The node (module text); ``spin`` runs it until shutdown.

    Args:
        problem: a route problem.
        args: ROS arguments (``--ros-args -p name:=value ...``).
        view: the live Foxglove view to feed (None: none).
    """

    def __init__(self, problem: Problem, args: list[str] | None = None, view: Any = None) -> None:
        import rclpy
        from rclpy.node import Node

        rclpy.init(args=args)
        self.node = node = Node("mmstab")
        s = FollowSettings.of(problem)
        p = GuardSettings()
        defaults = {
            "map_topic": s.map_topic,
            "odom_topic": s.odom_topic,
            "joints_topic": s.joints_topic or "",
            **{k: v for k, v in NodeTopics("", "", "")._asdict().items() if k.endswith("_topic")
               and k not in ("map_topic", "odom_topic", "joints_topic")},
            "max_map_age": p.max_map_age,
            "odom_timeout": p.odom_timeout,
            "odom_wait": p.odom_wait,
            "log_period": p.log_period,
            "control_rate": 50.0,
        }  # fmt: skip
        values = {k: node.declare_parameter(k, v).value for k, v in defaults.items()}
        self.topics = NodeTopics(*(str(values[k]) for k in NodeTopics._fields))
        guard = GuardSettings(*(float(values[k]) for k in GuardSettings._fields))
        self.names = joint_names(problem.robot)
        node.get_logger().info("building the online loop (V, roadmap, controller) ...")
        follower = build_follower(problem)
        margin = planner_margin(problem.section("planner"))
        wants = bool(self.topics.joints_topic)
        self.live = LiveFollower(follower, guard, self.names, margin, wants)
        self.live.on_step = self._on_step
        self.step_published = float("nan")
        self.map_received = float("nan")
        self.mu_max = float(mu_max(problem.robot))
        self.view = view
        self.command = np.zeros(len(TRACKS) + len(self.names))
        self.fresh = False
        self.answers = 0
        self.maps_received = 0
        self._publishers()
        self._subscriptions()
        node.create_timer(1.0 / float(values["control_rate"]), self._tick)
        # the set-up's objects (V, the roadmap, CasADi's) out of the collector's full passes,
        # as in ``follow``: one pass over them takes tens of ms of a map's answer
        gc.collect()
        gc.freeze()
        node.get_logger().info(
            f"answering maps on {self.topics.map_topic} (odometry {self.topics.odom_topic}"
            + (f", joints {self.topics.joints_topic}" if self.topics.joints_topic else "")
            + ")"
        )

    # ------------------------------------------------------------------ wiring
    def _publishers(self) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from std_msgs.msg import Float64MultiArray
        from trajectory_msgs.msg import JointTrajectory
        from visualization_msgs.msg import MarkerArray

        n, t = self.node, self.topics
        self.pub_target = n.create_publisher(JointTrajectory, t.arm_target_topic, 10)
        self.pub_command = n.create_publisher(Float64MultiArray, t.command_topic, 10)
        self.pub_diag = n.create_publisher(DiagnosticArray, t.diagnostics_topic, 10)
        self.pub_markers = n.create_publisher(MarkerArray, t.markers_topic, 10)

    def _subscriptions(self) -> None:
        from grid_map_msgs.msg import GridMap
        from nav_msgs.msg import Odometry
        from rclpy.qos import DurabilityPolicy, QoSProfile
        from sensor_msgs.msg import JointState
        from tf2_msgs.msg import TFMessage

        n, t = self.node, self.topics
        n.create_subscription(GridMap, t.map_topic, self._on_map, 10)
        n.create_subscription(Odometry, t.odom_topic, self._on_odom, 100)
        if t.joints_topic:
            n.create_subscription(
                JointState, t.joints_topic, lambda m: self.live.on_joints(m, t.joints_topic), 100
            )
        n.create_subscription(TFMessage, "/tf", self.live.on_tf, 100)
        static = QoSProfile(depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        n.create_subscription(TFMessage, "/tf_static", self.live.on_tf, static)

    def _on_odom(self, msg: Any) -> None:
        self.live.on_odometry(msg)
        self._guarded(lambda: self.live.poll(time.time()))

    def _on_map(self, msg: Any) -> None:
        self.maps_received += 1
        self.map_received = time.time()
        self._guarded(lambda: self.live.on_map(msg, time.time()))

    def _guarded(self, answer: Any) -> None:
        """Emit ``answer()``'s answers; an error in the loop is a stale answer, not a crash."""
        try:
            answers = answer()
        except Exception as e:  # the node keeps running, whatever one map did
            self.live.pending.clear()
            why = f"error in the update: {type(e).__name__}: {e}"
            self.node.get_logger().error(why)
            answers = [self.live._stale(time.time(), "", why)]
        self._emit(answers)
        if any(a.step is not None for a in answers):  # the re-plans wait for the answer
            self._guarded_spare()

    def _guarded_spare(self) -> None:
        try:
            self.live.spare()
        except Exception as e:  # as an update's error: logged, the next map answers anew
            self.node.get_logger().error(f"error in the spare time: {type(e).__name__}: {e}")

    def _tick(self) -> None:
        now = time.time()
        self._guarded(lambda: self.live.poll(now))
        stale = self.live.watchdog(now)
        if stale is not None:
            self._emit([stale])
        self._publish_command(None)

    # ------------------------------------------------------------------ answers
    def _emit(self, answers: list[LiveAnswer]) -> None:
        for a in answers:
            self.answers += 1
            log = self.node.get_logger()
            if a.reason is not None or a.step is None:
                if a.reason is not None and self.live.log.say(reason_key(a.reason), time.time()):
                    log.warning(f"stale answer: {a.reason}")
                self.fresh = False
                self.command = np.zeros_like(self.command)
            else:
                for gone in self.live.log.clear():
                    log.info(f"fresh again (was: {gone})")
            if a.step is None:  # stale: the arm stops (a fresh one was sent by _on_step)
                self._publish_command(a.stamp)
            self._publish_diagnostics(a)
            self._publish_markers(a)
            if self.view is not None:
                self.view.answer(a)

    def _publish_command(self, stamp: float | None) -> None:
        from std_msgs.msg import Float64MultiArray, MultiArrayDimension, MultiArrayLayout

        dim = MultiArrayDimension(
            label=",".join([*TRACKS, *self.names]), size=len(self.command), stride=len(self.command)
        )
        cmd = self.command if self.fresh else np.zeros_like(self.command)
        self.pub_command.publish(
            Float64MultiArray(layout=MultiArrayLayout(dim=[dim]), data=cmd.tolist())
        )

    def _on_step(self, stamp: float, frame: str, qdot: Any, q_ref: Any) -> None:
        """The loop's step: the command and the arm's target out at once, verdicts after."""
        self.fresh = True
        self.command = np.asarray(qdot, dtype=float)
        self._publish_command(stamp)
        if q_ref is not None:
            self._publish_target(stamp, frame, q_ref)
        self.step_published = time.time()

    def _publish_target(self, stamp: float, frame: str, q: Any) -> None:
        from builtin_interfaces.msg import Duration
        from std_msgs.msg import Header
        from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

        point = JointTrajectoryPoint(
            positions=[float(x) for x in q], time_from_start=Duration(sec=0, nanosec=100_000_000)
        )
        self.pub_target.publish(
            JointTrajectory(
                header=Header(stamp=time_msg(stamp), frame_id=frame),
                joint_names=self.names,
                points=[point],
            )
        )

    def _publish_diagnostics(self, a: LiveAnswer) -> None:
        from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
        from std_msgs.msg import Header

        def kv(k: str, v: Any) -> Any:
            return KeyValue(key=k, value=str(v))

        values = [
            kv("map_stamp", f"{a.stamp:.9f}"),
            kv("answered", f"{time.time():.9f}"),
            kv("source", "watchdog" if a.watchdog else "map"),
            kv("maps_received", self.maps_received),
        ]
        if a.step is not None:
            st = a.step
            values += [
                kv("mu", repr(float(st.mu))),
                kv("mu_planned", repr(float(st.mu_planned))),
                kv("tilt", repr(float(st.tilt))),
                kv("s", repr(float(st.s))),
                kv("covered", st.covered),
                kv("measured", st.measured),
                kv("status", st.status),
                kv("q", " ".join(repr(float(x)) for x in st.q)),
                kv("qdot", " ".join(repr(float(x)) for x in st.qdot)),
                kv("latency_ms", f"{st.latency * 1e3:.3f}"),
                kv("cpu_ms", f"{self.live.follower.cpu_time * 1e3:.3f}"),
                kv("command_published", f"{self.step_published:.9f}"),
                kv("map_received", f"{self.map_received:.9f}"),
            ]
        worst = max(v.level for v in a.verdicts)
        head = DiagnosticStatus(
            level=bytes([worst]),
            name="mmstab: stability",
            message=a.reason or ("stable" if worst == 0 else "see the verdicts"),
            hardware_id="mmstab",
            values=values,
        )
        status = [head] + [
            DiagnosticStatus(
                level=bytes([v.level]),
                name=f"mmstab: {v.name}",
                message=v.message,
                hardware_id="mmstab",
            )  # fmt: skip
            for v in a.verdicts
        ]
        assert [v.name for v in a.verdicts] == list(VERDICTS)
        self.pub_diag.publish(
            DiagnosticArray(header=Header(stamp=time_msg(a.stamp)), status=status)
        )

    def _publish_markers(self, a: LiveAnswer) -> None:
        from builtin_interfaces.msg import Duration
        from geometry_msgs.msg import Point, Vector3
        from std_msgs.msg import ColorRGBA, Header
        from visualization_msgs.msg import Marker, MarkerArray

        header = Header(stamp=time_msg(a.stamp), frame_id=a.frame_id)
        if a.scene is None or a.step is None:  # stale or not covered: nothing to stand on
            self.pub_markers.publish(MarkerArray(markers=[Marker(header=header, action=3)]))
            return
        sc = a.scene
        r, g, b = mu_colour(float(a.step.mu), self.mu_max)

        def marker(i: int, kind: int, pts: np.ndarray, scale: float, rgb: tuple) -> Any:
            return Marker(
                header=header, ns="mmstab", id=i, type=kind, action=0,
                scale=Vector3(x=scale, y=scale, z=scale),
                color=ColorRGBA(r=float(rgb[0]), g=float(rgb[1]), b=float(rgb[2]), a=1.0),
                points=[Point(x=float(p[0]), y=float(p[1]), z=float(p[2])) for p in pts],
                lifetime=Duration(sec=1, nanosec=0),
            )  # fmt: skip

        closed = np.vstack([sc.polygon, sc.polygon[:1]])
        self.pub_markers.publish(
            MarkerArray(
                markers=[
                    marker(0, Marker.LINE_STRIP, closed, 0.02, (r, g, b)),
                    marker(1, Marker.SPHERE_LIST, sc.com[None], 0.06, (0.1, 0.3, 1.0)),
                    marker(2, Marker.SPHERE_LIST, sc.com_ground[None], 0.04, (0.1, 0.3, 1.0)),
                    marker(3, Marker.LINE_LIST, sc.tip_axis, 0.03, (1.0, 0.0, 1.0)),
                ]
            )
        )

    def spin(self) -> None:
        """Answer maps until Ctrl-C or shutdown."""
        import rclpy

        try:
            rclpy.spin(self.node)
        except KeyboardInterrupt:
            pass
        finally:
            self.node.destroy_node()
            if rclpy.ok():
                rclpy.shutdown()
            unfreeze_long_lived()
