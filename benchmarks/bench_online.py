"""Benchmark: the online loop's latency per map beside the offline planner (issue 26).

Usage: ``python benchmarks/bench_online.py [PROBLEM.yaml] [--recording FILE] [--repeats N]``;
writes ``results/bench/online.json``. The recording (``mmstab record``, written if missing)
is followed ``repeats`` times on one core (the process pinned to one CPU, BLAS threads 1);
per map: the update's wall time (rest of the robot, its reference and the horizon on the
map, re-plan of the poses whose ground changed, one controller step). Beside it, in the
same run, the offline warm-started planner on the same route poses on the problem's own
terrain (its per-pose search time, the resting pose included), and the whole offline plan
per pose. Medians over the repeats of each percentile.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from common import machine_info  # noqa: E402

from mmstab.core.files import write_json  # noqa: E402
from mmstab.core.problem import load_problem  # noqa: E402
from mmstab.experiments.online import offline_plan  # noqa: E402
from mmstab.experiments.recording import record_route  # noqa: E402
from mmstab.runs.online.run import follow_recording, summarize  # noqa: E402
from mmstab.workspace import load_or_build_workspace  # noqa: E402


def main() -> None:
    """Follow the recording ``--repeats`` times, plan offline beside it, write the JSON."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("problem", nargs="?", default="problems/rough.yaml")
    ap.add_argument("--recording", default="results/online/rough.mcap")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", default="results/bench/online.json")
    args = ap.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    problem = load_problem(args.problem)
    rec = Path(args.recording)
    if not rec.exists():
        record_route(problem, rec)
    ws = load_or_build_workspace(problem)
    runs, offline_pose, offline_total = [], [], []
    for _ in range(args.repeats):
        run = follow_recording(problem, rec, ws)
        runs.append(summarize(run))
        t0 = time.perf_counter()
        off = offline_plan(problem, run, ws)
        offline_total.append((time.perf_counter() - t0) / len(off.s))
        offline_pose.append(float(np.median(off.search_seconds)))
    lat = [r["latency_ms"] for r in runs]
    result = {
        "problem": args.problem,
        "recording": str(rec),
        "updates": runs[0]["updates"],
        "replanned_poses": runs[0]["replanned_poses"],
        "online_latency_ms": {
            k: statistics.median(x[k] for x in lat) for k in ("p50", "p99", "max", "mean")
        },
        "offline_ms_per_pose": {
            "search_median": 1e3 * statistics.median(offline_pose),
            "whole_plan_mean": 1e3 * statistics.median(offline_total),
        },
        "targets_ms": {"p50": 10.0, "p99": 30.0},
        "repeats": args.repeats,
        "machine": machine_info(one_core=True),
    }
    write_json(args.out, result)
    print(
        f"online: p50 {result['online_latency_ms']['p50']:.2f} ms, p99 "
        f"{result['online_latency_ms']['p99']:.2f} ms per map ({result['updates']} maps); "
        f"offline: {result['offline_ms_per_pose']['search_median']:.2f} ms per pose (search), "
        f"{result['offline_ms_per_pose']['whole_plan_mean']:.2f} ms per pose (whole plan)"
    )


if __name__ == "__main__":
    main()
