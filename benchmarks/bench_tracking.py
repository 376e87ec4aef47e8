"""Benchmark: wall time of the default tracking run and µs per control step, per QP plugin.

Plans the default problem once (``mmstab.planner.plan_path``), then runs the whole tracking
simulation (one lap, dt = 1 ms: 30 000 steps) ``--repeats`` times per plugin and reports
medians of: the control loop's µs per step (controller step + hold-still guard + exact-arc
integration + logging, one CasADi call through ``Function.buffer()``), the loop's wall time,
and the whole ``simulate`` call (build + reference + loop + stability post-processing; the lap's
posture reference is checked and repaired once beforehand, timed apart). With
``mmstab.codegen`` present, the generated step is timed too, per code-generable
plugin. Not a test; the machine is shared, so expect noise.

Usage: python benchmarks/bench_tracking.py [PROBLEM.yaml] [--repeats N] [-o JSON]
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np
from common import machine_info

from mmstab.app import generated_step, with_plugin
from mmstab.control.controller import CODEGEN_PLUGINS, PLUGINS, ControllerSettings
from mmstab.control.posture import build_posture_reference, posture_samples
from mmstab.core.files import MmstabError, write_json
from mmstab.core.problem import Problem, load_problem
from mmstab.runs.tracking import StepBackend, simulate


def bench(
    problem: Problem,
    plan: Any,
    posture: Any,
    plugin: str,
    repeats: int,
    generated: bool = False,
) -> dict[str, Any]:
    """Median timings of ``repeats`` whole runs with one plugin (interpreted or generated).

    The lap's posture reference (checked and repaired once, ``posture``) is shared by all
    runs; each run still builds its start-up approach.
    """
    prob = with_plugin(problem, plugin)
    loop, whole, per_step = [], [], []
    run = None
    for _ in range(repeats):
        step: StepBackend | None = generated_step(prob, plugin) if generated else None
        t0 = time.perf_counter()
        run = simulate(prob, plan, step=step, progress=False, posture=posture)
        whole.append(time.perf_counter() - t0)
        loop.append(run.wall_seconds)
        per_step.append(run.us_per_step)
    assert run is not None
    return {
        "us_per_step_median": float(np.median(per_step)),
        "us_per_step_all": per_step,
        "loop_seconds_median": float(np.median(loop)),
        "simulate_seconds_median": float(np.median(whole)),
        "steps": run.steps,
        "qp_failures": len(run.failures),
        "arm_com_error_final_m": float(run.arm_com_error[-1]),
        "base_error_final_m": float(run.base_error[-1]),
    }


def main() -> None:
    """Plan once, time every plugin, write the JSON summary."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("problem", nargs="?", default="problems/ramp.yaml")
    ap.add_argument("--repeats", type=int, default=3, help="runs per plugin (median)")
    ap.add_argument("-o", "--out", default="results/bench/tracking.json")
    args = ap.parse_args()
    problem = load_problem(args.problem)
    from mmstab.planner import plan_path

    t0 = time.perf_counter()
    plan = plan_path(problem)
    plan_seconds = time.perf_counter() - t0
    settings = ControllerSettings.from_section(problem.section("controller"))
    t0 = time.perf_counter()
    posture = build_posture_reference(
        problem.robot, plan, posture_samples(settings.lap_time, settings.dt)
    )
    posture_seconds = time.perf_counter() - t0
    print(f"plan {plan_seconds:.2f} s, posture reference (check + repair) {posture_seconds:.2f} s")
    interpreted = {}
    for plugin in PLUGINS:
        r = interpreted[plugin] = bench(problem, plan, posture, plugin, args.repeats)
        print(
            f"interpreted {plugin:8s} {r['us_per_step_median']:6.1f} us/step, loop "
            f"{r['loop_seconds_median']:.2f} s, simulate {r['simulate_seconds_median']:.2f} s "
            f"({r['steps']} steps, {r['qp_failures']} QP failures)"
        )
    generated: dict[str, Any] = {}
    try:
        import mmstab.codegen  # noqa: F401
    except ImportError:
        generated = {"note": "mmstab.codegen not available in this installation"}
    else:
        for plugin in CODEGEN_PLUGINS:
            try:
                r = generated[plugin] = bench(
                    problem, plan, posture, plugin, args.repeats, generated=True
                )
            except MmstabError as exc:
                generated[plugin] = {"error": str(exc)}
                continue
            print(f"generated   {plugin:8s} {r['us_per_step_median']:6.1f} us/step")
    write_json(
        args.out,
        {
            "what": "default tracking run (one lap): µs per control step and wall times",
            "note": "medians on a shared 2-core machine: noisy",
            "problem": str(args.problem),
            "repeats": args.repeats,
            "plan_seconds": plan_seconds,
            "posture_reference_seconds": posture_seconds,
            "machine": machine_info(),
            "interpreted": interpreted,
            "generated": generated,
        },
    )
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
