"""Benchmark: atlas cells per second on local Dask clusters, and a 10,000-cell atlas.

Usage: ``python benchmarks/atlas.py [PROBLEM.yaml] [--cells-scaling N] [--skip-10k]``;
writes ``results/bench/atlas.json``. Uses the problem's robot, workspace grid and planner
settings; the atlas axes are the benchmark's own.

- Scaling: the same atlas (one variant, ``--cells-scaling`` cells in chunks of 4) on a
  local cluster of 1 worker process, 2 worker processes, and 1 process with 2 threads.
  Each cluster is warmed up first (a small atlas: imports, kinematics, V loaded), then
  the measured atlas runs on it; cells/s = cells / (first submission -> last result).
  Scaling efficiency = (cells/s with 2 processes) / (2 x cells/s with 1).
- 10,000 cells: 50 slopes x 200 headings x 1 variant on the default local cluster
  (one process per core), wall time of the whole ``run_atlas`` including cluster start-up
  and figures (target: <= 5 min on a 2-core machine).
"""

from __future__ import annotations

import argparse
import copy
import json
import math
import os
import tempfile
import time
from pathlib import Path
from typing import Any

from common import machine_info

from experiments.atlas.driver import available_cores, dask_client
from experiments.atlas.runner import run_atlas
from mmstab.core.files import read_yaml, write_json
from mmstab.core.problem import Problem, problem_from_dict


def with_atlas(problem_path: str, slopes: int, headings: int, chunks: tuple[int, int]) -> Problem:
    """The problem with a benchmark atlas section (one variant: the robot file's flippers)."""
    data = copy.deepcopy(read_yaml(problem_path))
    data["atlas"] = {
        "axes": {
            "slope": {"start": 0.0, "stop": 0.8, "num": slopes},
            "heading": {"start": 0.0, "stop": 2 * math.pi, "num": headings},
        },
        "chunks": {"slope": chunks[0], "heading": chunks[1]},
        "margin": 250.0,
    }
    return problem_from_dict(data, problem_path)


def scaling_run(problem_path: str, cells: int, workers: int, processes: bool) -> dict[str, Any]:
    """Warm a local cluster up, then time ``cells`` cells on it."""
    headings = 8
    warm = with_atlas(problem_path, 1, workers * 4, (1, 4))
    measured = with_atlas(problem_path, max(1, cells // headings), headings, (1, 4))
    t0 = time.perf_counter()
    with dask_client(None, workers, processes) as client, tempfile.TemporaryDirectory() as tmp:
        address = client.scheduler.address
        start = time.perf_counter() - t0
        run_atlas(warm, Path(tmp) / "warm", address, progress=False, figures=False)
        run = run_atlas(measured, Path(tmp) / "run", address, progress=False, figures=False)["run"]
    return {
        "workers": run["workers"],
        "threads": run["threads"],
        "processes": processes,
        "cells": run["cells_computed"],
        "seconds": run["seconds"],
        "cells_per_second": run["cells_per_second"],
        "cluster_start_seconds": round(start, 2),
    }


def main() -> None:
    """Run the benchmark and write its JSON."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("problem", nargs="?", default="problems/ramp.yaml")
    ap.add_argument("--cells-scaling", type=int, default=96)
    ap.add_argument("--skip-10k", action="store_true", help="leave out the 10,000-cell atlas")
    ap.add_argument("--out", default="results/bench/atlas.json")
    args = ap.parse_args()
    load_start = os.getloadavg()
    one = scaling_run(args.problem, args.cells_scaling, 1, True)
    two = scaling_run(args.problem, args.cells_scaling, 2, True)
    threads = scaling_run(args.problem, args.cells_scaling, 2, False)
    result: dict[str, Any] = {
        "machine": machine_info(load_average_start=load_start),
        "scaling": {
            "processes_1": one,
            "processes_2": two,
            "threads_2": threads,
            "efficiency_2_processes": round(
                two["cells_per_second"] / (2 * one["cells_per_second"]), 3
            ),
            "processes_over_threads": round(
                two["cells_per_second"] / threads["cells_per_second"], 3
            ),
        },
    }
    if not args.skip_10k:
        big = with_atlas(args.problem, 50, 200, (10, 20))
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            s = run_atlas(big, Path(tmp), None, progress=True)
            wall = time.perf_counter() - t0
        result["atlas_10k"] = {
            "cells": s["cells"],
            "workers": s["run"]["workers"],
            "wall_seconds": round(wall, 1),
            "compute_seconds": s["run"]["seconds"],
            "cells_per_second": s["run"]["cells_per_second"],
            "target_seconds": 300,
            "cores": available_cores(),
        }
    elif Path(args.out).is_file():  # keep the last measured 10,000-cell run, marked as such
        previous = json.loads(Path(args.out).read_text())
        for key in ("atlas_10k", "atlas_10k_previous_run"):
            if key in previous:
                result["atlas_10k_previous_run"] = {**previous[key], "machine": previous["machine"]}
                break
    result["machine"]["load_average_end"] = os.getloadavg()
    write_json(args.out, result)
    sc = result["scaling"]
    print(
        f"atlas: {one['cells_per_second']:.2f} cells/s with 1 process, "
        f"{two['cells_per_second']:.2f} with 2 (efficiency {sc['efficiency_2_processes']:.2f}), "
        f"{threads['cells_per_second']:.2f} with 2 threads -> {args.out}"
    )
    if "atlas_10k" in result:
        print(f"atlas: 10,000 cells in {result['atlas_10k']['wall_seconds']:.0f} s")


if __name__ == "__main__":
    main()
