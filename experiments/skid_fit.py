"""``make skid-fit``: the belts' shear modulus K fitted on the skid experiment's MuJoCo runs.

The skid-steer model (:func:`mmstab.stability.skid.skid_twist`) with Wong-Chiang shear: a belt
element's friction is ``μ n (1 - exp(-j / K))`` along its slip velocity, j the shear
displacement it gathered since it touched down. A belt that slips lengthwise (or runs at
all) keeps little sideways resistance in reserve, so the robot creeps downhill inside the
static friction cone, faster the softer the belts' grip (the larger K). K is fitted here on
``make skid``'s cases (the training set: the ramp grid and the poses along ``rough.yaml``'s
route; the validation routes are held out): the downhill velocity of the CoM (projected on
the support plane) beyond the commanded (v, 0), MuJoCo's against the model's for the same
belts, gravity in B and CoM, over the cases on a slope where the model's cone holds. K
minimises the pinball loss at ``quantile`` (the model under-predicts in about 1 - quantile
of the cases), searched on a log grid; ``bootstrap`` resamples of the cases (seeded) give
its spread.

Settings: ``problems/skid_fit.yaml``. Writes ``summary.json`` (K, the loss, the share of cases
the model under-predicts by more than :data:`UNDER` per kind of case, the bootstrap's 5-95 %).
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from experiments.common import experiment_run
from mmstab.core.files import ConfigError, read_yaml, write_json

#: A case counts as under-predicted when MuJoCo's downhill velocity passes the model's by
#: more than this [m/s].
UNDER = 0.005
KEYS = ("data", "problem", "quantile", "grid_m", "grid_points", "bootstrap", "seed")


def load_settings(path: str | Path) -> dict[str, Any]:
    """Read and check the settings (one line naming the file and field on a bad one)."""
    data = read_yaml(path)
    if not isinstance(data, dict):
        raise ConfigError(path, "", "a mapping: " + ", ".join(KEYS))
    for key in KEYS:
        if key not in data:
            raise ConfigError(path, key, "missing")
    if not 0.5 <= float(data["quantile"]) < 1.0:
        raise ConfigError(path, "quantile", "between 0.5 and 1")
    lo, hi = (float(v) for v in data["grid_m"])
    if not 0 < lo < hi <= 1.0:
        raise ConfigError(path, "grid_m", "[low, high] with 0 < low < high <= 1 m")
    here = Path(path).parent
    return {**data, "data_path": str(here / data["data"]),
            "problem_path": str(here / data["problem"])}  # fmt: skip


def training_cases(summary: dict[str, Any]) -> list[dict[str, Any]]:
    """``make skid``'s cases on a slope: ramp grid and rough ground (gravity in B recorded)."""
    cases = [c | {"kind": "ramp"} for c in summary["all_cases"]]
    cases += [c | {"kind": "rough"} for c in summary.get("rough_ground", {}).get("all_cases", [])]
    return [
        c | {"kind": c["kind"] + ("_turn" if c["yaw_rate_commanded"] else "_straight")}
        for c in cases
        if np.hypot(*c["gravity_body"][:2]) > 1e-6  # on a slope: a downhill to slide along
    ]


def model_downhill(robot: Any, friction: float, cases: list[dict[str, Any]], K: float) -> Any:
    """The model's CoM downhill velocity beyond (v, 0) per case at K [m] (NaN: slides)."""
    from mmstab.stability.skid import point_velocity, skid_twist, track_patch

    patch, b = track_patch(robot), robot.base.tracks.separation
    com = robot.overall_com(robot.arm_com(robot.stowed))
    g = np.array([c["gravity_body"] for c in cases], dtype=float)
    v = np.array([c["speed"] for c in cases], dtype=float)
    w = np.array([c["yaw_rate_commanded"] for c in cases], dtype=float)
    belts = np.c_[v - w * b / 2, v + w * b / 2]
    twist = skid_twist(patch, g, com, belts, friction, K)
    down = g[:, :2] / np.linalg.norm(g[:, :2], axis=1, keepdims=True)
    at_com = point_velocity(twist.velocity_body, twist.yaw_rate, com[:2])
    return np.sum((at_com - np.c_[v, np.zeros_like(v)]) * down, axis=1)


def pinball(residual: Any, quantile: float) -> Any:
    """Mean pinball loss of residuals (data - model) along the last axis [m/s]."""
    r = np.asarray(residual, dtype=float)
    return np.mean(np.maximum(quantile * r, (quantile - 1.0) * r), axis=-1)


def fit(settings: dict[str, Any]) -> dict[str, Any]:
    """K on the grid minimising the pinball loss, and its bootstrap spread."""
    from mmstab.core.problem import load_problem
    from mmstab.stability.slip import terrain_friction

    problem = load_problem(settings["problem_path"])
    path = Path(settings["data_path"])
    if not path.exists():
        raise ConfigError(path, "", "missing: run make skid first")
    cases = training_cases(json.loads(path.read_text()))
    lo, hi = (float(x) for x in settings["grid_m"])
    grid = np.r_[0.0, np.geomspace(lo, hi, int(settings["grid_points"]))]
    friction = terrain_friction(problem.terrain)
    model = np.array([model_downhill(problem.robot, friction, cases, K) for K in grid])
    mujoco = np.array([c["mujoco"]["downhill"] for c in cases], dtype=float)
    keep = np.isfinite(model).all(axis=0) & np.isfinite(mujoco)
    model, mujoco = model[:, keep], mujoco[keep]
    kinds = np.array([c["kind"] for c in cases])[keep]
    q = float(settings["quantile"])
    loss = pinball(mujoco[None, :] - model, q)
    best = int(np.argmin(loss))
    rng = np.random.default_rng(int(settings["seed"]))
    draws = rng.integers(0, len(mujoco), size=(int(settings["bootstrap"]), len(mujoco)))
    boot = np.array([grid[np.argmin(pinball(mujoco[d][None, :] - model[:, d], q))] for d in draws])
    under = mujoco - model[best] > UNDER
    under0 = mujoco - model[0] > UNDER
    return {
        "shear_modulus_m": float(grid[best]),
        "quantile": q,
        "cases": int(keep.sum()),
        "cases_left_out": int((~keep).sum()),
        "pinball_loss_m_s": float(loss[best]),
        "pinball_loss_coulomb_m_s": float(loss[0]),
        "under_share": float(under.mean()),
        "under_share_coulomb": float(under0.mean()),
        "under_m_s": UNDER,
        "by_kind": {
            k: {
                "cases": int((kinds == k).sum()),
                "under_share": float(under[kinds == k].mean()),
                "under_share_coulomb": float(under0[kinds == k].mean()),
                "mujoco_median_m_s": float(np.median(mujoco[kinds == k])),
                "model_median_m_s": float(np.median(model[best][kinds == k])),
            }
            for k in sorted(set(kinds))
        },  # fmt: skip
        "bootstrap_p5_p95_m": [float(np.percentile(boot, 5)), float(np.percentile(boot, 95))],
        "grid_m": grid.tolist(),
        "loss_m_s": loss.tolist(),
    }


def run_fit(settings: dict[str, Any], out: str | Path) -> dict[str, Any]:
    """Fit and write ``summary.json`` to ``out``."""
    t0 = time.perf_counter()
    summary = fit(settings)
    summary["settings"] = {k: settings[k] for k in KEYS}
    summary["seconds"] = time.perf_counter() - t0
    d = Path(out)
    d.mkdir(parents=True, exist_ok=True)
    write_json(d / "summary.json", summary)
    return summary


def main(argv: list[str] | None = None) -> int:
    """``python -m experiments.skid_fit [SETTINGS] [-o DIR]``; exit status."""
    got = experiment_run(argv, __doc__, "problems/skid_fit.yaml", "results/skid_fit", run_fit,
                         load_settings)  # fmt: skip
    if isinstance(got, int):
        return got
    s, out = got
    lo, hi = (1000 * x for x in s["bootstrap_p5_p95_m"])
    print(f"shear modulus K = {1000 * s['shear_modulus_m']:.2f} mm (bootstrap 5-95 %: "
          f"{lo:.2f}-{hi:.2f} mm); under-predicted by > {100 * UNDER:g} cm/s: "
          f"{100 * s['under_share']:.0f} % of {s['cases']} cases (Coulomb: "
          f"{100 * s['under_share_coulomb']:.0f} %) -> {out}")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
