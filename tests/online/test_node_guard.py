"""The live node's loop and guard without ROS: LiveFollower fed a recording's messages.

The messages are ``rosbags``' (the fields ROS 2's have), the clock a number: what ``mmstab
node`` does per message, checked against ``mmstab follow`` on the same recording and on the
faults a robot has (docs/online.md, "Never a stale safe").
"""

from __future__ import annotations

import dataclasses
import json
import struct
import time
from pathlib import Path

import numpy as np
import pytest
from test_online import problem_file

import mmstab
from mmstab.outputs.recording import record_route
from mmstab.runs.online.follow import FollowSettings, build_follower
from mmstab.runs.online.guard import (
    ERROR,
    OK,
    STALE,
    UNMAPPED,
    VERDICTS,
    WARN,
    GuardSettings,
    ReasonLog,
    map_fault,
    verdicts,
)
from mmstab.runs.online.live import LiveAnswer, LiveFollower
from mmstab.runs.online.rosenv import stamp_of
from mmstab.runs.online.run import follow_recording
from mmstab.runs.recording import joint_names
from mmstab.stability.static import axis_angles
from mmstab.terrain.base import GRAVITY_G
from mmstab.terrain.gridmap import GRIDMAP, ros_time, typestore
from mmstab.terrain.recording import messages

GUARD = GuardSettings()


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> tuple[mmstab.Problem, Path]:
    d = tmp_path_factory.mktemp("live")
    problem = mmstab.load_problem(problem_file(d, noise=0.0, unknown=0.0))
    path = d / "live.mcap"
    record_route(problem, path, duration=2.0)
    return problem, path


def feed(
    problem: mmstab.Problem, path: Path, faults: dict[str, float] | None = None
) -> list[LiveAnswer]:
    """The recording's messages into a LiveFollower, each at its stamp + 5 ms (wall)."""
    faults = faults or {}
    s = FollowSettings.of(problem)
    live = LiveFollower(build_follower(problem), GUARD, joint_names(problem.robot), 0.0)
    store = typestore(False)
    out: list[LiveAnswer] = []
    topics = {s.map_topic: GRIDMAP, s.odom_topic: "nav_msgs/msg/Odometry"}
    for m in messages(path, topics):
        msg, now = m.message, m.time + 0.005
        if m.topic == s.odom_topic:
            if m.time >= faults.get("odom-stops", np.inf):
                continue
            live.on_odometry(msg)
            out += live.poll(now)
            continue
        header = msg.header
        if m.time >= faults.get("no-transform", np.inf):
            header = dataclasses.replace(header, frame_id="elsewhere")
        if m.time >= faults.get("old-map", np.inf):
            header = dataclasses.replace(header, stamp=ros_time(store, stamp_of(msg) - 2.0))
        if m.time >= faults.get("restart", np.inf) and m.time < faults["restart"] + 0.05:
            header = dataclasses.replace(header, stamp=ros_time(store, stamp_of(msg) - 0.3))
        msg = dataclasses.replace(msg, header=header)
        if m.time >= faults.get("malformed", np.inf):
            layer = msg.data[0]
            msg.data[0] = dataclasses.replace(layer, data=layer.data[:-7])
        out += live.on_map(msg, now)
        live.spare()  # after the answers, as the node does
    out += live.flush(now + GUARD.odom_wait)  # the last map's wait is over
    return out


def test_the_live_loop_gives_follows_answers(recorded: tuple[mmstab.Problem, Path]) -> None:
    problem, path = recorded
    ref = follow_recording(problem, path).steps
    got = feed(problem, path)
    assert len(got) == len(ref) == 21
    for a, st in zip(got, ref, strict=True):
        assert a.reason is None and a.step is not None
        # the same step: times from the first map (follow: from the recording's start)
        assert a.step.time == pytest.approx(st.time - ref[0].time, abs=1e-9)
        assert np.allclose(a.step.q, st.q, atol=1e-9) and np.allclose(a.step.qdot, st.qdot)
        assert a.step.mu == pytest.approx(st.mu, rel=1e-9)
        assert [v.name for v in a.verdicts] == list(VERDICTS)
        assert a.scene is not None and len(a.scene.polygon) >= 3
        # the CoM's projection lies below it, on the support's plane (body z through it)
        assert a.scene.com_ground[2] < a.scene.com[2]
        assert np.allclose(a.scene.com_ground[:2], a.scene.com[:2])
        # the tip axis: the edge of this support whose force angle under m g is the least,
        # and that angle times m g is the answer's μ (the scene is μ's own support)
        poly, weight = a.scene.polygon, problem.robot.total_mass * GRAVITY_G
        theta = axis_angles(poly, a.scene.com, weight)
        j = int(np.argmin(theta))
        np.testing.assert_array_equal(a.scene.tip_axis, poly[[j, (j + 1) % len(poly)]])
        assert theta[j] * np.linalg.norm(weight) == pytest.approx(a.step.mu, rel=1e-9)


@pytest.mark.parametrize(
    ("fault", "reason"),
    [
        ("odom-stops", "odometry stopped"),
        ("no-transform", "no transform"),
        ("old-map", "map is 2.01 s old"),  # 2 s back, received 5 ms after
        ("malformed", "malformed map"),
    ],
)
def test_each_fault_ends_in_stale_verdicts(
    recorded: tuple[mmstab.Problem, Path], fault: str, reason: str
) -> None:
    problem, path = recorded
    got = feed(problem, path, {fault: 1.0})
    assert len(got) == 21
    # the maps from the fault on (odometry: once it is odom_timeout behind) are stale
    start = 1.0 + (GUARD.odom_timeout + 0.01 if fault == "odom-stops" else 0.0)
    for i, a in enumerate(got):  # the maps are 0.1 s apart
        if 0.1 * i < 1.0 - 1e-6:
            assert a.reason is None  # fresh before it
        elif 0.1 * i >= start - 1e-6:
            assert a.reason is not None and reason in a.reason and a.step is None
            assert all(v.level == STALE for v in a.verdicts)  # never an OK
    assert got[-1].reason is not None


def test_a_restarted_publisher_is_stale_until_fresh_odometry(
    recorded: tuple[mmstab.Problem, Path],
) -> None:
    problem, path = recorded
    got = feed(problem, path, {"restart": 1.0})
    stale = [a for a in got if a.reason is not None]
    assert len(stale) == 1 and "publisher restarted" in stale[0].reason
    assert all(v.level == STALE for v in stale[0].verdicts)
    # the next map (its stamp 0.3 s ahead again) is answered with the odometry at its stamp
    after = got[got.index(stale[0]) + 1]
    assert after.reason is None and after.step is not None


def test_the_watchdog_says_stale_once_per_period(recorded: tuple[mmstab.Problem, Path]) -> None:
    problem, _ = recorded
    live = LiveFollower(build_follower(problem), GUARD, joint_names(problem.robot), 0.0)
    first = live.watchdog(100.0)
    assert first is not None and first.watchdog and first.reason == "no map received"
    assert live.watchdog(100.1) is None  # not again within max_map_age
    again = live.watchdog(100.0 + GUARD.max_map_age + 0.01)
    assert again is not None and all(v.level == STALE for v in again.verdicts)


def test_map_fault_times() -> None:
    g = GuardSettings(max_map_age=0.5, odom_timeout=0.2)
    assert map_fault(g, 10.0, 9.9, 9.85) is None
    assert "old" in str(map_fault(g, 10.0, 9.4, 9.4))
    assert map_fault(g, 10.0, 9.9, None) == "no odometry received"
    assert "odometry stopped" in str(map_fault(g, 10.0, 9.9, 9.65))


def test_verdict_levels() -> None:
    v = {x.name: x.level for x in verdicts(True, 100.0, 0.0, 0.1, 0.7, None, False, 0.1)}
    assert v == dict.fromkeys(VERDICTS, OK)
    v = {x.name: x.level for x in verdicts(True, -1.0, 0.0, 0.7, 0.7, True, True, -0.02)}
    assert v == {"tip": ERROR, "slide": ERROR, "step": ERROR, "high-centred": ERROR,
                 "arm-contact": ERROR, "coverage": OK}  # fmt: skip
    # atan(0.7) = 34.99 deg: a tilt of 35.0 deg slides, 34.9 does not
    assert verdicts(True, 1.0, 0.0, np.radians(35.0), 0.7, None, False, 0.1)[1].level == ERROR
    assert verdicts(True, 1.0, 0.0, np.radians(34.9), 0.7, None, False, 0.1)[1].level == OK
    v = {x.name: x for x in verdicts(True, 100.0, 0.0, 0.1, 0.7, None, False, -0.034)}
    assert v["arm-contact"].message == "the arm 3.4 cm in the ground"
    v = {x.name: x for x in verdicts(True, 100.0, 0.0, 0.1, 0.7, None, False, np.nan)}
    assert v["arm-contact"].level == WARN and "not mapped" in v["arm-contact"].message
    none = verdicts(False, float("nan"), 0.0, np.nan, 0.7, None, False, np.nan)
    v = {x.name: x.level for x in none}
    assert v["coverage"] == ERROR and all(v[n] == STALE for n in VERDICTS[:-1])


def test_reason_log_says_once_per_period() -> None:
    log = ReasonLog(10.0)
    assert log.say("odometry stopped", 0.0) and not log.say("odometry stopped", 5.0)
    assert log.say("odometry stopped", 10.5) and log.say("no transform", 10.5)
    assert sorted(log.clear()) == ["no transform", "odometry stopped"]
    assert log.say("odometry stopped", 11.0)


def test_the_foxglove_view_serves_the_answers(recorded: tuple[mmstab.Problem, Path]) -> None:
    """A WebSocket client (Foxglove's protocol) subscribes and reads μ and the verdicts."""
    pytest.importorskip("foxglove")
    websockets = pytest.importorskip("websockets.sync.client")
    from mmstab.runs.online.foxglove_view import FoxgloveView

    problem, path = recorded
    answers = feed(problem, path, {"no-transform": 1.5})  # fresh, then stale
    view = FoxgloveView(problem, port=0)
    try:
        with websockets.connect(
            f"ws://127.0.0.1:{view.port}", subprotocols=["foxglove.sdk.v1"]
        ) as ws:
            channels: dict[str, int] = {}
            while not {"/mu", "/verdicts", "/support_polygon", "/map", "/tf"} <= set(channels):
                msg = json.loads(ws.recv(timeout=5))
                if msg["op"] == "advertise":
                    channels.update({c["topic"]: c["id"] for c in msg["channels"]})
            subs = {1: "/mu", 2: "/verdicts", 3: "/support_polygon"}
            ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                {"id": k, "channelId": channels[t]} for k, t in subs.items()]}))  # fmt: skip
            time.sleep(0.3)
            for a in answers:
                view.answer(a)
            got: dict[str, list[bytes]] = {t: [] for t in subs.values()}
            while min(len(x) for x in got.values()) < len(answers):
                data = ws.recv(timeout=5)
                if isinstance(data, bytes) and data[0] == 1:  # a message on a subscription
                    sub = struct.unpack_from("<I", data, 1)[0]
                    got[subs[sub]].append(data[13:])
    finally:
        view.stop()
    mu = [json.loads(p)["data"] for p in got["/mu"]]
    for a, m in zip(answers, mu, strict=True):
        assert (m is None) if a.step is None else m == pytest.approx(a.step.mu, rel=1e-12)
    v = [json.loads(p) for p in got["/verdicts"]]
    assert v[-1]["reason"] is not None and "no transform" in v[-1]["reason"]
    assert all(x["level"] == STALE for x in v[-1]["verdicts"].values())
    assert v[0]["reason"] is None and set(v[0]["verdicts"]) == set(VERDICTS)
    assert len(got["/support_polygon"]) == len(answers)  # an entity or its deletion each


def test_unmapped_ground_ahead_is_a_warning() -> None:
    v = {x.name: x for x in verdicts(True, 100.0, 0.0, 0.1, 0.7, UNMAPPED, False, 0.1)}
    assert v["step"].level == WARN and "not mapped" in v["step"].message


def test_maps_that_come_before_their_odometry_wait_in_order(
    recorded: tuple[mmstab.Problem, Path],
) -> None:
    """A busy node: each odometry arrives 0.12 s late, after the next map (the map 0.1 s on)."""
    problem, path = recorded
    ref = follow_recording(problem, path).steps
    s = FollowSettings.of(problem)
    guard = GuardSettings(odom_wait=0.2)
    live = LiveFollower(build_follower(problem), guard, joint_names(problem.robot), 0.0)
    topics = {s.map_topic: GRIDMAP, s.odom_topic: "nav_msgs/msg/Odometry"}
    events = sorted(
        ((m.time + (0.12 if m.topic == s.odom_topic else 0.0), i, m)
         for i, m in enumerate(messages(path, topics))),
        key=lambda e: (e[0], e[1]),
    )  # fmt: skip
    got: list[LiveAnswer] = []
    waited = 0
    for now, _, m in events:
        if m.topic == s.odom_topic:
            live.on_odometry(m.message)
            got += live.poll(now)
        else:
            got += live.on_map(m.message, now)
            waited = max(waited, len(live.pending))
    got += live.flush(events[-1][0])
    assert waited == 2  # two maps waiting at once: the old node answered the first too early
    assert len(got) == len(ref) and all(a.reason is None for a in got)
    for a, st in zip(got, ref, strict=True):
        assert a.step is not None and np.allclose(a.step.pose, st.pose, atol=1e-12)
        assert np.allclose(a.step.qdot, st.qdot) and a.step.mu == pytest.approx(st.mu, rel=1e-9)


def test_faults_are_named_and_timed() -> None:
    from mmstab.runs.online.player import parse_faults

    assert parse_faults(["odom-stops@1.5", "restart@2"]) == {"odom-stops": 1.5, "restart": 2.0}
    with pytest.raises(mmstab.ConfigError, match="'bogus': one of odom-stops"):
        parse_faults(["bogus@1"])
    with pytest.raises(mmstab.ConfigError, match="a time"):
        parse_faults(["old-map@soon"])
