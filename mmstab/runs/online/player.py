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
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from trajectory_msgs.msg import JointTrajectory

    faults = faults or {}
    rclpy.init()
    node = rclpy.create_node("mmstab_play")
    got: list[dict[str, Any]] = []
    shift_box = [0.0]

    def on_diag(msg: Any) -> None:
        head = next((s for s in msg.status if s.name == "mmstab: stability"), None)
        if head is None:
            return
        values = {kv.key: kv.value for kv in head.values}
        got.append({
            "kind": "diagnostics",
            "received": time.time(),
            "stamp": float(values["map_stamp"]) - shift_box[0],
            "abs_stamp": float(values["map_stamp"]),
            "levels": {s.name.removeprefix("mmstab: "): s.level[0] for s in msg.status},
            "message": head.message,
            "source": values.get("source", "map"),
            "values": values,
        })  # fmt: skip

    def on_target(msg: Any) -> None:
        got.append({
            "kind": "arm_target", "received": time.time(),
            "stamp": stamp_of(msg) - shift_box[0],
            "positions": [float(x) for x in msg.points[0].positions],
        })  # fmt: skip

    if answers is not None:
        node.create_subscription(DiagnosticArray, topics.diagnostics_topic, on_diag, 1000)
        node.create_subscription(JointTrajectory, topics.arm_target_topic, on_target, 1000)
    with open_recording(path) as reader:
        ros1 = Path(path).suffix.lower() == ".bag"
        want = {topics.map_topic, topics.odom_topic, topics.joints_topic, "/tf", "/tf_static"}
        conns = [c for c in reader.connections if c.topic in want]
        if not any(c.topic == topics.map_topic for c in conns):
            raise ConfigError(path, "topic", f"no topic {topics.map_topic!r}")
        pubs: dict[str, Any] = {}
        for c in conns:
            if c.topic not in pubs:
                qos: Any = 100
                if c.topic == "/tf_static":
                    qos = QoSProfile(depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL)
                pubs[c.topic] = (node.create_publisher(message_class(c.msgtype), c.topic, qos), c)
        map_pub = pubs[topics.map_topic][0]
        t_end = time.time() + WAIT_NODE
        while map_pub.get_subscription_count() == 0 and time.time() < t_end:
            rclpy.spin_once(node, timeout_sec=0.05)
        if map_pub.get_subscription_count() == 0:
            raise ConfigError(topics.map_topic, "", f"no node subscribed within {WAIT_NODE:g} s")
        t_end = time.time() + 2.0  # the node's other subscriptions (some may not be there)
        while time.time() < t_end and any(
            p.get_subscription_count() == 0 for p, _ in pubs.values()
        ):
            rclpy.spin_once(node, timeout_sec=0.01)
        start_rec = reader.start_time * 1e-9
        t0 = time.time()
        maps = sent = 0
        restarted = False
        for c, t_ns, raw in reader.messages(connections=conns):
            t = t_ns * 1e-9 - start_rec
            if limit is not None and maps >= limit:
                break
            wait = t0 + t / rate - time.time()
            while wait > 0:
                rclpy.spin_once(node, timeout_sec=min(wait, 0.01))
                wait = t0 + t / rate - time.time()
            if "restart" in faults and t >= faults["restart"] and not restarted:
                restarted = True
                for topic, (pub, conn) in list(pubs.items()):
                    node.destroy_publisher(pub)
                    pubs[topic] = (
                        node.create_publisher(message_class(conn.msgtype), topic, 100),
                        conn,
                    )
                map_pub = pubs[topics.map_topic][0]
                while map_pub.get_subscription_count() == 0:
                    rclpy.spin_once(node, timeout_sec=0.01)
            cls = message_class(c.msgtype)
            from rclpy.serialization import deserialize_message

            data = reader.typestore.ros1_to_cdr(raw, c.msgtype) if ros1 else raw
            msg = deserialize_message(bytes(data), cls)
            # recorded stamps -> now: the recording's time t is published at wall t0 + t
            shift = t0 - start_rec
            if restarted:
                shift -= RESTART_BACK
            if c.topic == topics.map_topic:
                shift_box[0] = shift
            is_map = c.topic == topics.map_topic
            if c.topic in (topics.odom_topic, "/tf") and t >= faults.get("odom-stops", np.inf):
                continue
            _restamp(msg, shift)
            if is_map:
                if t >= faults.get("no-transform", np.inf):
                    msg.header.frame_id = "elsewhere"
                if t >= faults.get("old-map", np.inf):
                    msg.header.stamp = time_msg(stamp_of(msg) - 2.0)
                if t >= faults.get("malformed", np.inf):
                    msg.data[0].data = msg.data[0].data[:-7]
                maps += 1
            pubs[c.topic][0].publish(msg)
            sent += 1
        quiet = time.time()

        def n_diag() -> int:
            return sum(a["kind"] == "diagnostics" and a["source"] == "map" for a in got)

        while answers is not None and time.time() - quiet < WAIT_ANSWERS:
            before = n_diag()
            rclpy.spin_once(node, timeout_sec=0.05)
            if n_diag() != before:
                quiet = time.time()
            if n_diag() >= maps:
                break
    node.destroy_node()
    rclpy.shutdown()
    if answers is not None:
        Path(answers).write_text("".join(json.dumps(a) + "\n" for a in got))
    return {"maps": maps, "messages": sent, "answers": n_diag() if answers is not None else None}
