"""``make skid-rates``: the skid-steer model's slide per radian against the turn rate, in MuJoCo.

The ramp grid of :mod:`experiments.skid` (the whole robot driven on a MuJoCo ramp at constant
track speeds, its mean twist beside :func:`mmstab.stability.skid.skid_twist`'s for the same
belts, gravity and CoM) at turn rates from a creep (0.15 rad/s commanded) to the tracks'
fastest pivots (1.2 rad/s), over a window as long as the slide verdict's. The model is
homogeneous in the belts' speed (the shear makes it nearly so); MuJoCo's slide per radian is
not: it falls as the turn gets faster. What the route's time law
(:mod:`mmstab.runs.time_law`) needs is the model's error where it slows a corner: the
ratio MuJoCo / model over the cases that turn slower than ``slow_yaw_rate``. Its largest
value bounds ``physics.slide_budget`` (the share of ``slip_distance`` a slowed turn's model
slide may use): ``slide_budget <= 1 / ratio`` keeps MuJoCo's slide within the distance
wherever the model's error is no worse than on this grid. The faster turns are the
verdict's: a pivot faster than the tracks turn lasts longer than the path's (MuJoCo turns at
the tracks' rate and slides per second about as the model does at it), and the largest
ratio of the slides per second, MuJoCo over the model, bounds from below the margin
:data:`mmstab.runs.verdict.TRACKS_TIME_MARGIN` the verdict puts on such turns.

Settings: ``problems/skid_rates.yaml``. Writes ``summary.json`` (every case; per command the
median MuJoCo yaw rate and the ratio's median and range; over the slow cases the ratio's
largest value, its case and ``budget_bound``; over the fast ones the slide per second's
ratio, its median and largest).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from experiments import skid
from experiments.common import experiment_run
from experiments.skid_measures import TURNING, per_radian
from mmstab.core.files import ConfigError, write_json

#: Slides per radian below this in MuJoCo are not ratioed (nothing to slide) [m/rad].
MIN_SLIDE = 0.02


def load_settings(path: str | Path) -> dict[str, Any]:
    """:func:`experiments.skid.load_settings` and ``slow_yaw_rate`` [rad/s] (> 0)."""
    data = skid.load_settings(path)
    if not float(data.get("slow_yaw_rate", 0.0)) > 0:
        raise ConfigError(path, "slow_yaw_rate", "a yaw rate > 0 [rad/s]")
    return data


def ratios(cases: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The cases that turn and slide: MuJoCo's yaw rate, both slides per radian, their ratio."""
    out = []
    for c in cases:
        mj, model = c["mujoco"], c["model"]
        if abs(mj["yaw_rate"]) < TURNING or not model["holds"] or model["yaw_rate"] == 0:
            continue
        a, b = per_radian(mj), per_radian(model)
        if a <= MIN_SLIDE or not b > 0:
            continue
        out.append({k: c[k] for k in ("slope_deg", "heading_deg", "command")}
                   | {"yaw_rate": abs(mj["yaw_rate"]), "mujoco_m_rad": a, "model_m_rad": b,
                      "ratio": a / b,
                      "per_second_ratio": mj["downhill"] / model["downhill"]})  # fmt: skip
    return out


def summarize(settings: dict[str, Any], cases: list[dict[str, Any]]) -> dict[str, Any]:
    """Per command and over the slow turns: the ratio MuJoCo / model of the slide per radian."""
    rated = ratios(cases)
    by_command = {}
    for name in settings["commands"]:
        r = [x for x in rated if x["command"] == name]
        if r:
            q = [x["ratio"] for x in r]
            by_command[name] = {"cases": len(r),
                                "yaw_rate_median": float(np.median([x["yaw_rate"] for x in r])),
                                "ratio_median": float(np.median(q)),
                                "ratio_range": [float(min(q)), float(max(q))]}  # fmt: skip
    slow = [x for x in rated if x["yaw_rate"] <= float(settings["slow_yaw_rate"])]
    fast = [x for x in rated if x["yaw_rate"] > float(settings["slow_yaw_rate"])]
    worst = max(slow, key=lambda x: x["ratio"]) if slow else None
    return {
        "cases": len(cases),
        "rated_cases": len(rated),
        "by_command": by_command,
        "slow": {
            "yaw_rate_max": float(settings["slow_yaw_rate"]),
            "cases": len(slow),
            "ratio_median": float(np.median([x["ratio"] for x in slow])) if slow else None,
            "ratio_max": None if worst is None else worst["ratio"],
            "worst_case": worst,
            "budget_bound": None if worst is None else 1.0 / worst["ratio"],
        },
        "fast": {
            "cases": len(fast),
            "ratio_median": float(np.median([x["ratio"] for x in fast])) if fast else None,
            "ratio_max": max((x["ratio"] for x in fast), default=None),
            "per_second_ratio_median": float(np.median([x["per_second_ratio"] for x in fast]))
            if fast
            else None,
            "per_second_ratio_max": max((x["per_second_ratio"] for x in fast), default=None),
        },
        "rated": rated,
    }


def run_rates(settings: dict[str, Any], out: str | Path) -> dict[str, Any]:
    """Run the grid; write ``summary.json`` to ``out``."""
    t0 = time.perf_counter()
    cases = skid.run_cases(settings)
    summary = {"settings": settings, **summarize(settings, cases), "all_cases": cases,
               "seconds": time.perf_counter() - t0}  # fmt: skip
    Path(out).mkdir(parents=True, exist_ok=True)
    write_json(Path(out) / "summary.json", summary)
    return summary


def main(argv: list[str] | None = None) -> int:
    """``python -m experiments.skid_rates [SETTINGS] [-o DIR]``; the exit status."""
    got = experiment_run(argv, __doc__, "problems/skid_rates.yaml", "results/skid_rates",
                         run_rates, load_settings)  # fmt: skip
    if isinstance(got, int):
        return got
    s, out = got
    for name, c in s["by_command"].items():
        lo, hi = c["ratio_range"]
        print(f"{name}: yaw {c['yaw_rate_median']:.2f} rad/s, MuJoCo/model per radian median "
              f"{c['ratio_median']:.2f} ({lo:.2f}-{hi:.2f})")  # fmt: skip
    slow = s["slow"]
    print(f"slow turns (<= {slow['yaw_rate_max']} rad/s): {slow['cases']} cases, ratio max "
          f"{slow['ratio_max']}, slide_budget <= {slow['budget_bound']}")  # fmt: skip
    print(f"-> {out}/summary.json ({s['seconds']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
