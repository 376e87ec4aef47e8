"""Benchmark: the online loop's latency per map on the routes of ``make validate-routes``.

Usage: ``python benchmarks/bench_online_routes.py [--routes N] [--out FILE]``; writes
``results/bench/online_routes.json``. User-like ground (side slopes, bumps, ditches, kerbs;
``problems/validate_routes.yaml``, routes 0 .. N-1): each route is recorded as
``mmstab record`` records it (seeded noise and occluded patches) and followed once, as
``mmstab follow`` follows it, on one core (the process pinned to one CPU, BLAS threads 1).
Per route: the wall time from each map to its answer (the command and the verdicts; the
spare time's re-plans after it excluded) without the first map (the horizon's set-up,
before the robot moves), its p50, p99 and max [ms]; over the routes: their median, 90th
percentile and max, and the routes whose p99 passes the 10 ms target. ``bench_online.py``
gives one route's slow maps with their causes (``--validation-route K``).
"""

from __future__ import annotations

import argparse
import os
import statistics
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from bench_online import validation_route  # noqa: E402
from common import machine_info  # noqa: E402

from mmstab.core.files import write_json  # noqa: E402
from mmstab.core.problem import load_problem  # noqa: E402
from mmstab.outputs.recording import record_route  # noqa: E402
from mmstab.runs.online.run import follow_recording  # noqa: E402

TARGET_P99_MS = 10.0


def route_latency(k: int) -> dict:
    """Route ``k`` recorded and followed: its per-map latency without the first map [ms]."""
    path = Path(validation_route(k))
    problem = load_problem(path)
    rec = path.with_suffix(".mcap")
    record_route(problem, rec)
    run = follow_recording(problem, rec)
    ms = 1e3 * np.array([x.latency for x in run.steps[1:]])
    return {
        "route": k,
        "maps": len(run.steps),
        "p50": float(np.percentile(ms, 50)),
        "p99": float(np.percentile(ms, 99)),
        "max": float(ms.max()),
        "first_map_ms": 1e3 * run.steps[0].latency,
    }


def main() -> None:
    """Record and follow the routes, write the JSON."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--routes", type=int, default=48)
    ap.add_argument("--out", default="results/bench/online_routes.json")
    args = ap.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    routes = [route_latency(k) for k in range(args.routes)]
    p99 = [r["p99"] for r in routes]
    result = {
        "settings": "problems/validate_routes.yaml",
        "routes": routes,
        "p99_ms": {
            "median": statistics.median(p99),
            "p90": float(np.percentile(p99, 90)),
            "max": max(p99),
        },
        "max_ms": max(r["max"] for r in routes),
        "over_target": [r["route"] for r in routes if r["p99"] > TARGET_P99_MS],
        "over_target_count": sum(r["p99"] > TARGET_P99_MS for r in routes),
        "target_p99_ms": TARGET_P99_MS,
        "machine": machine_info(one_core=True),
    }
    write_json(args.out, result)
    n = len(result["over_target"])
    print(
        f"online on {len(routes)} validation routes: p99 per route median "
        f"{result['p99_ms']['median']:.1f}, p90 {result['p99_ms']['p90']:.1f}, max "
        f"{result['p99_ms']['max']:.1f} ms; over {TARGET_P99_MS:g} ms on {n}; the slowest map "
        f"{result['max_ms']:.0f} ms -> {args.out}"
    )


if __name__ == "__main__":
    main()
