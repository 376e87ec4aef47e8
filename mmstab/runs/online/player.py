"""``mmstab play``: a recording played onto ROS 2 topics, as the robot would publish it.

Every message of the recording's topics is published at its recorded time from now
(``rate`` times faster), its header stamps moved to now (the map's, the odometry's, each
transform's), so a node sees live data. The player waits until a node subscribes to the
map topic. With ``answers``, it also records what ``mmstab node`` answers (its
``DiagnosticArray`` and ``JointTrajectory``) as JSON lines, the map stamps given back in
the recording's time: what the tests and ``benchmarks/node_latency.py`` read.

``faults`` (``NAME@T``, T [s] of the recording) break the stream the ways a robot does, to
see the node's guard (:mod:`mmstab.runs.online.guard`) at work:

* ``odom-stops@T``: no odometry (nor TF) from T on;
* ``no-transform@T``: maps from T on are in frame ``elsewhere``, which no transform joins;
* ``old-map@T``: maps from T on are stamped 2 s in the past;
* ``malformed@T``: maps from T on have an elevation layer of the wrong size;
* ``restart@T``: at T the publishers restart (destroyed and created again) with a clock
  ``RESTART_BACK`` behind: their stamps go back.
"""

from __future__ import annotations

import importlib
import json
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from mmstab.core.files import ConfigError
from mmstab.runs.online.rosenv import NodeTopics, stamp_of, time_msg
from mmstab.terrain.recording import open_recording

FAULTS = ("odom-stops", "no-transform", "old-map", "malformed", "restart")
#: How long the player waits for a node to subscribe [s], and for the last answers [s].
WAIT_NODE, WAIT_ANSWERS = 120.0, 10.0
#: How far a restarted publisher's clock is behind [s].
RESTART_BACK = 0.3


def parse_faults(items: list[str]) -> dict[str, float]:
    """``NAME@T`` items as {name: T [s]}.

    Raises:
        ConfigError: an unknown name or a time that is not a number.
    """
    out = {}
    for item in items:
        name, _, t = item.partition("@")
        if name not in FAULTS:
            raise ConfigError("--fault", "name", f"{name!r}: one of {', '.join(FAULTS)}")
        try:
            out[name] = float(t)
        except ValueError:
            raise ConfigError("--fault", name, f"{t!r}: a time [s] after '@'") from None
    return out


def message_class(msgtype: str) -> Any:
    """The rclpy class of ``pkg/msg/Name``."""
    pkg, _, name = msgtype.split("/")
    return getattr(importlib.import_module(f"{pkg}.msg"), name)


def _restamp(msg: Any, shift: float) -> None:
    if hasattr(msg, "header"):
        msg.header.stamp = time_msg(stamp_of(msg) + shift)
    for ts in getattr(msg, "transforms", []):
        ts.header.stamp = time_msg(stamp_of(ts) + shift)


def play(
    path: str | os.PathLike[str],
    topics: NodeTopics,
    rate: float = 1.0,
    faults: dict[str, float] | None = None,
    answers: str | os.PathLike[str] | None = None,
    limit: int | None = None,
) -> dict[str, Any]:
    """Play the recording (module text); returns counts (maps, messages, answers).

    Args:
        path: ``.mcap``, ``.bag`` or a ROS 2 bag folder.
        topics: the node's topics (the map, odometry and joint topics are played, with /tf
            and /tf_static when recorded; the answers read from the others).
        rate: playback speed (1 = real time).
        faults: ``{name: T [s]}`` (module text).
        answers: write the node's answers here (JSON lines).
        limit: play only up to the ``limit``-th map.
    """
    import rclpy

    rclpy.init()
    try:
        player = Player(topics, faults or {}, answers is not None)
        with open_recording(path) as reader:
            maps, sent = player.run(reader, Path(path), rate, limit)
        player.collect(maps)
        player.node.destroy_node()
    finally:
        rclpy.shutdown()
    if answers is not None:
        Path(answers).write_text("".join(json.dumps(a) + "\n" for a in player.got))
    return {"maps": maps, "messages": sent, "answers": player.answered() if answers else None}


class Player:
    """The player's node: publishers of the recording's topics, the answers' subscriptions.

    Args:
        topics: the node's topics.
        faults: ``{name: T [s]}`` (module text).
        listen: read the node's answers back.
    """

    def __init__(self, topics: NodeTopics, faults: dict[str, float], listen: bool) -> None:
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from trajectory_msgs.msg import JointTrajectory

        self.topics, self.faults, self.listen = topics, faults, listen
        self._conns: list[Any] = []
        self.node = rclpy.create_node("mmstab_play")
        self.got: list[dict[str, Any]] = []
        self.shift = 0.0  # recorded stamps -> now [s], of the last map published
        self.pubs: dict[str, tuple[Any, Any]] = {}
        if listen:
            n = self.node
            n.create_subscription(DiagnosticArray, topics.diagnostics_topic, self._diag, 1000)
            n.create_subscription(JointTrajectory, topics.arm_target_topic, self._target, 1000)

    def _diag(self, msg: Any) -> None:
        head = next((s for s in msg.status if s.name == "mmstab: stability"), None)
        if head is None:
            return
        values = {kv.key: kv.value for kv in head.values}
        self.got.append({
            "kind": "diagnostics",
            "received": time.time(),
            "stamp": float(values["map_stamp"]) - self.shift,
            "abs_stamp": float(values["map_stamp"]),
            "levels": {s.name.removeprefix("mmstab: "): s.level[0] for s in msg.status},
            "message": head.message,
            "source": values.get("source", "map"),
            "values": values,
        })  # fmt: skip

    def _target(self, msg: Any) -> None:
        self.got.append({
            "kind": "arm_target", "received": time.time(),
            "stamp": stamp_of(msg) - self.shift,
            "positions": [float(x) for x in msg.points[0].positions],
        })  # fmt: skip

    def answered(self) -> int:
        """The node's answers to maps read back so far."""
        return sum(a["kind"] == "diagnostics" and a["source"] == "map" for a in self.got)

    def _advertise(self, conns: list[Any]) -> None:
        from rclpy.qos import DurabilityPolicy, QoSProfile

        for c in conns:
            if c.topic in self.pubs:
                continue
            qos: Any = 100
            if c.topic == "/tf_static":
                qos = QoSProfile(depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL)
            self.pubs[c.topic] = (
                self.node.create_publisher(message_class(c.msgtype), c.topic, qos),
                c,
            )

    def _wait_for_node(self, limit: float, others: bool = True) -> None:
        """Until a node subscribes to the map (``limit`` [s]), then its other topics (2 s)."""
        import rclpy

        map_pub = self.pubs[self.topics.map_topic][0]
        t_end = time.time() + limit
        while map_pub.get_subscription_count() == 0 and time.time() < t_end:
            rclpy.spin_once(self.node, timeout_sec=0.05)
        if map_pub.get_subscription_count() == 0:
            raise ConfigError(self.topics.map_topic, "", f"no node subscribed within {limit:g} s")
        t_end = time.time() + (2.0 if others else 0.0)  # some of them may not be subscribed
        while time.time() < t_end and any(
            p.get_subscription_count() == 0 for p, _ in self.pubs.values()
        ):
            rclpy.spin_once(self.node, timeout_sec=0.01)

    def _restart(self) -> None:
        """The publishers destroyed and created again (new ones for the node to match)."""
        for pub, _ in self.pubs.values():
            self.node.destroy_publisher(pub)
        self.pubs.clear()
        self._advertise(self._conns)
        self._wait_for_node(WAIT_NODE, others=False)

    def _break(self, msg: Any, t: float) -> None:
        """A map's faults from their times on (module text)."""
        f = self.faults
        if t >= f.get("no-transform", np.inf):
            msg.header.frame_id = "elsewhere"
        if t >= f.get("old-map", np.inf):
            msg.header.stamp = time_msg(stamp_of(msg) - 2.0)
        if t >= f.get("malformed", np.inf):
            msg.data[0].data = msg.data[0].data[:-7]

    def run(self, reader: Any, path: Path, rate: float, limit: int | None) -> tuple[int, int]:
        """Publish the recording at ``rate``; returns (maps, messages) published."""
        import rclpy
        from rclpy.serialization import deserialize_message

        t = self.topics
        want = {t.map_topic, t.odom_topic, t.joints_topic, "/tf", "/tf_static"}
        self._conns = [c for c in reader.connections if c.topic in want]
        if not any(c.topic == t.map_topic for c in self._conns):
            raise ConfigError(path, "topic", f"no topic {t.map_topic!r}")
        self._advertise(self._conns)
        self._wait_for_node(WAIT_NODE)
        ros1 = path.suffix.lower() == ".bag"
        start, t0 = reader.start_time * 1e-9, time.time()
        maps = sent = 0
        back = 0.0  # a restarted publisher's clock is behind
        for c, t_ns, raw in reader.messages(connections=self._conns):
            tr = t_ns * 1e-9 - start
            if limit is not None and maps >= limit:
                break
            while (wait := t0 + tr / rate - time.time()) > 0:
                rclpy.spin_once(self.node, timeout_sec=min(wait, 0.01))
            if tr >= self.faults.get("restart", np.inf) and back == 0.0:
                back = RESTART_BACK
                self._restart()
            if c.topic in (t.odom_topic, "/tf") and tr >= self.faults.get("odom-stops", np.inf):
                continue
            data = reader.typestore.ros1_to_cdr(raw, c.msgtype) if ros1 else raw
            msg = deserialize_message(bytes(data), message_class(c.msgtype))
            shift = t0 - start - back  # the recording's time t is published at wall t0 + t
            _restamp(msg, shift)
            if c.topic == t.map_topic:
                self.shift = shift
                self._break(msg, tr)
                maps += 1
            self.pubs[c.topic][0].publish(msg)
            sent += 1
        return maps, sent

    def collect(self, maps: int) -> None:
        """Read answers until there is one per map or none came for ``WAIT_ANSWERS``."""
        import rclpy

        quiet = time.time()
        while self.listen and time.time() - quiet < WAIT_ANSWERS and self.answered() < maps:
            before = self.answered()
            rclpy.spin_once(self.node, timeout_sec=0.05)
            if self.answered() != before:
                quiet = time.time()
