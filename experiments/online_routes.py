"""``make online-routes``: the online loop on the validation's routes, its arm against the ground.

Each route of the validation's generator (``generator``, its seeds: the routes of ``make
validate-routes``) is recorded as ``mmstab record`` records it (seeded 1 cm noise and
occluded patches) and followed as ``mmstab follow`` follows it. Per route: the arm, as the
loop had it at each covered map, against that map's ground at the robot's rest there
(``arm_in_ground``, the verdict ``follow`` exits 5 on), the same states at their rests on the
route's own ground (``arm_in_ground_true``), the maps where the two verdicts agree, whether
the loop's tip rule fired, the maps the tracks would slide on, and μ's least on the maps.

Writes ``summary.json`` (settings, per-route records, the routes each verdict names). The
latency is ``make bench-online``'s (one core, ``online_routes.json``).
"""

from __future__ import annotations

import multiprocessing
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from experiments.common import experiment_run
from mmstab.core.files import read_yaml, validate, write_json

SCHEMA = {
    "type": "object",
    "additionalProperties": False,
    "required": ["generator", "routes"],
    "properties": {
        "generator": {"type": "string"},
        "routes": {"type": "integer", "minimum": 1},
        "workers": {"type": "integer", "minimum": 1},
    },
}


def load_settings(path: str | Path) -> dict[str, Any]:
    """Read and check the settings file and its generator's (errors name file and field)."""
    from experiments.validate_routes import load_settings as load_generator

    data = read_yaml(path)
    validate(path, data, SCHEMA)
    data["generator_settings"] = load_generator(Path(path).parent / data["generator"])
    return data


def route_online(task: tuple[dict[str, Any], int, str]) -> dict[str, Any]:
    """Route k recorded and followed (the pool's job): its record."""
    from experiments.validate_routes import ground_record, route_problem
    from mmstab.core.problem import load_problem
    from mmstab.outputs.online import arm_heights_covered
    from mmstab.outputs.recording import record_route
    from mmstab.runs.arm_ground import in_ground_in_time
    from mmstab.runs.online.run import follow_recording, summarize

    settings, k, out = task
    data = route_problem(settings["generator_settings"], k)
    path = Path(out) / "problems" / f"route{k:02d}.yaml"
    path.write_text(yaml.safe_dump(data))
    problem = load_problem(path)
    with tempfile.TemporaryDirectory() as d:
        recording = Path(d) / "route.mcap"
        record_route(problem, recording)
        run = follow_recording(problem, recording)
    s = summarize(run)
    t, h_map, h_true = arm_heights_covered(problem, run)
    known = np.isfinite(h_map) & np.isfinite(h_true)
    return {
        "route": k,
        **ground_record(data),
        "maps": len(run.steps),
        "covered_maps": len(t),
        "arm_in_ground": s["arm_in_ground"],
        "arm_in_ground_true": in_ground_in_time(h_true, t),
        "verdict_known_maps": int(known.sum()),
        "verdict_agree_maps": int(((h_map < 0) == (h_true < 0))[known].sum()),
        "tipped": s["tipped"],
        "slide_maps": 0 if s["slides"] is None else s["slides"]["maps"],
        "mu_min": s["mu_min"],
    }


def summarize_routes(records: list[dict[str, Any]]) -> dict[str, Any]:
    """The routes each verdict names, and the maps where the map's and the ground's agree."""
    known = sum(r["verdict_known_maps"] for r in records)
    return {
        "routes": len(records),
        "arm_in_ground": [r["route"] for r in records if r["arm_in_ground"]["contact"]],
        "arm_in_ground_routes": sum(r["arm_in_ground"]["contact"] for r in records),
        "arm_in_ground_true": [r["route"] for r in records if r["arm_in_ground_true"]["contact"]],
        "deepest_m": max(
            (x["by"] for r in records for x in r["arm_in_ground"]["intervals_s"]), default=None
        ),  # fmt: skip
        "verdict_agree_share": sum(r["verdict_agree_maps"] for r in records) / max(known, 1),
        "tipped": [r["route"] for r in records if r["tipped"] is not None],
    }


def run_online_routes(
    settings: dict[str, Any], out: str | Path, indices: list[int] | None = None
) -> dict[str, Any]:
    """Record and follow the routes (all, or ``indices``), write the summary."""
    from mmstab.core.problem import load_problem
    from mmstab.workspace import load_or_build_workspace

    out = Path(out)
    (out / "problems").mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    indices = list(range(settings["routes"])) if indices is None else indices
    tasks = [(settings, k, str(out)) for k in indices]
    first = route_online(tasks[0])  # the workspace and roadmap built once, before the pool
    load_or_build_workspace(load_problem(out / "problems" / f"route{indices[0]:02d}.yaml"),
                            progress=False)  # fmt: skip
    workers = settings.get("workers", 1)
    if workers == 1 or len(tasks) == 1:
        records = [first, *(route_online(t) for t in tasks[1:])]
    else:
        ctx = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(workers, mp_context=ctx) as pool:
            records = [first, *pool.map(route_online, tasks[1:])]
    summary = {
        **summarize_routes(records),
        "seconds": time.perf_counter() - t0,
        "settings": {k: v for k, v in settings.items() if k != "generator_settings"},
        "records": records,
    }
    write_json(out / "summary.json", summary)
    return summary


def main(argv: list[str] | None = None) -> int:
    """``python -m experiments.online_routes [SETTINGS] [-o DIR]``; exit status."""
    got = experiment_run(argv, __doc__, "problems/online_routes.yaml", "results/online_routes",
                         run_online_routes, load_settings)  # fmt: skip
    if isinstance(got, int):
        return got
    s, out = got
    print(f"online routes: {s['routes']}; the arm in the map's ground on {s['arm_in_ground']}, "
          f"in the true ground on {s['arm_in_ground_true']}; the two agree on "
          f"{100 * s['verdict_agree_share']:.1f} % of the maps; tipped {s['tipped']}")  # fmt: skip
    print(f"-> {out}/summary.json ({s['seconds']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
