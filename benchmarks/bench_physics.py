"""Benchmark: real-time factor of the whole robot in MuJoCo, alone and with the controller.

Usage: ``python benchmarks/bench_physics.py [--seconds S] [--repeats N]``; writes
``results/bench/physics.json``. On one core (the process pinned to one CPU, BLAS threads 1):
simulated time / wall time of (a) the model alone, driving straight at 0.2 m/s with the arm
held, on the ramp's plane, on rough.yaml's heightfield (5 cm cells) and on kerb.yaml's (2 cm);
(b) the closed loop (:mod:`mmstab.physics.closed_loop`, the controller reading MuJoCo's
state every 4 ms) on the ramp lap (plane) and along rough.yaml's route (heightfield), with
the interpreted controller and with the generated C step. Each case runs on the default
model (the problem's ``physics:`` section: sphere wheels, 4 ms step) and, as the peer in the
same run, on the model before it (cylinder wheels, 2 ms step). Medians over the repeats, of
the wall-clock factor and of the CPU-time one (simulated time / this process's CPU time:
the factor on a core of one's own; other jobs on a shared machine slow the wall clock).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import time
from collections.abc import Callable

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from common import machine_info  # noqa: E402

from mmstab import app  # noqa: E402
from mmstab.control.controller import build_controller  # noqa: E402
from mmstab.control.reference import initial_state  # noqa: E402
from mmstab.core.files import write_json  # noqa: E402
from mmstab.core.problem import load_problem  # noqa: E402
from mmstab.outputs.simulate import controller_settings, loop_settings  # noqa: E402
from mmstab.physics.closed_loop import run_closed_loop  # noqa: E402
from mmstab.physics.robot_model import ModelSettings  # noqa: E402
from mmstab.physics.robot_sim import RobotSim  # noqa: E402

#: The model before the closed loop's faster default (docs/physics.md, "Speed").
CYLINDER_2MS = ModelSettings(
    wheel="cylinder", timestep=0.002, solref=(0.006, 1.0), suspension_armature=0.0
)
PLANE, ROUGH, KERB = "problems/ramp.yaml", "problems/rough.yaml", "problems/kerb.yaml"


def model_alone(
    problem_path: str, seconds: float, settings: ModelSettings | None
) -> tuple[float, float]:
    """Real-time factors (wall, CPU) of the model driving straight at 0.2 m/s, arm held."""
    problem = load_problem(problem_path)
    pose = initial_state(problem.base_path, problem.robot.stowed)[:3]
    if settings is None:
        settings = loop_settings(problem).model_settings()
    sim = RobotSim(problem.robot, problem.terrain, pose=pose, settings=settings)
    t0, cpu0 = time.perf_counter(), time.process_time()
    sim.step((0.2, 0.2), problem.robot.stowed, seconds)
    return seconds / (time.perf_counter() - t0), seconds / (time.process_time() - cpu0)


def closed_loop(
    problem_path: str,
    seconds: float,
    backend: str,
    settings: ModelSettings | None,
    on_time: bool = False,
) -> tuple[float, float]:
    """Real-time factors (wall, CPU) of the problem's closed loop (controller included).

    ``on_time``: without the reference governor (``physics.governor: null``), its peer.
    """
    problem = load_problem(problem_path)
    cs = controller_settings(problem)
    loop = dataclasses.replace(loop_settings(problem), duration=seconds)
    if on_time:
        loop = dataclasses.replace(loop, governor=None)
    if backend == "generated":
        cs = dataclasses.replace(cs, plugin=problem.section("codegen")["plugin"])
        step = app.generated_step(problem).function
    else:
        step = build_controller(problem.robot, cs).step
    state0 = initial_state(problem.base_path, problem.robot.stowed)
    run = run_closed_loop(problem, app.plan(problem), step, cs, loop, state0, settings)
    return run.real_time_factor, float(run.t[-1] / (run.cpu_seconds or float("nan")))


def cases(seconds: float) -> dict[str, Callable[[], tuple[float, float]]]:
    """Every case, by name: ``<what>_<ground>[_<backend>]`` on the default model.

    Then the same with ``_cylinder_2ms``: the peer, the model before; and the closed loops
    with ``_no_governor``: the reference on time, the reference governor's peer.
    """
    out: dict[str, Callable[[], tuple[float, float]]] = {}
    for suffix, model in (("", None), ("_cylinder_2ms", CYLINDER_2MS)):
        out |= {
            f"model_alone_plane{suffix}": lambda m=model: model_alone(PLANE, seconds, m),
            f"model_alone_rough{suffix}": lambda m=model: model_alone(ROUGH, seconds, m),
            f"model_alone_kerb{suffix}": lambda m=model: model_alone(KERB, seconds / 5, m),
        }
        for backend in ("interpreted", "generated"):
            out |= {
                f"closed_loop_plane_{backend}{suffix}": lambda b=backend, m=model: closed_loop(
                    PLANE, seconds, b, m
                ),
                f"closed_loop_rough_{backend}{suffix}": lambda b=backend, m=model: closed_loop(
                    ROUGH, seconds, b, m
                ),
            }
    for ground, path in (("plane", PLANE), ("rough", ROUGH)):  # the governor's peer: on time
        for backend in ("interpreted", "generated"):
            out[f"closed_loop_{ground}_{backend}_no_governor"] = lambda p=path, b=backend: (
                closed_loop(p, seconds, b, None, on_time=True)
            )
    return out


def main() -> None:
    """Measure each case ``--repeats`` times; write the medians."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", default="results/bench/physics.json")
    args = ap.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    load_before = machine_info()["load_average"]
    wall, cpu = {}, {}
    for name, f in cases(args.seconds).items():
        runs = [f() for _ in range(args.repeats)]
        wall[name] = statistics.median(w for w, _ in runs)
        cpu[name] = statistics.median(c for _, c in runs)
    out = {"real_time_factor": wall, "real_time_factor_cpu": cpu, "target": 10.0,
           "seconds": args.seconds, "repeats": args.repeats, "load_average_before": load_before,
           "machine": machine_info(one_core=True)}  # fmt: skip
    write_json(args.out, out)
    print("real-time factor (wall, CPU): " + ", ".join(
        f"{k} {wall[k]:.1f}x {cpu[k]:.1f}x" for k in wall))  # fmt: skip


if __name__ == "__main__":
    main()
