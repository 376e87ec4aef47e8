"""Benchmark: resting poses on the shipped terrains, batched over poses vs one at a time.

Usage: ``python benchmarks/bench_terrain.py [PROBLEM.yaml ...] [--poses N] [--runs R]``;
writes ``results/bench/terrain.json``. Poses are drawn (seeded) uniformly over each map,
inside the robot's reach of the edge, headings uniform. Reports medians over the runs
(the machine may be shared): milliseconds per pose amortised over a batch of N (wall, and
this process's CPU time, which a busy machine inflates less), and per pose called one by
one; the rounds each pose took and the flags raised. In the same run, interleaved with
it, the reference path (all candidates in every round, ``active_candidates=0``) on the
same poses, and the largest difference between the
two paths' rests. Target of issue 14: <= 0.1 ms per pose batched (the published C++
contact estimator for tracked robots reports about 0.5 ms per pose; not run here).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np
from common import machine_info

from mmstab.config import write_json
from mmstab.problem import load_problem
from mmstab.terrain.heightmap_terrain import HeightmapTerrain

DEFAULT = ["problems/rough.yaml", "problems/kerb.yaml", "problems/dem.yaml"]


def random_poses(terrain: HeightmapTerrain, n: int, seed: int = 0) -> np.ndarray:
    """``n`` poses (x, y, yaw) over the map, inside the robot's reach of its edge."""
    reach = float(np.max(np.linalg.norm(terrain.candidates.points, axis=1)))  # any attitude
    x0, x1, y0, y1 = terrain.heightmap.bounds
    rng = np.random.default_rng(seed)
    return np.c_[
        rng.uniform(x0 + reach, x1 - reach, n),
        rng.uniform(y0 + reach, y1 - reach, n),
        rng.uniform(-np.pi, np.pi, n),
    ]


def bench(path: str, n: int, runs: int, singles: int) -> dict[str, Any]:
    """Time one problem's terrain."""
    problem = load_problem(path)
    terrain = problem.terrain
    if not isinstance(terrain, HeightmapTerrain):
        raise SystemExit(f"{path}: not a heightmap problem")
    poses = random_poses(terrain, n)
    reference = dataclasses.replace(
        terrain, settings=terrain.settings._replace(active_candidates=0)
    )
    terrain.rest(poses[:10])  # warm caches (candidates, CoM)
    reference.rest(poses[:10])
    batch, cpu, ref_batch, ref_cpu = [], [], [], []
    for _ in range(runs):  # interleaved: both paths see the same machine load
        for t_, wall, proc in ((terrain, batch, cpu), (reference, ref_batch, ref_cpu)):
            t, c = time.perf_counter(), time.process_time()
            r_ = t_.rest(poses)
            wall.append((time.perf_counter() - t) / n * 1e3)
            proc.append((time.process_time() - c) / n * 1e3)
            if t_ is terrain:
                r = r_
            else:
                ref = r_
    diff = np.maximum(np.abs(r.roll - ref.roll), np.abs(r.pitch - ref.pitch))
    one = []
    for _ in range(runs):
        t = time.perf_counter()
        for p in poses[:singles]:
            terrain.rest(p)
        one.append((time.perf_counter() - t) / singles * 1e3)
    return {
        "problem": path,
        "terrain": terrain.heightmap.source,
        "cells": list(terrain.heightmap.shape),
        "resolution_m": terrain.heightmap.resolution,
        "candidates": len(terrain.candidates.points),
        "poses": n,
        "ms_per_pose_batched_median": statistics.median(batch),
        "ms_per_pose_batched_runs": batch,
        "cpu_ms_per_pose_batched_median": statistics.median(cpu),
        "reference_path_ms_per_pose_batched_median": statistics.median(ref_batch),
        "reference_path_cpu_ms_per_pose_batched_median": statistics.median(ref_cpu),
        "speed_up_cpu": statistics.median(ref_cpu) / statistics.median(cpu),
        "max_attitude_difference_to_reference_rad": float(np.nanmax(diff)),
        "same_flags_as_reference": bool(
            all(
                np.array_equal(getattr(r, k), getattr(ref, k))
                for k in ("converged", "high_centred", "line_contact", "tips_over")
            )
        ),
        "ms_per_pose_single_median": statistics.median(one),
        "single_poses_timed": singles,
        "rounds_median": float(np.median(r.iterations)),
        "rounds_max": int(r.iterations.max()),
        "converged_share": float(r.converged.mean()),
        "not_converged": int((~r.converged & ~r.tips_over).sum()),
        "high_centred": int(r.high_centred.sum()),
        "line_contact": int(r.line_contact.sum()),
        "tips_over": int(r.tips_over.sum()),
    }


def main() -> None:
    """Run the benchmark and write the JSON."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("problems", nargs="*", default=DEFAULT)
    ap.add_argument("--poses", type=int, default=4000)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--singles", type=int, default=200)
    ap.add_argument("-o", "--out", default="results/bench/terrain.json")
    a = ap.parse_args()
    rows = [bench(p, a.poses, a.runs, a.singles) for p in a.problems]
    for row in rows:
        print(
            f"{row['problem']}: {row['ms_per_pose_batched_median']:.4f} ms/pose batched "
            f"(CPU {row['cpu_ms_per_pose_batched_median']:.4f}) "
            f"({row['poses']} poses; reference path CPU "
            f"{row['reference_path_cpu_ms_per_pose_batched_median']:.4f}, "
            f"max difference {row['max_attitude_difference_to_reference_rad']:.1e} rad), "
            f"{row['ms_per_pose_single_median']:.3f} ms/pose one by one;"
            f" rounds median {row['rounds_median']:.0f}, max {row['rounds_max']}"
        )
    out = write_json(
        Path(a.out),
        {
            "what": "resting pose of the tracked base on heightmaps (mmstab.terrain.rest)",
            "target_ms_per_pose": 0.1,
            "reference_cpp_ms_per_pose": 0.5,
            "reference_note": "published C++ contact estimator for tracked robots; not run here",
            "machine": machine_info(),
            "load_average_1_5_15min": list(os.getloadavg()),
            "results": rows,
        },
    )
    print(f"bench-terrain: wrote {out}")


if __name__ == "__main__":
    main()
