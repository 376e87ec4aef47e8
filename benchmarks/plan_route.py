"""Benchmark: the planner along a route, ms per pose and the gap to the exhaustive Eq. 6.

Usage: ``python benchmarks/plan_route.py [PROBLEM.yaml] [--runs N] [--out FILE]``; adds
(or replaces) the ``route`` entry of ``results/bench/plan.json``, keeping its other entries
(the ramp's, from ``benchmarks/plan.py``). Times are medians over ``--runs`` (the machine
may be shared).

Per warm-started pose (every pose after the first), in the same run:

- ``warm``: the route planner (:func:`mmstab.planner.solve_route`, warm CMA-ES with
  the population as one NumPy batch, the coarse guard);
- ``warm_pycma``: the same starts and step size through ``solve_pose`` (pycma);
- ``cold``: ``solve_pose`` with the problem's own search at every pose (no warm start);
- ``exhaustive``: Eq. 6 over all of V's samples at the same previous CoM (one batch), the
  reference of the fitness gap ``100 (F_exhaustive - F) / |F_exhaustive|`` [%] (negative:
  CMA-ES found an off-grid CoM better than every sample);
- ``sequence``: the whole route at once (``method: sequence``, the shipped route problems'
  search), its total time divided by the poses.

The resting poses are computed once per run in one batch; their share is counted in every
pose's time. No IK (postures) here: the search alone. Wall times and, less sensitive to
other processes on a shared machine, CPU times of this process (with the load average).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path
from typing import Any

import numpy as np
from common import machine_info

from mmstab.core.files import write_json
from mmstab.core.problem import load_problem
from mmstab.paths.route import DEFAULT_SPACING, route_samples
from mmstab.planner import (
    PlannerSettings,
    planning_region,
    pose_fitness,
    region_samples,
    solve_exhaustive,
    solve_pose,
    solve_route,
)
from mmstab.stability.static import mu_max
from mmstab.workspace import load_or_build_workspace


def gaps(problem: Any, region: Any, plan: Any, samples: np.ndarray) -> tuple[list[float], float]:
    """Fitness gap per pose [%] against the exhaustive reference, and its ms per pose."""
    robot = problem.robot
    gravity = problem.terrain.gravity_body(plan.poses)
    previous = robot.arm_com(robot.stowed)
    out, seconds = [], []
    for k, t in enumerate(plan.targets):
        fit = pose_fitness(
            robot, gravity[k], previous, plan.settings, mu_max(robot), region.diameter
        )
        t0 = time.perf_counter()
        best = solve_exhaustive(fit, samples).best_fitness
        seconds.append(time.perf_counter() - t0)
        out.append(100.0 * (best - float(fit(t.target_com)[0])) / abs(best))
        previous = t.target_com
    return out, 1e3 * float(np.median(seconds))


def cold_ms(problem: Any, region: Any, plan: Any, settings: PlannerSettings) -> float:
    """Median ms per pose of ``solve_pose`` with the problem's search at the plan's poses."""
    robot = problem.robot
    rng = np.random.default_rng(settings.seed)
    times = []
    for k, t in enumerate(plan.targets[1:], start=1):
        t0 = time.perf_counter()
        solve_pose(robot, problem.terrain, region, t.pose, plan.target_com[k - 1], settings, rng)
        times.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(times))


def main() -> None:
    """Run the route benchmark and merge its entry into ``--out``."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("problem", nargs="?", default="problems/rough.yaml")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--out", default="results/bench/plan.json")
    args = ap.parse_args()
    t_start = time.perf_counter()
    problem = load_problem(args.problem)
    route = problem.route
    if route is None:
        raise SystemExit(f"{args.problem}: path: not a route")
    ws = load_or_build_workspace(problem, progress=False)
    region = planning_region(ws, problem.section("workspace")["method"])
    samples = region_samples(region)
    section = problem.section("planner")
    # the warm-started per-pose search (method: cmaes), whatever the file plans with; the
    # whole-route search (method: sequence, the shipped default) is timed next to it
    own = PlannerSettings.from_section(section)
    settings = own._replace(method="cmaes")
    sequence = own._replace(method="sequence")
    s = route_samples(route.length, float(section.get("spacing", DEFAULT_SPACING)))
    poses = route.route.sample(s).pose
    robot, terrain = problem.robot, problem.terrain
    solve_route(robot, terrain, region, s, poses, settings)  # warm-up (caches, imports)
    warm_ms, pycma_ms, first_ms, warm_cpu, pycma_cpu, seq_ms = [], [], [], [], [], []
    solve_route(robot, terrain, region, s, poses, sequence)  # warm-up of its caches
    for _ in range(args.runs):
        seq = solve_route(robot, terrain, region, s, poses, sequence)
        seq_ms.append(1e3 * float(np.mean(seq.search_seconds)))
        plan = solve_route(robot, terrain, region, s, poses, settings)
        warm_ms.append(1e3 * float(np.median(plan.search_seconds[1:])))
        warm_cpu.append(1e3 * float(np.median(plan.search_cpu_seconds[1:])))
        first_ms.append(1e3 * float(plan.search_seconds[0]))
        peer = solve_route(robot, terrain, region, s, poses, settings, search="solve_pose")
        pycma_ms.append(1e3 * float(np.median(peer.search_seconds[1:])))
        pycma_cpu.append(1e3 * float(np.median(peer.search_cpu_seconds[1:])))
    gap, exhaustive_ms = gaps(problem, region, plan, samples)
    gap_pycma, _ = gaps(problem, region, peer, samples)
    entry = {
        "problem": str(problem.path),
        "machine": machine_info(),
        "route_length_m": route.length,
        "poses": len(s),
        "spacing_m": float(np.median(np.diff(s))),
        "runs": args.runs,
        "ms_per_pose": {
            "warm": float(np.median(warm_ms)),
            "warm_pycma": float(np.median(pycma_ms)),
            "cold_solve_pose": cold_ms(problem, region, plan, settings),
            "exhaustive": exhaustive_ms,
            "first_pose_cold": float(np.median(first_ms)),
            "sequence": float(np.median(seq_ms)),
        },
        "cpu_ms_per_pose": {
            "warm": float(np.median(warm_cpu)),
            "warm_pycma": float(np.median(pycma_cpu)),
        },
        "load_average_1min": os.getloadavg()[0],
        "gap_pct": {
            "warm": {"max": max(gap), "median": float(np.median(gap))},
            "warm_pycma": {"max": max(gap_pycma), "median": float(np.median(gap_pycma))},
        },
        "within_0.5_pct_every_pose": bool(max(gap) <= 0.5),
        "planned_ge_stowed_every_pose": bool(np.all(plan.mu_planned >= plan.mu_stowed)),
        "guard_starts": int(plan.guarded.sum()),
        "seconds": time.perf_counter() - t_start,
    }
    out = Path(args.out)
    result = json.loads(out.read_text()) if out.is_file() else {}
    result["route"] = entry
    write_json(out, result)
    ms = entry["ms_per_pose"]
    print(
        f"bench-plan route: {len(s)} poses over {route.length:.1f} m; ms per warm pose "
        f"{ms['warm']:.2f} (pycma {ms['warm_pycma']:.2f}, cold {ms['cold_solve_pose']:.2f}, "
        f"exhaustive {ms['exhaustive']:.2f}); CPU ms per warm pose "
        f"{entry['cpu_ms_per_pose']['warm']:.2f}; gap max {max(gap):.3f} % -> {out}"
    )


if __name__ == "__main__":
    main()
