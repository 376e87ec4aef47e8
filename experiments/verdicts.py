"""Verdicts against physics: mmstab's tips / holds / slides against MuJoCo's.

Settings come from ``problems/verdicts.yaml``: the grid's axes (heading, payload, arm,
friction, track speed) and the slope offsets around mmstab's critical slope, the
thresholds of MuJoCo's verdict, the durations, the MuJoCo models the grid runs on, the
bisection of the tip slope. ``make verdicts`` (``python -m experiments.verdicts``)
writes ``results/verdicts/summary.json`` (per model: the confusion matrix, the agreement,
every case, every disagreement; the tip slopes predicted vs bisected) and ``verdicts.png``.
``docs/verdicts.md``, explains the numbers.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from experiments.common import experiment_run
from mmstab.core.files import ConfigError, read_yaml, write_json
from mmstab.core.pool import ChunkPool
from mmstab.physics.edge_cases import (
    ArmPostures,
    Case,
    Config,
    Prediction,
    bisect_tip,
    build_cases,
    case_sim,
    configs,
)
from mmstab.physics.robot_model import ModelSettings
from mmstab.physics.verdict_sim import VERDICTS, SimSettings, Thresholds

#: Keys the settings file must have.
REQUIRED = ("problem", "grid", "thresholds", "sim", "models", "main_model", "bisection")


def load_settings(path: str | Path) -> dict[str, Any]:
    """The settings file, checked for its sections (paths resolved against its folder)."""
    data = read_yaml(path)
    missing = [k for k in REQUIRED if k not in data]
    if missing:
        raise ConfigError(path, "", f"missing {', '.join(missing)}")
    if data["main_model"] not in data["models"]:
        raise ConfigError(path, "main_model", f"{data['main_model']!r} is not in models")
    data["problem"] = str(Path(path).parent / data["problem"])
    return data


def arm_postures(settings: dict[str, Any], cache_dir: str | None = None) -> ArmPostures:
    """The grid's postures: the problem's robot, V's valid postures clear of the ground."""
    from mmstab.core.problem import load_problem
    from mmstab.workspace import load_or_build_workspace

    problem = load_problem(settings["problem"])
    ws = load_or_build_workspace(problem, progress=False, cache_dir=cache_dir)
    return ArmPostures(
        problem.robot,
        settings.get("payload_com", [0.0, 0.0, 0.0]),
        ws.valid_q[ws.valid_in_V],
        {k: np.asarray(v, dtype=float) for k, v in settings.get("postures", {}).items()},
        float(settings.get("ground_clearance", 0.02)),
    )


def grid_of(settings: dict[str, Any]) -> tuple[list[Config], np.ndarray]:
    """The configurations and the slope offsets [rad] of the settings' ``grid``."""
    g = settings["grid"]
    grid = configs(
        np.radians(g["heading_deg"]), g["payload"], list(g["arm"]), g["friction"], g["speed"]
    )
    return grid, np.radians(np.asarray(g["offsets_deg"], dtype=float))


def sim_settings(settings: dict[str, Any]) -> dict[str, SimSettings]:
    """One :class:`SimSettings` per MuJoCo model of the settings."""
    return {
        name: SimSettings(**settings["sim"], model=ModelSettings(**(overrides or {})))
        for name, overrides in settings["models"].items()
    }


def _sim_task(
    postures: ArmPostures,
    sims: dict[str, SimSettings],
    thresholds: Thresholds,
    kind: str,
    model: str,
    index: int,
    config: Config,
    value: float,
    bracket: float = 0.0,
    iterations: int = 0,
) -> tuple[str, str, int, Any]:
    """A worker's task: one case (``kind`` case, ``value`` the slope) or one bisection."""
    if kind == "case":
        return kind, model, index, case_sim(postures, sims[model], thresholds, config, value)
    found = bisect_tip(postures, sims[model], thresholds, config, value, bracket, iterations)
    return kind, model, index, found


def confusion(predicted: list[str], simulated: list[str]) -> dict[str, dict[str, int]]:
    """Counts: ``out[mmstab's verdict][MuJoCo's verdict]``."""
    out = {p: {s: 0 for s in VERDICTS} for p in VERDICTS}
    for p, s in zip(predicted, simulated, strict=True):
        out[p][s] += 1
    return out


def case_row(case: Case, prediction: Prediction, sim: Any) -> dict[str, Any]:
    """One case of ``summary.json`` (angles in degrees)."""
    c = case.config
    return {
        "index": case.row,
        "heading_deg": float(np.degrees(c.heading)),
        "payload_kg": c.payload,
        "arm": c.arm,
        "friction": c.friction,
        "speed": c.speed,
        "binds": prediction.binds,
        "critical_deg": float(np.degrees(prediction.critical)),
        "offset_deg": float(np.degrees(case.offset)),
        "slope_deg": float(np.degrees(case.angle)),
        "posture": case.posture.tolist(),
        "mu": case.mu,
        "mmstab": case.verdict,
        "mujoco": sim.verdict,
        "agree": case.verdict == sim.verdict,
        "event_s": sim.time,
        "tilt_deg": sim.tilt_deg,
        "slip_m": sim.slip_m,
        "arm_ground": sim.arm_ground,
    }


def model_summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Confusion matrix, agreement and disagreements of one model's rows."""
    agree = sum(r["agree"] for r in rows)
    return {
        "cases": len(rows),
        "agree": agree,
        "agreement": agree / len(rows) if rows else float("nan"),
        "confusion": confusion([r["mmstab"] for r in rows], [r["mujoco"] for r in rows]),
        "disagreements": [r for r in rows if not r["agree"]],
        "arm_ground_cases": sum(r["arm_ground"] for r in rows),
        "rows": rows,
    }


def bisection_row(config: Config, found: Any) -> dict[str, Any]:
    """One bisected tip slope of ``summary.json`` (degrees)."""
    predicted, simulated = np.degrees(found.predicted), np.degrees(found.simulated)
    return {
        "heading_deg": float(np.degrees(config.heading)),
        "payload_kg": config.payload,
        "arm": config.arm,
        "friction": config.friction,
        "speed": config.speed,
        "predicted_deg": float(predicted),
        "simulated_deg": None if np.isnan(simulated) else float(simulated),
        "error_deg": None if np.isnan(simulated) else float(simulated - predicted),
        "bracket_deg": [float(np.degrees(found.lo)), float(np.degrees(found.hi))],
        "runs": found.runs,
    }


def slope_summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """How close the bisected tip slopes come to mmstab's."""
    errors = np.array([r["error_deg"] for r in rows if r["error_deg"] is not None])
    return {
        "configurations": len(rows),
        "bracketed": len(errors),
        "within_1_deg": int(np.sum(np.abs(errors) <= 1.0)),
        "max_abs_error_deg": float(np.max(np.abs(errors))) if len(errors) else None,
        "mean_error_deg": float(np.mean(errors)) if len(errors) else None,
        "rows": rows,
    }


def _tasks(
    settings: dict[str, Any], grid: list[Config], predictions: list[Prediction], cases: list[Case]
) -> list[tuple[Any, ...]]:
    """Every simulation of the run: each case on each model, then the bisections."""
    tasks: list[tuple[Any, ...]] = [
        ("case", model, c.row, c.config, c.angle) for model in settings["models"] for c in cases
    ]
    b = settings["bisection"]
    for model in b["models"]:
        for k, (config, p) in enumerate(zip(grid, predictions, strict=True)):
            if p.binds == "tip" and config.speed == 0:
                bracket = float(np.radians(b["bracket_deg"]))
                tasks.append(("bisect", model, k, config, p.tip_slope, bracket, b["iterations"]))
    return tasks


def run_verdicts(
    settings: dict[str, Any], out: str | Path, cache_dir: str | None = None
) -> dict[str, Any]:
    """Build the grid, simulate it, write ``summary.json`` and ``verdicts.png``; the summary."""
    t0 = time.perf_counter()
    postures = arm_postures(settings, cache_dir)
    grid, offsets = grid_of(settings)
    predictions, cases = build_cases(postures, grid, offsets)
    by_config = {c: p for c, p in zip(grid, predictions, strict=True)}
    sims, thresholds = sim_settings(settings), Thresholds(**settings["thresholds"])
    tasks = _tasks(settings, grid, predictions, cases)
    results: dict[tuple[str, str, int], Any] = {}
    workers = int(settings.get("workers", 1))
    with ChunkPool(_sim_task, (postures, sims, thresholds), workers) as pool:
        for kind, model, index, value in pool.run(tasks):
            results[(kind, model, index)] = value
    models = {
        model: model_summary(
            [case_row(c, by_config[c.config], results[("case", model, c.row)]) for c in cases]
        )
        for model in settings["models"]
    }
    slopes = {
        model: slope_summary(
            [
                bisection_row(grid[k], v)
                for (kind, m, k), v in sorted(results.items())
                if kind == "bisect" and m == model
            ]
        )
        for model in settings["bisection"]["models"]
    }
    main = models[settings["main_model"]]
    summary = {
        "settings": settings,
        "candidates": len(postures.candidates),
        "configurations": len(grid),
        "cases": len(cases),
        "main_model": settings["main_model"],
        "agreement": main["agreement"],
        "models": models,
        "tip_slopes": slopes,
        "seconds": time.perf_counter() - t0,
    }
    out = Path(out)
    write_json(out / "summary.json", summary)
    from experiments.verdicts_figure import verdicts_figure

    verdicts_figure(summary, out / "verdicts.png")
    return summary


def main(argv: list[str] | None = None) -> int:
    """``python -m experiments.verdicts [SETTINGS] [-o DIR]``; the exit status."""
    got = experiment_run(
        argv, __doc__, "problems/verdicts.yaml", "results/verdicts", run_verdicts, load_settings
    )
    if isinstance(got, int):
        return got
    s, out = got
    for name, m in s["models"].items():
        t = s["tip_slopes"].get(name)
        slope = f"; tip slope within 1 deg {t['within_1_deg']}/{t['bracketed']}" if t else ""
        print(f"{name}: {m['agree']}/{m['cases']} agree ({100 * m['agreement']:.1f} %){slope}")
    print(f"-> {out}/summary.json, verdicts.png ({s['seconds']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
