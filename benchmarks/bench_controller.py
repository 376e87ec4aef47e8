"""Benchmark: µs per interpreted controller step, per QP plugin (not a test).

Runs the default problem's closed loop (circle reference on the ramp, a fixed arm posture and
its CoM as the target, start 0.1 m off the path with the arm stowed, the arm on its start-up
approach for the first ``approach_time``) for
``--seconds`` of simulated time and times every ``Controller.solve`` call. Also times the same
``step`` Function called the usual ways (keyword/dict arguments; positional NumPy arguments),
to show where the per-call overhead goes. Medians; the machine is shared, so expect noise.

Usage: python benchmarks/bench_controller.py [PROBLEM.yaml] [--seconds S] [-o JSON]
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from types import SimpleNamespace

import numpy as np
from common import machine_info

from mmstab.control.controller import (
    PLUGINS,
    ControllerSettings,
    StepReference,
    build_controller,
    quiet_stdout,
)
from mmstab.control.reference import initial_state
from mmstab.core.files import write_json
from mmstab.core.problem import load_problem
from mmstab.runs.rollout import run_inputs

ARM_TARGET_POSTURE = np.array([2.0, 0.3, -0.5, 0.2])  # a reachable arm posture [rad]


def _median_us(samples: list[float]) -> float:
    return float(np.median(samples) * 1e6)


def bench_plugin(problem, settings: ControllerSettings, seconds: float) -> dict:
    """Closed-loop run with one plugin; per-call timings of solve and of plain Function calls."""
    robot = problem.robot
    t0 = time.perf_counter()
    c = build_controller(robot, settings)
    build_s = time.perf_counter() - t0
    steps = int(round(seconds / settings.dt))
    q = ARM_TARGET_POSTURE[None]
    plan = SimpleNamespace(fractions=np.zeros(1), target_com=robot.arm_com(q), postures=q)
    state = initial_state(problem.circle, robot.stowed, lateral_offset=0.1)
    inputs = run_inputs(problem, plan, steps=steps, state0=state, settings=settings)
    refs = StepReference.unpack(inputs.reference)
    xi_des = refs.xi_des
    solve_t, saturated = [], 0
    for k in range(steps):
        ref_k = StepReference.unpack(inputs.reference[k])
        t = time.perf_counter()
        res = c.solve(state, *ref_k)
        solve_t.append(time.perf_counter() - t)
        saturated += bool(np.any(np.isclose(np.abs(res.qdot), c.params.qdot_max, atol=1e-9)))
        state = c.model.integrate(state, res.qdot, settings.dt)
    final_error = np.linalg.norm(xi_des[-1] - c.model.task(state))
    # the same Function, called the ordinary ways, at the final state
    ref, p = inputs.reference[-1], c.params.pack()
    dict_t, pos_t = [], []
    with quiet_stdout():  # OSQP's polish line; both timings pay the same
        for _ in range(min(steps, 2000)):
            t = time.perf_counter()
            c.step(state=state, reference=ref, params=p)
            dict_t.append(time.perf_counter() - t)
            t = time.perf_counter()
            c.step(state, ref, p)
            pos_t.append(time.perf_counter() - t)
    return {
        "solve_us_median": _median_us(solve_t),
        "solve_us_p90": float(np.percentile(solve_t, 90) * 1e6),
        "step_dict_call_us_median": _median_us(dict_t),
        "step_positional_call_us_median": _median_us(pos_t),
        "build_s": build_s,
        "steps": steps,
        "steps_with_saturated_joint": saturated,
        "failures": c.failures,
        "final_task_error": float(final_error),
    }


def main() -> None:
    """Run every plugin and write the JSON summary."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("problem", nargs="?", default="problems/ramp.yaml")
    ap.add_argument("--seconds", type=float, default=5.0, help="simulated time per plugin [s]")
    ap.add_argument("-o", "--out", default="results/bench/controller.json")
    args = ap.parse_args()
    problem = load_problem(args.problem)
    base = ControllerSettings.from_section(problem.section("controller"))
    results = {}
    for plugin in PLUGINS:
        results[plugin] = bench_plugin(
            problem, dataclasses.replace(base, plugin=plugin), args.seconds
        )
        r = results[plugin]
        print(
            f"{plugin:8s} solve {r['solve_us_median']:6.1f} us/step median "
            f"(p90 {r['solve_us_p90']:6.1f}); same Function, dict call "
            f"{r['step_dict_call_us_median']:6.1f} us, "
            f"positional {r['step_positional_call_us_median']:6.1f} us; "
            f"failures {r['failures']}, final task error {r['final_task_error']:.1e}"
        )
    write_json(
        args.out,
        {
            "what": "µs per interpreted controller step (Controller.solve), ramp closed loop",
            "note": "medians on a shared 2-core machine: noisy",
            "problem": str(args.problem),
            "simulated_seconds": args.seconds,
            "machine": machine_info(),
            "plugins": results,
        },
    )
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
