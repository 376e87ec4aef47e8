"""Benchmark: what carrying the local ground in the reference costs the controller step.

Reports, per code-generable plugin and qpOASES, the QP Function's SX instruction count
(deterministic) and the median µs of an interpreted ``Controller.solve`` (noisy on a shared
machine), with the reference vector's size. Run it on two checkouts to compare (see
``docs/controller-terrain.md``).

Usage: python benchmarks/step_terrain.py [PROBLEM.yaml] [-o JSON]
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np
from common import machine_info

from mmstab.control.controller import REFERENCE_SIZE, ControllerSettings, build_controller
from mmstab.core.files import write_json
from mmstab.core.problem import load_problem


def main() -> None:
    """Measure and write ``results/bench/step_terrain.json``."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("problem", nargs="?", default="problems/ramp.yaml")
    ap.add_argument("-o", "--output", default="results/bench/step_terrain.json")
    args = ap.parse_args()
    problem = load_problem(args.problem)
    settings = ControllerSettings.from_section(problem.section("controller"))
    state = np.r_[0.1, -1.4, 0.2, 0.0, 0.0, 2.0, 0.3, -0.5, 0.2]
    out = {"machine": machine_info(), "reference_size": REFERENCE_SIZE, "plugins": {}}
    for plugin in ("qrqp", "qpoases"):
        ctrl = build_controller(problem.robot, dataclasses.replace(settings, plugin=plugin))
        xi = ctrl.model.task(state) + 0.01
        for _ in range(200):
            ctrl.solve(state, xi)
        runs = []
        for _ in range(5):
            t0 = time.perf_counter()
            for _ in range(2000):
                ctrl.solve(state, xi)
            runs.append((time.perf_counter() - t0) / 2000 * 1e6)
        out["plugins"][plugin] = {
            "qp_sx_instructions": int(ctrl.qp.n_instructions()),
            "us_per_solve_median": float(np.median(runs)),
        }
        print(plugin, out["plugins"][plugin])
    write_json(args.output, out)


if __name__ == "__main__":
    main()
