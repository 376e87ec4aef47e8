"""``make drive``: the skid-steer drive layer (``physics.turn_ratio``) in ``mmstab simulate``.

A skid-steered base turns slower than its belts command (the turn deficit); the drive layer
(:mod:`mmstab.stability.drive`) reads the controller's sprocket rates as the twist they mean
and commands the belts ``v ∓ ω b / (2 η)``. This experiment runs it, for each turn ratio η
of the settings (a number, or ``auto``: the skid model's level pivot, arm stowed):

- **level**: the robot (arm stowed) on a level floor at constant sprocket rates through the
  layer (a pivot and an arc), MuJoCo's yaw rate over 2 s after a transient against the
  commanded (kinematic) one;
- **pairs**: the seeded random route pairs of ``tests/runs/test_random_routes.py`` (pairs
  0 .. n-1), each planned (``mmstab plan``: its turn verdicts) and simulated (``mmstab
  simulate``: its exit status and MuJoCo's events);
- **routes**: the shipped routes (``problems/*.yaml``, the planned or the stowed arm),
  simulated the same way.

Each run is a ``mmstab`` command in a process of its own, the problem's copy (with
``physics.turn_ratio`` set) beside its outputs. Writes ``summary.json``: the settings, the
resolved ``auto`` ratio, the level cases, per variant the pairs' and routes' records and
the counts of pairs that slide, tip or touch the ground. ``docs/skid.md`` ("The drive
layer") reads it.
"""

from __future__ import annotations

import copy
import json
import os
import subprocess
import sys
import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import yaml

from experiments.common import experiment_run
from mmstab.core.files import MmstabError, read_yaml, validate, write_json

ROOT = Path(__file__).resolve().parents[1]
_RATIO = {"oneOf": [{"type": "number", "exclusiveMinimum": 0, "maximum": 1},
                    {"const": "auto"}]}  # fmt: skip
_RATES = {"type": "array", "items": {"type": "number"}, "minItems": 2, "maxItems": 2}
SCHEMA = {
    "type": "object",
    "additionalProperties": False,
    "required": ["turn_ratios", "pairs", "routes", "level"],
    "properties": {
        "turn_ratios": {"type": "array", "items": _RATIO, "minItems": 1},
        "pairs": {"type": "integer", "minimum": 0},
        "routes": {
            "type": "object",
            "additionalProperties": {
                "type": "object",
                "additionalProperties": False,
                "required": ["problem", "arm"],
                "properties": {
                    "problem": {"type": "string"},
                    "arm": {"enum": ["planned", "stowed"]},
                },  # fmt: skip
            },
        },
        "level": {
            "type": "object",
            "additionalProperties": False,
            "required": ["friction", "transient_s", "duration_s", "turns"],
            "properties": {
                "friction": {"type": "number", "exclusiveMinimum": 0},
                "transient_s": {"type": "number", "minimum": 0},
                "duration_s": {"type": "number", "exclusiveMinimum": 0},
                "turns": {"type": "object", "additionalProperties": _RATES},
            },
        },
        "workers": {"type": "integer", "minimum": 1},
    },
}


def load_settings(path: str | Path) -> dict[str, Any]:
    """Read and check the settings file (errors name the file and the field)."""
    data = read_yaml(path)
    validate(path, data, SCHEMA)
    data["path"] = str(Path(path).resolve())
    return data


def _key(ratio: Any) -> str:
    """The variant's name: ``auto`` or the number as YAML writes it (``1.0``, ``0.54``)."""
    return "auto" if ratio == "auto" else repr(float(ratio))


def level_cases(settings: dict[str, Any]) -> list[dict[str, Any]]:
    """MuJoCo's level turns through the drive layer, per turn and ratio (module text)."""
    import numpy as np

    from mmstab.core.problem import load_problem
    from mmstab.physics.skid_sim import measure_twist
    from mmstab.stability.drive import DriveLayer, resolve_turn_ratio

    robot = load_problem(ROOT / "problems" / "ramp.yaml").robot
    lv = settings["level"]
    t = robot.base.tracks
    cases = []
    for turn, rates in lv["turns"].items():
        commanded = t.sprocket_radius * (rates[1] - rates[0]) / t.separation  # [rad/s]
        for ratio in settings["turn_ratios"]:
            eta = resolve_turn_ratio(robot, ratio)
            belts = DriveLayer.of(robot, eta).belts(np.asarray(rates, dtype=float))
            twist = measure_twist(
                robot, 0.0, 0.0, belts, lv["friction"],
                transient=lv["transient_s"], duration=lv["duration_s"],
            )  # fmt: skip
            cases.append({
                "turn": turn, "sprocket_rates": list(rates), "turn_ratio": eta,
                "belts_m_s": [float(b) for b in belts],
                "yaw_rate_over_commanded": float(twist.yaw_rate / commanded),
            })  # fmt: skip
    return cases


def _problem_copy(data: dict[str, Any], source: Path, folder: Path, ratio: Any) -> Path:
    """The problem ``data`` (read from ``source``) with ``physics.turn_ratio``, in ``folder``."""
    data = copy.deepcopy(data)
    data.setdefault("physics", {})["turn_ratio"] = ratio
    folder.mkdir(parents=True, exist_ok=True)
    robot = Path(data["robot"])
    robot = robot if robot.is_absolute() else (source.parent / robot).resolve()
    data["robot"] = os.path.relpath(robot, folder)
    terrain = data.get("terrain", {})
    if isinstance(terrain, dict) and "file" in terrain:
        file = Path(terrain["file"])
        file = file if file.is_absolute() else (source.parent / file).resolve()
        terrain["file"] = os.path.relpath(file, folder)
    path = folder / "problem.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def _mmstab(*args: str) -> int:
    """A ``mmstab`` command in a process of its own; its exit status."""
    cmd = [sys.executable, "-m", "mmstab", *args]
    return subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True).returncode


def _simulated(out: Path, status: int) -> dict[str, Any]:
    """What a run's ``summary.json`` says: the events and errors the docs compare."""
    if not (out / "summary.json").is_file():  # the run did not finish: name it, not a KeyError
        raise MmstabError(f"{out}: mmstab simulate exited {status} without a summary")
    s = json.loads((out / "summary.json").read_text())
    arm = s.get("arm_ground_contact") or {}

    def time_of(event: Any) -> float | None:
        return event["time_s"] if event else None

    return {
        "exit": status,
        "slid_s": time_of(s["slid"]),
        "tipped_s": time_of(s["tipped"]),
        "drift_max_m": s["downhill_drift_max_m"],
        "base_error_max_m": s["base_error_max_m"],
        "base_error_max_where_no_slip_predicted_m": s["base_error_max_where_no_slip_predicted_m"],
        "base_origin_error_max_where_no_slip_predicted_m":
            s["base_origin_error_max_where_no_slip_predicted_m"],
        "tilt_off_rest_max_rad": s["tilt_off_rest_max_rad"],
        "arm_ground_fraction": arm.get("fraction_of_checks", 0.0),
    }  # fmt: skip


def run_job(job: tuple[str, str, Path, Path, str, bool]) -> tuple[str, str, dict[str, Any]]:
    """One variant of one pair or route: plan (pairs) and simulate; its record."""
    variant, name, problem, out, arm, plan = job
    record: dict[str, Any] = {}
    for old in (out / "plan" / "summary.json", out / "physics" / "summary.json"):
        old.unlink(missing_ok=True)  # an earlier run's: never read as this one's
    if plan:  # the plan's turn verdicts (a route it refuses is planned all the same)
        _mmstab("plan", str(problem), "-o", str(out / "plan"), "--allow-sliding",
                "--allow-unstable")  # fmt: skip
        s = json.loads((out / "plan" / "summary.json").read_text())
        turns = s["slip"]["turns"]
        record["plan"] = {
            "slides": s["verdicts"]["slide"]["verdict"] != "holds",
            "slide_rate_max_m_s": turns["slide_rate_max_m_s"],
            "sliding_turns": [
                [
                    round(t["start_s"], 2),
                    round(t["end_s"], 2),
                    round(t["turn_rad"], 2),
                    round(t["slide_in_window_m"], 4),
                ]
                for t in turns["sliding_turns"]
            ],  # fmt: skip
        }
    sim = out / "physics"
    status = _mmstab("simulate", str(problem), "-o", str(sim), "--arm", arm)  # its verdict
    return variant, name, record | _simulated(sim, status)


def run_drive(settings: dict[str, Any], out: str | Path) -> dict[str, Any]:
    """All the runs (module text); writes ``summary.json`` in ``out``."""
    t0 = time.perf_counter()
    out = Path(out)
    sys.path[:0] = [str(ROOT / "tests"), str(ROOT / "tests" / "runs")]
    with warnings.catch_warnings():  # the tests' conftest on BLAS threads: not a test run
        warnings.simplefilter("ignore", UserWarning)
        from test_random_routes import pair_problem

    from mmstab.core.problem import load_problem
    from mmstab.stability.drive import resolve_turn_ratio

    jobs = []
    pairs_dir = out / "pairs"
    pairs_dir.mkdir(parents=True, exist_ok=True)
    for k in range(settings["pairs"]):
        source = pair_problem(k, pairs_dir)
        data = yaml.safe_load(source.read_text())
        for ratio in settings["turn_ratios"]:
            folder = pairs_dir / f"pair{k:02d}" / _key(ratio)
            path = _problem_copy(data, source, folder, ratio)
            jobs.append((_key(ratio), f"pair{k}", path, folder, "planned", True))
    settings_dir = Path(settings["path"]).parent
    for name, route in settings["routes"].items():
        source = (settings_dir / route["problem"]).resolve()
        data = yaml.safe_load(source.read_text())
        for ratio in settings["turn_ratios"]:
            folder = out / "routes" / name / _key(ratio)
            path = _problem_copy(data, source, folder, ratio)
            jobs.append((_key(ratio), name, path, folder, route["arm"], False))
    with ThreadPoolExecutor(settings.get("workers", 1)) as pool:  # each job a process
        done = list(pool.map(run_job, jobs))
    variants = [_key(r) for r in settings["turn_ratios"]]
    pairs: dict[str, dict[str, Any]] = {v: {} for v in variants}
    routes: dict[str, dict[str, Any]] = {v: {} for v in variants}
    for variant, name, record in done:
        if name.startswith("pair"):
            pairs[variant][name.removeprefix("pair")] = record
        else:
            routes[variant][name] = record
    robot = load_problem(ROOT / "problems" / "ramp.yaml").robot
    counts = {
        v: {
            "pairs": len(pairs[v]),
            "slide": sum(r["slid_s"] is not None for r in pairs[v].values()),
            "tip": sum(r["tipped_s"] is not None for r in pairs[v].values()),
            "arm_ground": sum(r["arm_ground_fraction"] > 0 for r in pairs[v].values()),
            "plan_slides": sum(r["plan"]["slides"] for r in pairs[v].values()),
        }
        for v in variants
    }
    summary = {
        "what": "the drive layer (physics.turn_ratio) in mmstab simulate (experiments/drive.py)",
        "settings": {k: v for k, v in settings.items() if k != "path"},
        "auto_turn_ratio": resolve_turn_ratio(robot, "auto"),
        "level": {
            "how": "level floor, arm stowed; yaw rate over the window after the transient at "
            "constant sprocket rates [rad/s] through DriveLayer(eta).belts",
            "cases": level_cases(settings),
        },  # fmt: skip
        "counts": counts,
        "pairs": pairs,
        "routes": routes,
        "seconds": time.perf_counter() - t0,
    }
    write_json(out / "summary.json", summary)
    return summary


def main(argv: list[str] | None = None) -> int:
    """``python -m experiments.drive [SETTINGS] [-o DIR]``; exit status."""
    got = experiment_run(argv, __doc__, "problems/drive.yaml", "results/drive", run_drive,
                         load_settings)  # fmt: skip
    if isinstance(got, int):
        return got
    s, out = got
    for v, c in s["counts"].items():
        r = s["routes"][v].get("rough_planned", {})
        print(f"turn_ratio {v}: pairs sliding {c['slide']} of {c['pairs']} (plan: "
              f"{c['plan_slides']}), tipping {c['tip']}, arm on the ground {c['arm_ground']}; "
              f"rough planned: control point {r.get('base_error_max_where_no_slip_predicted_m')} m "
              "where no slip is predicted")  # fmt: skip
    print(f"-> {out}/summary.json ({s['seconds']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
