"""Benchmark: resting poses on the shipped terrains, batched over poses vs one at a time.

Usage: ``python benchmarks/bench_terrain.py [PROBLEM.yaml ...] [--poses N] [--runs R]``;
writes ``results/bench/terrain.json``. Poses are drawn (seeded) uniformly over each map,
inside the robot's reach of the edge, headings uniform. Reports medians over the runs
(the machine may be shared): milliseconds per pose amortised over a batch of N (wall, and
this process's CPU time, which a busy machine inflates less), and per pose called one by
one; the rounds each pose took and the flags raised. Three paths, interleaved in the same
run on the same poses: the C kernel (the default, ``backend="c"``), its NumPy twin
(``backend="numpy"``, the same algorithm; the peer) and the kernel on all candidates in
every round (the reference path, ``active_candidates=0``), with the largest differences
between their rests. Target: <= 0.1 ms per pose batched (the published C++
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

from mmstab.core.files import write_json
from mmstab.core.problem import load_problem
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


FLAGS = ("converged", "high_centred", "line_contact", "tips_over")


def same_flags(a: Any, b: Any) -> bool:
    """Both rests raise the same flags at every pose."""
    return all(np.array_equal(getattr(a, k), getattr(b, k)) for k in FLAGS)


def max_difference(a: Any, b: Any) -> float:
    """Largest roll or pitch difference between two rests [rad]."""
    return float(np.nanmax(np.maximum(np.abs(a.roll - b.roll), np.abs(a.pitch - b.pitch))))


def bench(path: str, n: int, runs: int, singles: int) -> dict[str, Any]:
    """Time one problem's terrain: the C kernel, its NumPy twin and the reference path."""
    problem = load_problem(path)
    terrain = problem.terrain
    if not isinstance(terrain, HeightmapTerrain):
        raise SystemExit(f"{path}: not a heightmap problem")
    poses = random_poses(terrain, n)

    def variant(**changes: Any) -> HeightmapTerrain:
        return dataclasses.replace(terrain, settings=terrain.settings._replace(**changes))

    paths = {
        "c": terrain,  # the default: the C kernel
        "numpy": variant(backend="numpy"),  # the same algorithm in NumPy
        "reference": variant(active_candidates=0),  # the kernel on all candidates every round
    }
    for t_ in paths.values():
        t_.rest(poses[:10])  # warm caches (compiled kernel, candidates, CoM)
    wall: dict[str, list[float]] = {k: [] for k in paths}
    cpu: dict[str, list[float]] = {k: [] for k in paths}
    rests: dict[str, Any] = {}
    for _ in range(runs):  # interleaved: all paths see the same machine load
        for name, t_ in paths.items():
            t, c = time.perf_counter(), time.process_time()
            rests[name] = t_.rest(poses)
            wall[name].append((time.perf_counter() - t) / n * 1e3)
            cpu[name].append((time.process_time() - c) / n * 1e3)
    one: dict[str, list[float]] = {"c": [], "numpy": []}
    for _ in range(runs):
        for name in one:
            t = time.perf_counter()
            for p in poses[:singles]:
                paths[name].rest(p)
            one[name].append((time.perf_counter() - t) / singles * 1e3)
    r, med = rests["c"], statistics.median
    return {
        "problem": path,
        "terrain": terrain.heightmap.source,
        "cells": list(terrain.heightmap.shape),
        "resolution_m": terrain.heightmap.resolution,
        "candidates": len(terrain.candidates.points),
        "poses": n,
        "backend": terrain.settings.backend,
        "ms_per_pose_batched_median": med(wall["c"]),
        "ms_per_pose_batched_runs": wall["c"],
        "cpu_ms_per_pose_batched_median": med(cpu["c"]),
        "numpy_path_ms_per_pose_batched_median": med(wall["numpy"]),
        "numpy_path_cpu_ms_per_pose_batched_median": med(cpu["numpy"]),
        "speed_up_over_numpy_path_wall": med(wall["numpy"]) / med(wall["c"]),
        "max_attitude_difference_to_numpy_path_rad": max_difference(r, rests["numpy"]),
        "same_flags_as_numpy_path": same_flags(r, rests["numpy"]),
        "reference_path_ms_per_pose_batched_median": med(wall["reference"]),
        "reference_path_cpu_ms_per_pose_batched_median": med(cpu["reference"]),
        "max_attitude_difference_to_reference_rad": max_difference(r, rests["reference"]),
        "same_flags_as_reference": same_flags(r, rests["reference"]),
        "ms_per_pose_single_median": med(one["c"]),
        "numpy_path_ms_per_pose_single_median": med(one["numpy"]),
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
            f"{row['problem']}: {row['ms_per_pose_batched_median']:.4f} ms/pose batched, C "
            f"({row['poses']} poses; NumPy path {row['numpy_path_ms_per_pose_batched_median']:.4f}"
            f", max difference {row['max_attitude_difference_to_numpy_path_rad']:.1e} rad; "
            f"reference path {row['reference_path_ms_per_pose_batched_median']:.4f}), "
            f"{row['ms_per_pose_single_median']:.3f} ms/pose one by one "
            f"(NumPy {row['numpy_path_ms_per_pose_single_median']:.3f});"
            f" rounds median {row['rounds_median']:.0f}, max {row['rounds_max']}"
        )
    out = write_json(
        Path(a.out),
        {
            "what": "resting pose of the tracked base on heightmaps (mmstab.terrain.rest): "
            "the C kernel (default), its NumPy twin and the all-candidates reference path",
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
