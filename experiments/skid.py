"""Sliding in turns: mmstab's skid-steer model against the whole robot in MuJoCo.

Settings come from ``problems/skid.yaml``: the robot's problem, the friction, the ramp
slopes and headings, the track commands (pivots, arcs, straight) and the durations.
For every slope × heading × command the robot is driven on a MuJoCo ramp
(:func:`mmstab.physics.skid_sim.measure_twist`) and its mean twist is set beside the
steady twist of :func:`mmstab.stability.skid.skid_twist` for the same belt speeds, gravity and
CoM. ``make skid`` (``python -m experiments.skid``) writes ``results/skid/summary.json``
(every case; the medians of the slide per radian of heading change and of the turn rate,
model over MuJoCo) and ``skid.png``; with a ``rough_ground`` section, the same along a
route over a heightmap (:mod:`experiments.skid_rough`, ``rough.png``).
``docs/skid.md``, explains them.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from experiments import skid_rough
from experiments.common import experiment_run
from experiments.skid_measures import TURNING, downhill_beyond, median, per_radian
from mmstab.core.files import ConfigError, read_yaml, write_figure, write_json
from mmstab.physics.skid_sim import measure_twist
from mmstab.stability.skid import skid_twist, track_patch

#: Keys the settings file must have.
REQUIRED = ("problem", "friction", "slopes_deg", "headings_deg", "commands", "sim")


def load_settings(path: str | Path) -> dict[str, Any]:
    """The settings file, checked for its sections (the problem's path resolved)."""
    data = read_yaml(path)
    missing = [k for k in REQUIRED if k not in data]
    if missing:
        raise ConfigError(path, "", f"missing {', '.join(missing)}")
    for key in ("slopes_deg", "headings_deg"):
        if not isinstance(data[key], list) or not data[key]:
            raise ConfigError(path, key, "a non-empty list of angles [deg]")
    for name, c in data["commands"].items():
        if not (isinstance(c, list) and len(c) == 2):
            raise ConfigError(path, f"commands.{name}", "[speed m/s, yaw rate rad/s]")
    if not float(data["friction"]) > 0:
        raise ConfigError(path, "friction", "must be > 0")
    data["problem"] = str(Path(path).parent / data["problem"])
    if "rough_ground" in data:
        data["rough_ground"] = skid_rough.check_section(path, data["rough_ground"])
    return data


def run_cases(settings: dict[str, Any]) -> list[dict[str, Any]]:
    """Every slope × heading × command: MuJoCo's twist and the model's."""
    from mmstab.core.problem import load_problem

    problem = load_problem(settings["problem"])
    robot, shear = problem.robot, float(problem.section("physics")["shear_modulus"])
    patch, b = track_patch(robot), robot.base.tracks.separation
    com = robot.overall_com(robot.arm_com(robot.stowed))
    mu, sim = float(settings["friction"]), settings["sim"]
    cases = []
    for slope in settings["slopes_deg"]:
        for heading in settings["headings_deg"]:
            for name, (v, w) in settings["commands"].items():
                belts = (v - w * b / 2, v + w * b / 2)
                m = measure_twist(robot, np.radians(slope), np.radians(heading), belts, mu,
                                  settle=sim["settle"], transient=sim["transient"],
                                  duration=sim["duration"])  # fmt: skip
                p = skid_twist(patch, m.gravity_body, com, belts, mu, shear)
                cases.append(_case(slope, heading, name, (v, w), m, p, com))
    return cases


def _case(
    slope: float, heading: float, name: str, cmd: Any, m: Any, p: Any, com: Any
) -> dict[str, Any]:
    g = m.gravity_body
    down = g[:2] / max(float(np.linalg.norm(g[:2])), 1e-12)
    v, w = cmd
    # the CoM's velocity beyond the commanded (v, 0), downhill
    mj = downhill_beyond(m.velocity_body, m.yaw_rate, com, v, down)
    model = downhill_beyond(p.velocity_body[0], p.yaw_rate[0], com, v, down)
    return {
        "slope_deg": float(slope), "heading_deg": float(heading), "command": name,
        "speed": float(v), "yaw_rate_commanded": float(w),
        "gravity_body": np.asarray(g, dtype=float).tolist(),
        "mujoco": {"velocity_body": m.velocity_body.tolist(), "yaw_rate": m.yaw_rate,
                   "downhill": mj},
        "model": {"velocity_body": p.velocity_body[0].tolist(), "yaw_rate": float(p.yaw_rate[0]),
                  "downhill": model, "holds": bool(p.holds[0])},
    }  # fmt: skip


def summarize(cases: list[dict[str, Any]]) -> dict[str, Any]:
    """Medians over the turning cases: slide per radian and turn rate, model over MuJoCo."""
    turning = [c for c in cases if abs(c["mujoco"]["yaw_rate"]) >= TURNING]
    sloped = [c for c in turning if c["slope_deg"] > 0 and abs(c["model"]["yaw_rate"]) > 0]
    per_rad = [(per_radian(c["mujoco"]), per_radian(c["model"])) for c in sloped]
    slides = [(a, b) for a, b in per_rad if a > 0.02]  # a slide worth a ratio: > 2 cm/rad
    rates = [c["model"]["yaw_rate"] / c["mujoco"]["yaw_rate"] for c in turning]
    straight = [c for c in cases if c["yaw_rate_commanded"] == 0 and c["speed"] != 0]
    stuck = [c for c in cases if c["yaw_rate_commanded"] != 0 and c not in turning]
    ratios = [b / a for a, b in slides]
    return {
        "cases": len(cases),
        "turning_cases": len(turning),
        "slide_per_radian_ratio_median": median(ratios),
        "slide_per_radian_ratio_range": [min(ratios), max(ratios)] if ratios else None,
        "slide_per_radian_abs_error_median_m": median([abs(b - a) for a, b in per_rad]),
        "turn_rate_ratio_median": median(rates),
        "straight_downhill_max_m_s": {
            k: max((abs(c[k]["downhill"]) for c in straight), default=None)
            for k in ("mujoco", "model")
        },
        "cannot_turn": [
            {k: c[k] for k in ("slope_deg", "heading_deg", "command")}
            | {
                "mujoco_downhill": c["mujoco"]["downhill"],
                "model_downhill": c["model"]["downhill"],
                "model_yaw_rate": c["model"]["yaw_rate"],
            }
            for c in stuck
        ],  # fmt: skip
    }


def figure(cases: list[dict[str, Any]], path: Path) -> None:
    """Slide per radian and yaw rate: the model against MuJoCo, coloured by slope."""
    import matplotlib.pyplot as plt

    turning = [c for c in cases if abs(c["mujoco"]["yaw_rate"]) >= TURNING]
    fig, (a, b) = plt.subplots(1, 2, figsize=(9, 4))
    slope = [c["slope_deg"] for c in turning]
    x = [per_radian(c["mujoco"]) for c in turning]
    y = [per_radian(c["model"]) for c in turning]
    sc = a.scatter(x, y, c=slope, cmap="viridis", s=18)
    top = max(max(x), max(y)) * 1.05
    a.plot([0, top], [0, top], "k--", lw=0.8)
    a.set(xlabel="MuJoCo [m/rad]", ylabel="model [m/rad]", title="downhill slide per radian")
    rates = [[abs(c[k]["yaw_rate"]) for c in turning] for k in ("mujoco", "model")]
    b.scatter(rates[0], rates[1], c=slope, cmap="viridis", s=18)
    b.plot([0, 0.45], [0, 0.45], "k--", lw=0.8)
    b.set(xlabel="MuJoCo |yaw rate| [rad/s]", ylabel="model [rad/s]", title="turn rate")
    fig.colorbar(sc, ax=b, label="slope [deg]")
    fig.tight_layout()
    write_figure(path, fig)


def run_skid(settings: dict[str, Any], out: str | Path) -> dict[str, Any]:
    """Run the grid; write ``summary.json`` and ``skid.png`` to ``out``."""
    t0 = time.perf_counter()
    cases = run_cases(settings)
    d = Path(out)
    d.mkdir(parents=True, exist_ok=True)
    summary = {"settings": settings, **summarize(cases), "all_cases": cases}
    figure(cases, d / "skid.png")
    if "rough_ground" in settings:
        from mmstab.core.problem import load_problem

        robot = load_problem(settings["problem"]).robot
        rough = skid_rough.run_cases(robot, settings["rough_ground"], settings["sim"])
        summary["rough_ground"] = {**skid_rough.summarize(rough), "all_cases": rough}
        skid_rough.figure(rough, d / "rough.png")
    summary["seconds"] = time.perf_counter() - t0
    write_json(d / "summary.json", summary)
    return summary


def _cm(speed: float | None) -> str:
    return "n/a" if speed is None else f"{100 * speed:.1f} cm/s"


def _ratio(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.2f}"


def main(argv: list[str] | None = None) -> int:
    """``python -m experiments.skid [SETTINGS] [-o DIR]``; the exit status."""
    got = experiment_run(
        argv, __doc__, "problems/skid.yaml", "results/skid", run_skid, load_settings
    )
    if isinstance(got, int):
        return got
    s, out = got
    print(
        f"{s['turning_cases']}/{s['cases']} cases turn; slide per radian, model/MuJoCo: median "
        f"{_ratio(s['slide_per_radian_ratio_median'])}; turn rate model/MuJoCo: median "
        f"{_ratio(s['turn_rate_ratio_median'])}"
    )
    if "rough_ground" in s:
        r = s["rough_ground"]
        up, down = r["turns_uphill"], r["turns_downhill"]
        print(
            f"rough ground: {r['cases']} cases; straight, downhill creep max MuJoCo "
            f"{_cm(r['straight']['mujoco_downhill_max_m_s'])} / model "
            f"{_cm(r['straight']['model_downhill_max_m_s'])}; yaw over commanded toward uphill "
            f"{_ratio(up['mujoco_yaw_over_commanded_median'])} / "
            f"{_ratio(up['model_yaw_over_commanded_median'])}, toward downhill "
            f"{_ratio(down['mujoco_yaw_over_commanded_median'])} / "
            f"{_ratio(down['model_yaw_over_commanded_median'])} (MuJoCo / model)"
        )
    figures = "skid.png, rough.png" if "rough_ground" in s else "skid.png"
    print(f"-> {out}/summary.json, {figures} ({s['seconds']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
