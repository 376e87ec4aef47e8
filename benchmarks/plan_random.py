"""Benchmark: a one-off ``mmstab plan`` of seeded random routes, ms per pose, every check on.

Usage: ``python benchmarks/plan_random.py [--pairs N] [--runs R] [--out FILE]``; writes
``results/bench/plan_random.json``. The routes are the seeded random maps and routes of
``tests/runs/test_random_routes.py`` (pairs 0 .. N-1, the problems' default grid and planner:
``method: roadmap`` with the ground under the arm, the attitude margin and the climb limit
on). Each pair runs in a fresh process, as ``mmstab plan`` would:

- ``roadmap``: the first plan of the process is the one-off (the caches read from the
  cache folder, built first if missing): its fixed costs (``RoutePlan.fixed_seconds``:
  V, its membership file, the roadmap, the start node's component and shortest-path tree)
  apart from its time per pose (the whole search divided by the poses); then ``--runs`` - 1
  more plans in the same process (their fixed costs near 0, the per-pose work the same);
- ``sequence``: the whole route at once (``method: sequence``), ``--runs`` times; a route
  it does not settle on is recorded as such;
- ``cmaes``: the per-pose CMA-ES, warm-started pose to pose (``method: cmaes``), ``--runs``
  times: the median of its warm-started poses' search times.

The one-off plan runs in ``--one-offs`` fresh processes per pair (the first also runs the
repeats and the other methods): its figures are the median over them. Per pair the median
over the runs; over the pairs the median of those. Wall and CPU times, with the load
average before and after (a shared machine slows every figure).
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from common import machine_info

ROOT = Path(__file__).resolve().parents[1]


def one(
    k: int,
    runs: int,
    methods: tuple[str, ...] = ("sequence", "cmaes"),
    attitude_margin: float | None = None,
    turn_slide: float | None = None,
) -> dict[str, Any]:
    """Pair ``k`` in this process: the one-off roadmap plan first, then the repeats.

    ``attitude_margin`` [rad] and ``turn_slide`` [m]: the problems' ``planner`` keys instead
    of theirs (None: theirs).
    """
    t0 = time.perf_counter()
    sys.path[:0] = [str(ROOT / "tests"), str(ROOT / "tests" / "runs")]
    from test_random_routes import pair_problem

    from mmstab.core.files import PlanningError
    from mmstab.core.problem import load_problem, problem_from_dict
    from mmstab.planner import plan_problem

    imports = time.perf_counter() - t0
    folder = Path(tempfile.mkdtemp(prefix="mmstab-bench-"))
    t0 = time.perf_counter()
    problem = load_problem(pair_problem(k, folder))
    named = {"attitude_margin": attitude_margin, "turn_slide": turn_slide}
    named = {key: value for key, value in named.items() if value is not None}
    if named:
        data = copy.deepcopy(problem.data)
        data["planner"].update(named)
        problem = problem_from_dict(data, problem.path)
    load_s = time.perf_counter() - t0
    t0, c0 = time.perf_counter(), time.process_time()
    plan = plan_problem(problem)
    one_off_wall, one_off_cpu = time.perf_counter() - t0, time.process_time() - c0
    poses = len(plan.s)
    search_cpu = float(np.sum(plan.search_cpu_seconds))
    out: dict[str, Any] = {
        "pair": k,
        "poses": poses,
        "imports_s": imports,
        "load_problem_s": load_s,
        "one_off": {
            "fixed_s": getattr(plan, "fixed_seconds", float("nan")),  # nan: not reported
            "ms_per_pose": 1e3 * float(np.sum(plan.search_seconds)) / poses,
            "cpu_ms_per_pose": 1e3 * search_cpu / poses,
            "wall_s": one_off_wall,
            "cpu_s": one_off_cpu,
        },
    }
    from mmstab.workspace import load_or_build_workspace

    ws = load_or_build_workspace(problem, progress=False)
    per_pose = {"roadmap": [out["one_off"]["ms_per_pose"]], "sequence": [], "cmaes": []}
    cpu = [out["one_off"]["cpu_ms_per_pose"]]
    for _ in range(runs - 1):
        p = plan_problem(problem, ws)
        per_pose["roadmap"].append(1e3 * float(np.sum(p.search_seconds)) / poses)
        cpu.append(1e3 * float(np.sum(p.search_cpu_seconds)) / poses)
    out["roadmap_cpu_ms_per_pose"] = float(np.median(cpu))
    for method in methods:
        data = copy.deepcopy(problem.data)
        data["planner"]["method"] = method
        other = problem_from_dict(data, problem.path)
        for _ in range(runs):
            try:
                p = plan_problem(other, ws)
            except PlanningError as exc:
                out[f"{method}_failed"] = str(exc)
                break
            if method == "cmaes":  # the warm-started poses' search
                per_pose[method].append(1e3 * float(np.median(p.search_seconds[p.warm])))
            else:
                per_pose[method].append(1e3 * float(np.sum(p.search_seconds)) / len(p.s))
    out["ms_per_pose_runs"] = per_pose
    out["ms_per_pose"] = {m: float(np.median(v)) if v else None for m, v in per_pose.items()}
    return out


def _ms(x: float | None) -> str:
    return "n/a" if x is None else f"{x:.1f}"


def main() -> None:
    """Run every pair in its own process and write the medians."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, default=10, help="pairs 0 .. N-1")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument(
        "--one-offs", type=int, default=5, help="fresh processes per pair for the one-off plan"
    )
    ap.add_argument("--out", default="results/bench/plan_random.json")
    ap.add_argument("--roadmap-only", action="store_true", help="no sequence, no CMA-ES")
    ap.add_argument(
        "--attitude-margin", type=float, help="planner.attitude_margin [rad] for every pair"
    )
    ap.add_argument("--turn-slide", type=float, help="planner.turn_slide [m] for every pair")
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one is not None:
        methods = () if args.roadmap_only else ("sequence", "cmaes")
        print(json.dumps(one(args.one, args.runs, methods, args.attitude_margin, args.turn_slide)))
        return
    t_start = time.perf_counter()
    load_before = os.getloadavg()
    pairs = []
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    for k in range(args.pairs):
        cmd = [sys.executable, __file__, "--one", str(k), "--runs", str(args.runs)]
        cmd += ["--roadmap-only"] if args.roadmap_only else []
        margin = (
            [] if args.attitude_margin is None else ["--attitude-margin", str(args.attitude_margin)]
        )
        margin += [] if args.turn_slide is None else ["--turn-slide", str(args.turn_slide)]
        cmd += margin
        proc = subprocess.run(cmd, check=True, env=env, capture_output=True, text=True)
        r = json.loads(proc.stdout.strip().splitlines()[-1])
        one_offs = [r["one_off"]]
        for _ in range(args.one_offs - 1):  # the one-off alone, each in a fresh process
            cmd = [sys.executable, __file__, "--one", str(k), "--runs", "1", "--roadmap-only"]
            cmd += margin
            proc = subprocess.run(cmd, check=True, env=env, capture_output=True, text=True)
            one_offs.append(json.loads(proc.stdout.strip().splitlines()[-1])["one_off"])
        r["one_off_runs"] = one_offs
        r["one_off"] = {key: float(np.median([o[key] for o in one_offs])) for key in one_offs[0]}
        pairs.append(r)
        ms = r["ms_per_pose"]
        seq = "did not settle" if "sequence_failed" in r else _ms(ms["sequence"])
        print(
            f"pair {k}: {r['poses']} poses; roadmap one-off {r['one_off']['ms_per_pose']:.1f} "
            f"ms/pose + fixed {r['one_off']['fixed_s']:.2f} s, median of {args.runs} "
            f"{ms['roadmap']:.1f}; sequence {seq}; cmaes {_ms(ms['cmaes'])} ms/pose",
            flush=True,
        )

    def median(key: str) -> float | None:
        v = [p["ms_per_pose"][key] for p in pairs if p["ms_per_pose"][key] is not None]
        return float(np.median(v)) if v else None

    result = {
        "machine": machine_info(),
        "load_average_before": list(load_before),
        "load_average_after": list(os.getloadavg()),
        "pairs": args.pairs,
        "runs": args.runs,
        "one_offs": args.one_offs,
        "attitude_margin": args.attitude_margin,
        "turn_slide": args.turn_slide,
        "median_over_pairs": {
            "roadmap_one_off_ms_per_pose": float(
                np.median([p["one_off"]["ms_per_pose"] for p in pairs])
            ),
            "roadmap_one_off_fixed_s": float(np.median([p["one_off"]["fixed_s"] for p in pairs])),
            "roadmap_one_off_fixed_s_max": float(max(p["one_off"]["fixed_s"] for p in pairs)),
            "roadmap_ms_per_pose": median("roadmap"),
            "roadmap_cpu_ms_per_pose": float(
                np.median([p["roadmap_cpu_ms_per_pose"] for p in pairs])
            ),
            "roadmap_one_off_cpu_ms_per_pose": float(
                np.median([p["one_off"]["cpu_ms_per_pose"] for p in pairs])
            ),
            "sequence_ms_per_pose": median("sequence"),
            "sequence_settled_pairs": sum(p["ms_per_pose"]["sequence"] is not None for p in pairs),
            "cmaes_ms_per_pose": median("cmaes"),
            "load_problem_s": float(np.median([p["load_problem_s"] for p in pairs])),
            "imports_s": float(np.median([p["imports_s"] for p in pairs])),
        },
        "per_pair": pairs,
        "seconds": time.perf_counter() - t_start,
    }
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1))
    m = result["median_over_pairs"]
    print(
        f"bench-plan random routes ({args.pairs} pairs, median of {args.runs} runs each): "
        f"roadmap one-off {m['roadmap_one_off_ms_per_pose']:.1f} ms/pose, CPU "
        f"{m['roadmap_one_off_cpu_ms_per_pose']:.1f} (median of {args.one_offs} processes; "
        f"fixed costs "
        f"{m['roadmap_one_off_fixed_s']:.2f} s, worst {m['roadmap_one_off_fixed_s_max']:.2f}), "
        f"repeated {m['roadmap_ms_per_pose']:.1f} (CPU {m['roadmap_cpu_ms_per_pose']:.1f}); "
        f"sequence {_ms(m['sequence_ms_per_pose'])} "
        f"({m['sequence_settled_pairs']} settled); per-pose CMA-ES {_ms(m['cmaes_ms_per_pose'])}; "
        f"load {result['load_average_after'][0]:.1f} -> {out}"
    )


if __name__ == "__main__":
    main()
