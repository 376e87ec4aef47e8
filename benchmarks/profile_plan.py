"""Profile: where a one-off ``mmstab plan`` of a seeded random route spends its time.

Usage: ``python benchmarks/profile_plan.py [--pairs 0 1 2] [--out FILE]``. Each pair (the
seeded random map and route of ``tests/runs/test_random_routes.py``, default grid, every default
check on) is planned in a fresh process, as ``mmstab plan`` would (the workspace V and the
roadmap from their caches, built first if missing), under cProfile; the process's time is
split into the stages below (a function's cumulative time, the stages disjoint by
construction of the call tree) and written to ``results/bench/profile_plan.json``, with
each pair's 25 costliest functions by own time. The profile counts CPU time of the process
(``time.process_time``: a shared machine's other jobs left out), the pair's ``wall_s`` wall
time. A profile, not a benchmark: cProfile slows Python-heavy stages more than C-heavy ones.
"""

from __future__ import annotations

import argparse
import cProfile
import json
import os
import pstats
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
#: The stages: a label and the (file suffix, function) whose cumulative time is the stage's.
STAGES = (
    ("load_problem", "core/problem.py", "load_problem"),
    ("load_workspace", "workspace/cache.py", "load_or_build_workspace"),
    ("load_roadmap", "workspace/roadmap.py", "load_or_build_roadmap"),
    ("resting_poses", "planner/pose.py", "gravity_body_at"),
    ("component_view", "planner/searches/roadmap/__init__.py", "component_view"),
    ("ground_under_arm_setup", "planner/ground/under_arm.py", "__init__"),
    ("climb_plan", "planner/climbing.py", "climb_plan"),
    ("candidates", "planner/candidates.py", "route_candidates"),
    ("node_ground_check", "planner/candidates.py", "measure"),
    ("motion_and_transitions", "planner/motion.py", "transitions"),
    ("one_mu_rests", "planner/searches/roadmap/rounds.py", "mu"),
    ("moves_and_their_ground_check", "planner/searches/roadmap/rounds.py", "moves"),
    ("moves_clearance_checks", "model/collision.py", "keeps_clearance"),
    ("dynamic_programming", "planner/searches/sequence.py", "best_sequence"),
    ("stability_along", "stability/support.py", "stability_along"),
    ("plan_total", "planner/plan.py", "plan_problem"),
)


def one(k: int, out: Path) -> None:
    """Pair ``k`` planned in this process under cProfile; the stats dumped to ``out``."""
    sys.path[:0] = [str(ROOT / "tests"), str(ROOT / "tests" / "runs")]
    from test_random_routes import pair_problem

    from mmstab.core.problem import load_problem
    from mmstab.planner import plan_problem

    folder = Path(tempfile.mkdtemp(prefix="mmstab-profile-"))
    path = pair_problem(k, folder)
    prof = cProfile.Profile(time.process_time)  # CPU time: less sensitive to other jobs
    t0 = time.perf_counter()
    prof.enable()
    plan = plan_problem(load_problem(path), None)
    prof.disable()
    wall = time.perf_counter() - t0
    prof.dump_stats(str(out))
    Path(str(out) + ".json").write_text(json.dumps({"wall_s": wall, "poses": len(plan.s)}))


def stages(stats_file: Path) -> tuple[dict[str, float], list[dict[str, Any]]]:
    """Cumulative seconds per stage, and the costliest functions by own time."""
    st = pstats.Stats(str(stats_file))
    raw = st.stats  # type: ignore[attr-defined]
    out: dict[str, float] = {}
    for label, suffix, name in STAGES:
        out[label] = sum(v[3] for (f, _, fn), v in raw.items() if fn == name and f.endswith(suffix))
    top = sorted(raw.items(), key=lambda kv: kv[1][2], reverse=True)[:25]
    costly = [
        {
            "function": f"{Path(f).name}:{line}:{fn}",
            "own_s": v[2],
            "cumulative_s": v[3],
            "calls": v[1],
        }
        for (f, line, fn), v in top
    ]
    return out, costly


def main() -> None:
    """Profile the pairs, each in its own process, and write the split."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--out", default="results/bench/profile_plan.json")
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--stats", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one is not None:
        one(args.one, Path(args.stats))
        return
    result: dict[str, Any] = {"load_average_before": os.getloadavg(), "pairs": []}
    with tempfile.TemporaryDirectory() as tmp:
        for k in args.pairs:
            stats = Path(tmp) / f"pair{k}.prof"
            cmd = [sys.executable, __file__, "--one", str(k), "--stats", str(stats)]
            subprocess.run(cmd, check=True, env={**os.environ, "PYTHONPATH": str(ROOT)})
            info = json.loads(Path(str(stats) + ".json").read_text())
            split, costly = stages(stats)
            result["pairs"].append({"pair": k, **info, "stages_s": split, "costliest": costly})
            per = 1e3 * split["plan_total"] / info["poses"]
            print(
                f"pair {k}: {info['poses']} poses, {info['wall_s']:.2f} s wall, "
                f"{split['plan_total']:.2f} s CPU ({per:.0f} ms/pose, profiled)"
            )
            for label, sec in split.items():
                print(f"  {label:30s} {sec:7.3f} s")
    result["load_average_after"] = os.getloadavg()
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1))
    print(f"-> {out}")


if __name__ == "__main__":
    main()
