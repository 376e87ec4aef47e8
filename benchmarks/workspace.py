"""Benchmark: build the default workspace grid from scratch (no cache) a few times.

Usage: ``python benchmarks/workspace.py [PROBLEM.yaml] [--runs N]``; writes
``results/bench/workspace.json``. Reports medians: the machine may be shared.
Also times the two FCL strategies on the same postures (per-pair ``fcl.collide`` vs a
``DynamicAABBTreeCollisionManager`` of the base parts) and counts the FCL calls the
culling leaves for the whole grid.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from concurrent.futures import Executor, Future
from pathlib import Path
from typing import Any

import fcl
import numpy as np
from common import machine_info

from mmstab.core.files import write_json
from mmstab.core.problem import load_problem
from mmstab.model.collision import CollisionChecker
from mmstab.model.robot import Robot
from mmstab.workspace import build_workspace, grid_postures, joint_grid


class SerialExecutor(Executor):
    """Runs each task at once in this process (one core), for comparison."""

    def submit(self, fn: Any, /, *args: Any, **kwargs: Any) -> Future[Any]:
        """Run ``fn(*args, **kwargs)`` now; return its completed future."""
        f: Future[Any] = Future()
        f.set_result(fn(*args, **kwargs))
        return f


def fcl_strategies(robot: Robot, n: int = 5000, seed: int = 0) -> dict[str, float]:
    """Microseconds per posture to test the wrist against the five base parts, two ways."""
    cc = CollisionChecker(robot)
    q = np.random.default_rng(seed).uniform(robot.joint_lower, robot.joint_upper, (n, 4))
    R, p = cc.shape_poses(q)
    wrist, parts = cc._link_objs[3], list(cc._base_objs.values())
    req = fcl.CollisionRequest()
    t = time.perf_counter()
    for k in range(n):
        wrist.setTransform(fcl.Transform(R[k, 3], p[k, 3]))
        for o in parts:
            fcl.collide(wrist, o, req, fcl.CollisionResult())
    per_pair = (time.perf_counter() - t) / n * 1e6
    manager = fcl.DynamicAABBTreeCollisionManager()
    manager.registerObjects(parts)
    manager.setup()
    t = time.perf_counter()
    for k in range(n):
        wrist.setTransform(fcl.Transform(R[k, 3], p[k, 3]))
        manager.collide(wrist, fcl.CollisionData(), fcl.defaultCollisionCallback)
    broadphase = (time.perf_counter() - t) / n * 1e6
    return {"per_pair_us_per_posture": per_pair, "broadphase_us_per_posture": broadphase}


def fcl_calls(robot: Robot, grid: tuple[int, ...]) -> dict[str, int]:
    """FCL calls made for the whole grid (after reuse and culling) vs all pairs."""
    cc = CollisionChecker(robot)
    count = 0
    inner = cc._fcl

    def counting(pair: Any, R: Any, p: Any, rows: Any) -> Any:
        nonlocal count
        count += len(rows)
        return inner(pair, R, p, rows)

    cc._fcl = counting  # type: ignore[method-assign]
    jg = joint_grid(robot, grid)
    for s in range(0, jg.size, 16384):
        cc.collides(grid_postures(jg, s, min(s + 16384, jg.size)))
    return {"fcl_calls": count, "pairs_without_culling": jg.size * len(cc.pairs)}


def main() -> None:
    """Run the benchmark and write ``results/bench/workspace.json``."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("problem", nargs="?", default="problems/ramp.yaml")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--out", default="results/bench/workspace.json")
    args = ap.parse_args()
    problem = load_problem(args.problem)
    grid = tuple(problem.section("workspace")["grid"])
    seconds = []
    for _ in range(args.runs):
        t = time.perf_counter()
        ws = build_workspace(problem.robot, grid, progress=False)
        seconds.append(time.perf_counter() - t)
    t = time.perf_counter()
    build_workspace(problem.robot, grid, executor=SerialExecutor(), progress=False)
    serial = time.perf_counter() - t
    total = ws.postures
    result = {
        "grid": list(grid),
        "postures": total,
        "valid": len(ws.valid_com),
        "invalid": len(ws.invalid_com),
        "runs": args.runs,
        "seconds": seconds,
        "median_seconds": statistics.median(seconds),
        "median_postures_per_second": total / statistics.median(seconds),
        "serial_seconds": serial,
        "target_seconds": 10.0,
        **fcl_calls(problem.robot, grid),
        **fcl_strategies(problem.robot),
        "cpu_count": os.cpu_count(),
        "machine": machine_info(),
        "note": "wall time on a shared 2-core machine: medians, noisy",
    }
    write_json(Path(args.out), result)
    print(
        f"workspace {grid}: median {result['median_seconds']:.2f} s over {args.runs} runs, "
        f"{result['median_postures_per_second']:.0f} postures/s -> {args.out}"
    )


if __name__ == "__main__":
    main()
