"""Benchmark: real-time factor of the whole robot in MuJoCo, alone and with the controller.

Usage: ``python benchmarks/bench_physics.py [--seconds S] [--repeats N]``; writes
``results/bench/physics.json``. On one core (the process pinned to one CPU, BLAS threads 1):
simulated time / wall time of (a) the model alone, driving at constant track speeds with the
arm held, on the ramp's plane and on the kerb's heightfield; (b) the closed loop on the ramp
lap (:mod:`mmstab.physics.closed_loop`) with the interpreted controller and with the
generated C step. Medians over the repeats.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from common import machine_info  # noqa: E402

from mmstab import app  # noqa: E402
from mmstab.control.controller import build_controller  # noqa: E402
from mmstab.control.reference import initial_state  # noqa: E402
from mmstab.core.files import write_json  # noqa: E402
from mmstab.core.problem import load_problem  # noqa: E402
from mmstab.experiments.simulate import controller_settings, loop_settings  # noqa: E402
from mmstab.physics.closed_loop import run_closed_loop  # noqa: E402
from mmstab.physics.robot_sim import RobotSim  # noqa: E402


def model_alone(problem_path: str, seconds: float) -> float:
    """Real-time factor of the model driving straight at 0.2 m/s, the arm held."""
    problem = load_problem(problem_path)
    pose = initial_state(problem.base_path, problem.robot.stowed)[:3]
    sim = RobotSim(problem.robot, problem.terrain, pose=pose)
    t0 = time.perf_counter()
    sim.step((0.2, 0.2), problem.robot.stowed, seconds)
    return seconds / (time.perf_counter() - t0)


def closed_loop(seconds: float, backend: str) -> float:
    """Real-time factor of the ramp lap's closed loop (controller included)."""
    problem = load_problem("problems/ramp.yaml")
    cs = controller_settings(problem)
    loop = dataclasses.replace(loop_settings(problem), duration=seconds)
    if backend == "generated":
        cs = dataclasses.replace(cs, plugin=problem.section("codegen")["plugin"])
        step = app.generated_step(problem).function
    else:
        step = build_controller(problem.robot, cs).step
    state0 = initial_state(problem.base_path, problem.robot.stowed)
    return run_closed_loop(problem, app.plan(problem), step, cs, loop, state0).real_time_factor


def main() -> None:
    """Measure each case ``--repeats`` times; write the medians."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", default="results/bench/physics.json")
    args = ap.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    cases = {
        "model_alone_plane": lambda: model_alone("problems/ramp.yaml", args.seconds),
        "model_alone_heightfield": lambda: model_alone("problems/kerb.yaml", args.seconds / 5),
        "closed_loop_interpreted": lambda: closed_loop(args.seconds, "interpreted"),
        "closed_loop_generated": lambda: closed_loop(args.seconds, "generated"),
    }
    result = {
        name: statistics.median(f() for _ in range(args.repeats)) for name, f in cases.items()
    }
    out = {"real_time_factor": result, "target": 10.0, "seconds": args.seconds,
           "repeats": args.repeats, "machine": machine_info(one_core=True)}  # fmt: skip
    write_json(args.out, out)
    print("real-time factor: " + ", ".join(f"{k} {v:.1f}x" for k, v in result.items()))


if __name__ == "__main__":
    main()
