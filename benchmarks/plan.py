"""Benchmark: the planner against the exhaustive Eq. 6 reference, time and fitness gap.

Usage: ``python benchmarks/plan.py [PROBLEM.yaml] [--runs N] [--random N] [--seed S]``;
writes ``results/bench/plan.json``. Times are medians (the machine may be shared).

- ``lap``: the problem's poses in sequence (each penalised against the previous plan
  target); per pose the planner's time and the exhaustive reference's (Eq. 6 over all of
  V's samples at the same previous CoM, one batch), and the fitness gap
  ``100 (F_exhaustive - F_planner) / |F_exhaustive|`` [%] (negative: CMA-ES found an
  off-grid point better than every sample).
- ``random``: ``--random`` poses on ramps of slope <= 0.4 rad, any heading, previous CoM a
  random sample of V (``--seed``).
- Both for the problem's planner settings and for the first release's (``seeding:
  starts``, sigma0 0.05 m, population 16, 20 iterations), the peer in the same run.
- ``--alternatives``: other CMA-ES set-ups (``ALTERNATIVES``) on the same poses, written to
  ``plan_alternatives.json``.
- ``v_loss``: on the random set, the best mu over all collision-free grid CoMs against
  the best inside V [%] (what V's hull difference costs).
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np
from common import machine_info

from mmstab.core.files import write_json
from mmstab.core.problem import load_problem
from mmstab.planner import (
    PlannerSettings,
    best_mu,
    gravity_body_at,
    planning_region,
    pose_fitness,
    region_samples,
    solve_exhaustive,
    solve_path,
    solve_pose,
)
from mmstab.stability.static import mu_max
from mmstab.terrain import Ramp
from mmstab.workspace import load_or_build_workspace

#: The first release's search (today's golden numbers), for comparison.
FIRST_RELEASE = {
    "seeding": "starts",
    "starts": (2.0, 5.0),
    "sigma0": 0.05,
    "sigma0_unit": "m",
    "popsize": 16,
    "max_iterations": 20,
    "restarts": 0,
}
MAX_SLOPE = 0.4  # [rad]
#: Other searches (``--alternatives``), each as changes to the problem's planner settings.
ALTERNATIVES = {
    "coarse seed + 1 IPOP restart": {"restarts": 1},
    "8 starts around the turret, sigma0 0.15 d, pop 16, 30 it": {
        "seeding": "starts",
        "starts": tuple(np.arange(8) * np.pi / 4),
        "sigma0": 0.15,
        "sigma0_unit": "diameter",
        "popsize": 16,
        "max_iterations": 30,
        "restarts": 0,
    },
    "paper starts, sigma0 0.15 d, pop 16, 30 it, 2 IPOP restarts": {
        "seeding": "starts",
        "starts": (2.0, 5.0),
        "sigma0": 0.15,
        "sigma0_unit": "diameter",
        "popsize": 16,
        "max_iterations": 30,
        "restarts": 2,
    },
}


def _stats(values: list[float]) -> dict[str, float]:
    v = np.asarray(values, dtype=float)
    return {
        "median": float(np.median(v)),
        "max": float(v.max()),
        "over_0.5_pct": int(np.sum(v > 0.5)),
    }


def _gap(reference: float, value: float) -> float:
    return 100.0 * (reference - value) / abs(reference)


def random_cases(
    samples: np.ndarray, n: int, seed: int
) -> list[tuple[Ramp, np.ndarray, np.ndarray]]:
    """(ramp, pose, previous CoM): slope <= MAX_SLOPE, any heading, previous a sample of V."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        ramp = Ramp(rng.uniform(0.0, MAX_SLOPE))
        pose = np.array([0.0, 0.0, rng.uniform(-np.pi, np.pi)])
        out.append((ramp, pose, samples[rng.integers(len(samples))]))
    return out


def compare(
    problem: Any,
    region: Any,
    settings: PlannerSettings,
    runs: int,
    cases: list[tuple[Ramp, np.ndarray, np.ndarray]],
) -> dict[str, Any]:
    """Planner vs exhaustive on the lap and on the random cases."""
    robot = problem.robot
    samples = region_samples(region)
    norm = mu_max(robot)
    poses = problem.circle.poses(settings.poses)
    lap_ms, lap_gap, lap_ex_ms = [], [], []
    for run in range(runs):
        plan = solve_path(
            robot, problem.terrain, region, poses, settings._replace(seed=settings.seed + run)
        )
        lap_ms.extend(1e3 * t.seconds for t in plan.targets)
        previous = robot.arm_com(robot.stowed)
        for pose, t in zip(poses, plan.targets, strict=True):
            g = gravity_body_at(problem.terrain, pose)[0]
            ex = solve_exhaustive(
                pose_fitness(robot, g, previous, settings, norm, region.diameter), samples
            )
            lap_ex_ms.append(1e3 * ex.seconds)
            if run == 0:
                lap_gap.append(_gap(ex.best_fitness, t.fitness))
            previous = t.target_com
    rnd_ms, rnd_ex_ms, rnd_gap = [], [], []
    rng = np.random.default_rng(settings.seed)
    for ramp, pose, previous in cases:
        t = solve_pose(robot, ramp, region, pose, previous, settings, rng, norm)
        g = gravity_body_at(ramp, pose)[0]
        ex = solve_exhaustive(
            pose_fitness(robot, g, previous, settings, norm, region.diameter), samples
        )
        rnd_ms.append(1e3 * t.seconds)
        rnd_ex_ms.append(1e3 * ex.seconds)
        rnd_gap.append(_gap(ex.best_fitness, t.fitness))
    return {
        "settings": settings._asdict(),
        "lap": {
            "poses": len(poses),
            "median_ms_per_pose": statistics.median(lap_ms),
            "median_ms_per_pose_exhaustive": statistics.median(lap_ex_ms),
            "fitness_gap_pct": _stats(lap_gap),
            "fitness_gap_pct_per_pose": lap_gap,
        },
        "random": {
            "poses": len(cases),
            "median_ms_per_pose": statistics.median(rnd_ms),
            "median_ms_per_pose_exhaustive": statistics.median(rnd_ex_ms),
            "fitness_gap_pct": _stats(rnd_gap),
        },
    }


def main() -> None:
    """Run the benchmark and write its JSON."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("problem", nargs="?", default="problems/ramp.yaml")
    ap.add_argument("--runs", type=int, default=3, help="lap repetitions (seeds seed..seed+N-1)")
    ap.add_argument("--random", type=int, default=100, help="random poses")
    ap.add_argument("--seed", type=int, default=12, help="seed of the random poses")
    ap.add_argument("--out", default="results/bench/plan.json")
    ap.add_argument(
        "--alternatives",
        action="store_true",
        help="also run ALTERNATIVES (slow) -> plan_alternatives.json beside --out",
    )
    args = ap.parse_args()
    problem = load_problem(args.problem)
    ws = load_or_build_workspace(problem, progress=False)
    region = planning_region(ws, problem.section("workspace")["method"])
    samples = region_samples(region)
    settings = PlannerSettings.from_section(problem.section("planner"))
    cases = random_cases(samples, args.random, args.seed)
    t0 = time.perf_counter()
    current = compare(problem, region, settings, args.runs, cases)
    first = compare(problem, region, settings._replace(**FIRST_RELEASE), args.runs, cases)
    robot = problem.robot
    loss = []
    for ramp, pose, _ in cases:
        g = gravity_body_at(ramp, pose)[0]
        best_valid = best_mu(robot, g, ws.valid_com)[0]
        loss.append(100.0 * (best_valid - best_mu(robot, g, ws.valid_com_in_V)[0]) / best_valid)
    result = {
        "problem": str(problem.path),
        "machine": machine_info(),
        "workspace": {
            "method": problem.section("workspace")["method"],
            "grid": list(ws.grid),
            "samples_in_region": len(samples),
            "valid_samples": len(ws.valid_com),
        },
        "random_seed": args.seed,
        "max_slope_rad": MAX_SLOPE,
        "planner": current,
        "first_release": first,
        "v_loss_pct_random": _stats(loss) | {"min": float(np.min(loss))},
        "seconds": time.perf_counter() - t0,
    }
    write_json(Path(args.out), result)
    if args.alternatives:
        alt = {
            name: compare(problem, region, settings._replace(**changes), 1, cases)
            for name, changes in ALTERNATIVES.items()
        }
        alt["default"] = current
        write_json(Path(args.out).with_name("plan_alternatives.json"), alt)
        for name, r in alt.items():
            c = r["random"]
            print(
                f"{name}: random {c['median_ms_per_pose']:.1f} ms/pose (exhaustive "
                f"{c['median_ms_per_pose_exhaustive']:.1f}), gap median "
                f"{c['fitness_gap_pct']['median']:+.3f} %, max {c['fitness_gap_pct']['max']:+.3f} %"
            )
    for name, r in (("planner", current), ("first release", first)):
        for where in ("lap", "random"):
            c = r[where]
            print(
                f"{name:13s} {where:6s}: {c['median_ms_per_pose']:6.1f} ms/pose vs exhaustive "
                f"{c['median_ms_per_pose_exhaustive']:6.1f}; gap median "
                f"{c['fitness_gap_pct']['median']:+.3f} %, max {c['fitness_gap_pct']['max']:+.3f} %"
                f", {c['fitness_gap_pct']['over_0.5_pct']} poses > 0.5 %"
            )
    print(f"V loss (random poses): median {np.median(loss):.2f} %, max {np.max(loss):.2f} %")


if __name__ == "__main__":
    main()
