"""Benchmark: are the size estimates of ``mmstab.core.sizes`` bounds on this machine?

Usage: ``python benchmarks/sizes.py [PROBLEM.yaml] [--runs N]``; writes
``results/bench/sizes.json``. For one modest instance of each stage it measures the wall
time (median of ``--runs``) and, for the workspace and the tracking run, the peak memory
the Python heap saw (``tracemalloc``, a separate run), and puts beside them what
``mmstab.core.sizes`` estimates for the same instance. ``ratio`` = estimate / measured: above 1
the estimate is a conservative bound (what the size checks need), below 1 it is not.
"""

from __future__ import annotations

import argparse
import copy
import statistics
import time
import tracemalloc
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from common import machine_info

from mmstab.core import sizes
from mmstab.core.files import write_json
from mmstab.core.problem import Problem, load_problem, problem_from_dict


def _median_seconds(fn: Callable[[], Any], runs: int) -> float:
    times = []
    for _ in range(runs):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def _peak_bytes(fn: Callable[[], Any]) -> int:
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def _edited(problem: Problem, **sections: dict[str, Any]) -> Problem:
    data = copy.deepcopy(problem.data)
    for name, values in sections.items():
        data[name].update(values)
    return problem_from_dict(data, problem.path)


def _row(est: sizes.Estimate, seconds: float, peak: int | None = None) -> dict[str, Any]:
    row = {
        "field": est.field,
        "instance": est.work,
        "measured_s": seconds,
        "estimated_s": est.seconds,
        "ratio_s": est.seconds / seconds,
    }
    if peak is not None:
        row |= {"measured_peak_B": peak, "estimated_B": est.bytes, "ratio_B": est.bytes / peak}
    return row


def main() -> None:
    """Measure each stage, compare with the estimates, write the JSON."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("problem", nargs="?", default="problems/ramp.yaml")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--out", default="results/bench/sizes.json")
    args = ap.parse_args()
    base = load_problem(args.problem)
    robot = base.robot
    rows: dict[str, dict[str, Any]] = {}

    from mmstab.workspace import build_workspace, load_or_build_workspace

    grid = list(base.section("workspace")["grid"])
    build_workspace(robot, [4, 3, 3, 3], progress=False)  # warm up
    rows["workspace"] = _row(
        sizes.workspace_estimate(grid),
        _median_seconds(lambda: build_workspace(robot, grid, progress=False), args.runs),
        _peak_bytes(lambda: build_workspace(robot, grid, progress=False)),
    )

    from experiments.sweeps import link0_sweep

    sw = base.section("sweep")
    poses = base.circle.poses(sw["poses"])
    rows["sweep"] = _row(
        sizes.sweep_estimate(sw),
        _median_seconds(lambda: link0_sweep(robot, base.terrain, poses, sw["samples"]), args.runs),
    )

    from mmstab.planner import plan_path

    ws = load_or_build_workspace(base, progress=False)
    rows["planner"] = _row(
        sizes.planner_estimate(base.section("planner")),
        _median_seconds(lambda: plan_path(base, ws), args.runs),
    )

    from mmstab.workspace.fidelity import measure_fidelity

    wcfg = base.section("workspace")
    rows["precision"] = _row(
        sizes.precision_estimate(wcfg),
        _median_seconds(lambda: measure_fidelity(robot, ws, wcfg["precision_samples"], 0), 1),
    )

    from mmstab.runs.tracking import simulate

    plan = plan_path(base, ws)
    short = _edited(base, controller={"duration": 3.0})
    est = sizes.steps_estimate("controller.duration", 3.0, short.section("controller")["dt"])
    rows["controller"] = _row(
        est,
        _median_seconds(lambda: simulate(short, plan, progress=False), 1),
        _peak_bytes(lambda: simulate(short, plan, progress=False)),
    )

    from mmstab.stability.static import mu_max
    from mmstab.viz.animation import render_animation

    run = simulate(short, plan, progress=False)
    acfg = {**base.section("animation"), "frames": 12}
    out = Path(args.out).parent / "sizes_animation.gif"

    def render() -> None:
        render_animation(
            robot,
            base.terrain,
            run.t,
            run.state[:, :3],
            run.state[:, 5:9],
            run.mu.reconfigured,
            out,
            fps=acfg["fps"],
            size=(acfg["width"], acfg["height"]),
            max_frames=acfg["frames"],
            mu_scale=mu_max(robot),
            progress=False,
        )

    rows["animation"] = _row(
        sizes.animation_estimate(acfg, run.t.size), _median_seconds(render, 1), _peak_bytes(render)
    )
    out.unlink(missing_ok=True)
    summary = {
        "problem": args.problem,
        "machine": machine_info(),
        "runs": args.runs,
        "memory_available_B": sizes.available_memory(),
        "stages": rows,
        "all_conservative": bool(
            np.all([r["ratio_s"] >= 1 and r.get("ratio_B", 1) >= 1 for r in rows.values()])
        ),
        "note": "wall time on a shared machine; tracemalloc sees the Python heap only",
    }
    write_json(args.out, summary)
    for name, r in rows.items():
        mem = f", memory x{r['ratio_B']:.1f}" if "ratio_B" in r else ""
        print(f"{name:10s} {r['measured_s']:8.3f} s measured, estimate x{r['ratio_s']:.1f}{mem}")


if __name__ == "__main__":
    main()
