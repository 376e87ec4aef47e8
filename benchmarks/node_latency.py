"""Benchmark: ``mmstab node``'s end-to-end latency over ROS 2 (map stamp -> answer).

Usage: ``python benchmarks/node_latency.py [PROBLEM.yaml] [--recording FILE] [--duration S]``;
writes ``results/bench/node.json`` (``make bench-node``). A recording of the problem's route
(``mmstab record``, the first ``duration`` seconds; written if missing) is played in real
time onto ROS 2 topics by one process (``mmstab play``) while ``mmstab node`` answers in
another (Fast DDS on this machine, a domain of its own). Per map, from its stamp (the
recording's time moved to the wall clock; the map is published 1 ms after it, the
recording's receive delay):

* ``node``: the map in the node's callback (transport, deserialisation; the last map
  received before an answer, the map itself unless one came while the node was busy);
* ``command``: the controller's command and the arm's target published (right after the
  loop's step, before the verdicts);
* ``published``: the whole answer published (verdicts, markers: the ``answered`` time in
  its diagnostics);
* ``received``: the answer received back by the player;
* ``update``: the loop's own update (``Follower.update``, as ``mmstab follow`` times it:
  from the map to its answer, the command and the verdicts), and ``update_cpu`` the loop
  thread's processor time in it (what the other threads and processes on the two cores do
  not inflate).

``latency_ms_after_startup``: the same from 1 s after the first map's stamp on (the first
map plans the horizon, 0.1-0.2 s, and the maps behind it wait in the node's queue).
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from common import machine_info

from mmstab.core.files import write_json
from mmstab.core.problem import load_problem
from mmstab.outputs.recording import record_route

ROOT = Path(__file__).resolve().parents[1]
#: The maps of the first second are the set-up's (``latency_ms_after_startup`` leaves them out).
STARTUP_S = 1.0


def stats(x: np.ndarray) -> dict[str, float]:
    """p50 / p99 / max / mean [ms] of latencies [s]."""
    ms = 1e3 * np.asarray(x, dtype=float)
    return {
        "p50": float(np.percentile(ms, 50)),
        "p99": float(np.percentile(ms, 99)),
        "max": float(ms.max()),
        "mean": float(ms.mean()),
    }


def main() -> None:
    """Record if needed, run the node and the player, write the JSON."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("problem", nargs="?", default="problems/rough.yaml")
    ap.add_argument("--recording", default="results/bench/node_rough.mcap")
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--out", default="results/bench/node.json")
    args = ap.parse_args()
    problem = load_problem(args.problem)
    rec = Path(args.recording)
    if not rec.exists():
        rec.parent.mkdir(parents=True, exist_ok=True)
        record_route(problem, rec, args.duration)
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    env["ROS_DOMAIN_ID"] = str(100 + os.getpid() % 100)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    with tempfile.TemporaryDirectory() as tmp:
        answers = Path(tmp) / "answers.jsonl"
        node = subprocess.Popen(
            [sys.executable, "-m", "mmstab", "node", args.problem], env=env,
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        )  # fmt: skip
        try:
            played = subprocess.run(
                [sys.executable, "-m", "mmstab", "play", str(rec), "--problem", args.problem,
                 "--answers", str(answers)],
                env=env, check=True, capture_output=True, text=True,
            ).stdout  # fmt: skip
        finally:
            node.send_signal(signal.SIGINT)
            node.wait(timeout=20)
        got = [json.loads(line) for line in answers.read_text().splitlines()]
    maps = [a for a in got if a["kind"] == "diagnostics" and a["source"] == "map"]
    fresh = [a for a in maps if "latency_ms" in a["values"]]
    stamp = np.array([a["abs_stamp"] for a in maps])
    published = np.array([float(a["values"]["answered"]) for a in maps]) - stamp
    command = np.array([float(a["values"]["command_published"]) - a["abs_stamp"] for a in fresh])
    received_node = np.array([float(a["values"]["map_received"]) - a["abs_stamp"] for a in fresh])
    received = np.array([a["received"] for a in maps]) - stamp
    update = np.array([float(a["values"]["latency_ms"]) * 1e-3 for a in fresh])
    cpu = np.array([float(a["values"]["cpu_ms"]) * 1e-3 for a in fresh])
    # from 1 s on: without the first map's set-up (the horizon planned, 0.1-0.2 s) and the
    # maps that queued behind it, before the robot has moved
    late = stamp >= stamp.min() + STARTUP_S
    late_fresh = np.array([a["abs_stamp"] >= stamp.min() + STARTUP_S for a in fresh])
    published_maps = int(played.split("play: ")[1].split(" maps")[0])
    result = {
        "problem": args.problem,
        "recording": str(rec),
        "maps_published": published_maps,
        # a map that comes while the node is busy waits in its queue (depth 10, the newest kept)
        "maps_received_by_node": max(int(a["values"]["maps_received"]) for a in maps),
        "maps_answered": len(maps),
        "stale_answers": len(maps) - len(fresh),
        "latency_ms": {
            "stamp_to_node": stats(received_node),
            "stamp_to_command": stats(command),
            "stamp_to_published": stats(published),
            "stamp_to_received": stats(received),
            "update": stats(update),
            "update_cpu": stats(cpu),
        },
        "latency_ms_after_startup": {
            "stamp_to_command": stats(command[late_fresh]),
            "stamp_to_published": stats(published[late]),
            "stamp_to_received": stats(received[late]),
            "update": stats(update[late_fresh]),
        },
        "startup_s": STARTUP_S,
        "transport": "ROS 2 Jazzy wheels, rmw_fastrtps_cpp, localhost",
        "machine": machine_info(one_core=False),
    }
    write_json(args.out, result)
    lat = result["latency_ms"]["stamp_to_published"]
    cmd = result["latency_ms"]["stamp_to_command"]
    print(
        f"node: {len(maps)} of {published_maps} maps answered ({result['stale_answers']} stale, "
        f"{result['maps_received_by_node']} received); map stamp -> command p50 "
        f"{cmd['p50']:.1f} ms, p99 {cmd['p99']:.1f} ms; -> whole answer p50 {lat['p50']:.1f} ms, "
        f"p99 {lat['p99']:.1f} ms (update alone p50 "
        f"{result['latency_ms']['update']['p50']:.1f} ms, p99 "
        f"{result['latency_ms']['update']['p99']:.1f} ms)"
    )
    after = result["latency_ms_after_startup"]["stamp_to_published"]
    print(f"node: from {STARTUP_S:g} s on: answer p50 {after['p50']:.1f}, p99 {after['p99']:.1f}")


if __name__ == "__main__":
    main()
