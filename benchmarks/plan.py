"""Benchmark: CMA-ES planning time per base pose and for the whole path, and its quality.

Usage: ``python benchmarks/plan.py [PROBLEM.yaml] [--runs N]``; writes
``results/bench/plan.json``. Times are medians (the machine may be shared). The
per-pose time covers both CMA-ES starts (the paper's two), not the IK; the path time
covers the ten poses in sequence, with and without the IK that realises each target.
Quality: the fitness reached, against a long reference run (population 20, 200
iterations per start) at the same poses and previous CoMs.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np
from common import machine_info

from mmstab.config import write_json
from mmstab.ik import PostureSolver
from mmstab.planner import PlannerSettings, solve_path, solve_pose, start_coms
from mmstab.problem import load_problem
from mmstab.workspace import load_or_build_workspace


def main() -> None:
    """Run the benchmark and write its JSON."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("problem", nargs="?", default="problems/ramp.yaml")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--out", default="results/bench/plan.json")
    args = ap.parse_args()
    problem = load_problem(args.problem)
    robot, ramp = problem.robot, problem.terrain
    ws = load_or_build_workspace(problem, progress=False)
    settings = PlannerSettings.from_section(problem.section("planner"))
    poses = problem.circle.poses(settings.poses)
    starts = start_coms(robot, ws, settings.starts)
    solver = PostureSolver(robot, ws)

    per_pose, path_cma, path_ik = [], [], []
    for run in range(args.runs):
        s = settings._replace(seed=settings.seed + run)
        t0 = time.perf_counter()
        plan = solve_path(robot, ramp, ws, poses, s)
        path_cma.append(time.perf_counter() - t0)
        per_pose.extend(t.seconds for t in plan.targets)
        t0 = time.perf_counter()
        solve_path(robot, ramp, ws, poses, s, solver.realise)
        path_ik.append(time.perf_counter() - t0)

    reference = settings._replace(popsize=20, max_iterations=200, tol_x=1e-7, tol_fitness=1e-12)
    gaps = []
    rng = np.random.default_rng(settings.seed)
    previous = robot.arm_com(robot.stowed)
    for pose, target in zip(poses, plan.targets, strict=True):
        ref = solve_pose(robot, ramp, ws, pose, previous, reference, rng, starts=starts)
        gaps.append(ref.fitness - target.fitness)
        previous = target.target_com
    result = {
        "problem": str(problem.path),
        "machine": machine_info(),
        "settings": settings._asdict(),
        "runs": args.runs,
        "median_ms_per_pose": 1e3 * statistics.median(per_pose),
        "median_ms_path_cma": 1e3 * statistics.median(path_cma),
        "median_ms_path_with_ik": 1e3 * statistics.median(path_ik),
        "target_ms_per_pose": 50.0,
        "fitness_gap_vs_reference": {
            "mean": float(np.mean(gaps)),
            "max": float(np.max(gaps)),
            "reference": {"popsize": 20, "max_iterations": 200},
        },
    }
    write_json(Path(args.out), result)
    print(
        f"plan: {result['median_ms_per_pose']:.1f} ms per pose (median, both starts), "
        f"path {result['median_ms_path_cma']:.0f} ms "
        f"(with IK {result['median_ms_path_with_ik']:.0f} ms)"
        f"; fitness gap to a 200-iteration run: mean {np.mean(gaps):.3f}, max {np.max(gaps):.3f}"
    )


if __name__ == "__main__":
    main()
