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
  search), its total time divided by the poses;
- ``roadmap``: the whole route on the posture roadmap (``method: roadmap``), its total time
  (candidates, dynamic programming and the arm's moves) divided by the poses: ``cold``
  the first plan in this process (the roadmap read from its cache file, the nodes' CoMs,
  clusters and clearances computed), then warm (median over ``--runs``); beside it, in the
  same run, the roadmap's build time (``--rebuild-roadmap``: built here, else the cached
  file's figure), the quality of its plan (``route_quality``: gap to the per-pose optimum
  over V and over the roadmap) and OMPL's query times (RRT-Connect, PRM*) on seeded node
  pairs, from ``bench_roadmap.compare_queries``.

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
from bench_roadmap import compare_queries, query_pairs
from common import machine_info

from mmstab.core.files import write_json
from mmstab.core.problem import load_problem
from mmstab.outputs.routes import route_quality
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
from mmstab.workspace.roadmap import build_roadmap, load_or_build_roadmap


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


def roadmap_entry(problem: Any, ws: Any, region: Any, s: Any, poses: Any, settings: Any, args: Any):
    """``method: roadmap`` along the route: ms per pose cold and warm, build, quality, OMPL."""
    robot, terrain = problem.robot, problem.terrain
    t0 = time.perf_counter()
    rm = build_roadmap(robot, ws) if args.rebuild_roadmap else load_or_build_roadmap(robot, ws)
    load_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    plan = solve_route(robot, terrain, region, s, poses, settings)
    cold = 1e3 * (time.perf_counter() - t0) / len(s)
    wall, cpu = [], []
    for _ in range(args.runs):
        t0, c0 = time.perf_counter(), time.process_time()
        plan = solve_route(robot, terrain, region, s, poses, settings)
        wall.append(1e3 * (time.perf_counter() - t0) / len(s))
        cpu.append(1e3 * (time.process_time() - c0) / len(s))
    quality = route_quality(problem, plan)
    summary, straight = compare_queries(
        robot, rm, query_pairs(robot, rm, args.ompl_queries), args.ompl_budget
    )
    return {
        "ms_per_pose_warm": float(np.median(wall)),
        "ms_per_pose_warm_runs": wall,
        "cpu_ms_per_pose_warm": float(np.median(cpu)),
        "ms_per_pose_cold": cold,
        "build_seconds": rm.build_seconds,
        "built_here": bool(args.rebuild_roadmap),
        "load_or_build_seconds": load_s,
        "nodes": len(rm.nodes_q),
        "distinct_postures": len(np.unique(plan.postures, axis=0)),
        "gap_to_V_median": quality["gap_to_V_median"],
        "gap_to_V_worst": quality["gap_to_V_worst"],
        "gap_to_roadmap_median": quality["gap_to_roadmap_median"],
        "gap_to_roadmap_worst": quality["gap_to_roadmap_worst"],
        "planned_ge_stowed_every_pose": bool(np.all(plan.mu_planned >= plan.mu_stowed)),
        "queries": {
            "pairs": len(straight),
            "straight_line_median_rad": float(np.median(straight)),
            "methods": summary,
        },
    }


def main() -> None:
    """Run the route benchmark and merge its entry into ``--out``."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("problem", nargs="?", default="problems/rough.yaml")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--out", default="results/bench/plan.json")
    ap.add_argument("--rebuild-roadmap", action="store_true", help="time the roadmap's build")
    ap.add_argument("--ompl-queries", type=int, default=5, help="OMPL queries beside it")
    ap.add_argument("--ompl-budget", type=float, default=2.0, help="OMPL seconds per query")
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
    roadmap = roadmap_entry(problem, ws, region, s, poses, own._replace(method="roadmap"), args)
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
        "roadmap": roadmap,
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
    q = roadmap["queries"]["methods"]
    print(
        f"bench-plan roadmap: {roadmap['ms_per_pose_warm']:.2f} ms per pose warm (CPU "
        f"{roadmap['cpu_ms_per_pose_warm']:.2f}, cold {roadmap['ms_per_pose_cold']:.1f}), "
        f"sequence {ms['sequence']:.2f}; build {roadmap['build_seconds']:.1f} s; gap to V "
        f"median {100 * roadmap['gap_to_V_median']:.2f} %, to the roadmap median "
        f"{100 * roadmap['gap_to_roadmap_median']:.2f} %; per query: roadmap "
        f"{q['roadmap']['median_ms']:.1f} ms, shortcut {q['shortcut']['median_ms']:.1f} ms, "
        f"RRT-Connect {q['rrtconnect']['median_ms']:.0f} ms "
        f"({q['rrtconnect']['solved']} solved), PRM* "
        f"{q['prmstar']['median_ms']:.0f} ms ({q['prmstar']['solved']} solved)"
    )


if __name__ == "__main__":
    main()
