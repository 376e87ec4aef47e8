"""``mmstab node`` as a robot runs it: two processes over ROS 2 (Fast DDS, this machine only).

One process is the node (``mmstab node PROBLEM``), another plays a recording onto the
robot's topics and reads the node's answers back (``mmstab play --answers``); they must be
``mmstab follow``'s on the same recording, and each fault must end in stale verdicts. The
ROS 2 traffic stays on this machine (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, a domain
of its own). Skipped only when the ros extra is not installed (``make ros``).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from test_online import problem_file, with_joint_states

import mmstab
from mmstab.outputs.recording import record_route
from mmstab.runs.online.guard import STALE, VERDICTS
from mmstab.runs.online.rosenv import ros_available
from mmstab.runs.online.run import follow_recording
from mmstab.runs.recording import joint_names

ROOT = Path(__file__).resolve().parents[2]
MISSING = ros_available()
pytestmark = [
    pytest.mark.ros,
    pytest.mark.skipif(MISSING is not None, reason=f"ros extra not installed: {MISSING}"),
]
#: Maps of the recording (2 s at 10 Hz).
MAPS = 21


def ros_test_env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    env["ROS_DOMAIN_ID"] = str(100 + os.getpid() % 100)  # a domain of this run's own
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.pop("ROS_LOCALHOST_ONLY", None)
    return env


@pytest.fixture(scope="module")
def setup(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Any]]:
    """A 2 s recording with measured joint states, its problem, and a running node."""
    d = tmp_path_factory.mktemp("node")
    plain = mmstab.load_problem(problem_file(d, noise=0.0, unknown=0.0))
    record_route(plain, d / "plain.mcap", duration=2.0)
    robot = plain.robot
    held = np.array(robot.stowed, dtype=float) + 0.05  # the arm as its encoders report it
    with_joint_states(d / "plain.mcap", d / "run.mcap", joint_names(robot), held)
    data = yaml.safe_load(plain.path.read_text())
    data["online"]["joints_topic"] = "/joint_states"
    (d / "p.yaml").write_text(yaml.safe_dump(data))
    env = ros_test_env()
    log = open(d / "node.log", "w")  # noqa: SIM115 (closed below)
    node = subprocess.Popen(
        [sys.executable, "-m", "mmstab", "node", str(d / "p.yaml")],
        env=env, stdout=log, stderr=subprocess.STDOUT, cwd=ROOT,
    )  # fmt: skip
    try:
        yield {"dir": d, "problem": d / "p.yaml", "rec": d / "run.mcap", "held": held,
               "env": env, "node": node, "log": d / "node.log"}  # fmt: skip
    finally:
        node.send_signal(signal.SIGINT)
        try:
            node.wait(timeout=10)
        except subprocess.TimeoutExpired:
            node.kill()
        log.close()


def play(setup: dict[str, Any], name: str, *faults: str, rate: float = 1.0) -> list[dict[str, Any]]:
    """Play the recording (with faults) and return the node's answers to its maps."""
    out = setup["dir"] / f"{name}.jsonl"
    # the node serves the whole module: a play whose first stamp is older than the last
    # play's last one would be a restarted publisher to it, so each starts after that
    wait = setup.get("last_abs_stamp", 0.0) + 0.2 - time.time()
    if wait > 0:
        time.sleep(wait)
    cmd = [sys.executable, "-m", "mmstab", "play", str(setup["rec"]), "--problem",
           str(setup["problem"]), "--answers", str(out), "--rate", str(rate)]  # fmt: skip
    for f in faults:
        cmd += ["--fault", f]
    r = subprocess.run(cmd, env=setup["env"], capture_output=True, text=True, timeout=150)
    assert r.returncode == 0, r.stderr[-2000:] + Path(setup["log"]).read_text()[-2000:]
    got = [json.loads(line) for line in out.read_text().splitlines()]
    stamps = [a["abs_stamp"] for a in got if isinstance(a.get("abs_stamp"), float)]
    setup["last_abs_stamp"] = max([setup.get("last_abs_stamp", 0.0), *stamps])
    setup["targets"] = [a for a in got if a["kind"] == "arm_target"]
    return [a for a in got if a["kind"] == "diagnostics" and a["source"] == "map"]


def test_the_node_answers_every_map_as_follow_does(setup: dict[str, Any]) -> None:
    ref = follow_recording(mmstab.load_problem(setup["problem"]), setup["rec"]).steps
    got = play(setup, "plain")
    assert len(ref) == MAPS and len(got) == MAPS  # every map answered, once
    held = setup["held"]
    for a, st in zip(got, ref, strict=True):
        v = a["values"]
        assert a["message"] != "" and "mu" in v, a["message"]  # fresh
        q = np.array(v["q"].split(), dtype=float)
        qdot = np.array(v["qdot"].split(), dtype=float)
        assert v["measured"] == "True" and np.array_equal(q, held)  # the measured joints
        assert np.array_equal(q, st.q)
        # the controller's period is the time between map stamps: follow's to 1 ns
        assert np.allclose(qdot, st.qdot, atol=1e-5)
        assert float(v["mu"]) == pytest.approx(st.mu, rel=1e-9)  # the same posture and map
        assert a["stamp"] == pytest.approx(st.time - ref[0].time, abs=2e-3)
        assert set(a["levels"]) == {"stability", *VERDICTS}
        assert a["levels"]["coverage"] == 0
    # the arm's target posture (JointTrajectory), stamped with its map: follow's planned one
    targets = setup["targets"]
    assert len(targets) == MAPS
    for t, st in zip(targets, ref, strict=True):
        assert st.q_ref is not None and np.allclose(t["positions"], st.q_ref, atol=1e-9)


@pytest.mark.parametrize(
    ("fault", "reason", "start"),
    [
        ("odom-stops", "odometry stopped", 1.25),  # odom_timeout 0.2 s after the last
        ("no-transform", "no transform", 1.0),
        ("old-map", "old", 1.0),
        ("malformed", "malformed map", 1.0),
    ],
)
def test_each_fault_ends_in_stale_verdicts(
    setup: dict[str, Any], fault: str, reason: str, start: float
) -> None:
    got = play(setup, fault, f"{fault}@1.0", rate=2.0)  # the guard's limits are in stamps
    assert len(got) == MAPS
    for i, a in enumerate(got):  # the maps are 0.1 s apart
        if 0.1 * i >= start - 1e-6:
            assert reason in a["message"], (i, a["message"])
            assert all(level == STALE for level in a["levels"].values())  # never an OK
    assert setup["node"].poll() is None  # the node keeps running


def test_a_restarted_publisher_is_stale_once(setup: dict[str, Any]) -> None:
    # the node serves the whole module and logs every earlier test's faults too: only this
    # play's part of the log counts
    before = len(Path(setup["log"]).read_text())
    got = play(setup, "restart", "restart@1.0")
    stale = [a for a in got if a["message"].startswith("map stamp went back")]
    assert len(stale) == 1 and all(v == STALE for v in stale[0]["levels"].values())
    assert "mu" in got[-1]["values"]  # fresh again afterwards
    assert setup["node"].poll() is None
    log = Path(setup["log"]).read_text()[before:]
    assert log.count("stale answer: map stamp went back") == 1  # said once
