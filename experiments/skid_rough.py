"""Sliding in turns on rough ground: the skid-steer model against MuJoCo along a route.

The ramp grid (:mod:`experiments.skid`) compares the two on planes. Here the same
robot, arm stowed, is set at poses along a problem's route over its heightmap (every
``spacing`` metres), driven at constant track speeds (straight, and arcs that turn toward
either side) and its mean twist set beside :func:`mmstab.stability.skid.skid_twist`'s for
the same belts, CoM and gravity in B (MuJoCo's attitude at the window's start). The model
rests the belts on one plane; the heightfield's bumps give the tracks a few loaded road
wheels whose contact normals follow the bumps.

The ``rough_ground`` section of ``problems/skid.yaml``: ``problem`` (its terrain, friction and
route), ``spacing`` [m], ``commands`` ([speed m/s, yaw rate rad/s] by name). Results go to
``summary.json``'s ``rough_ground`` and ``rough.png``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from experiments.skid_measures import TURNING, downhill_beyond, median, per_radian
from mmstab.core.files import ConfigError, write_figure

#: A turn counts toward uphill or downhill when the slope's in-plane gravity is at least
#: this share of g (about 3 degrees of tilt) [-].
SLOPED = 0.05


def check_section(path: str | Path, section: Any) -> dict[str, Any]:
    """The ``rough_ground`` section, checked (its problem's path resolved)."""
    where = "rough_ground"
    if not isinstance(section, dict):
        raise ConfigError(path, where, "a mapping: problem, spacing, commands")
    missing = [k for k in ("problem", "spacing", "commands") if k not in section]
    if missing:
        raise ConfigError(path, where, f"missing {', '.join(missing)}")
    try:
        spacing = float(section["spacing"])
    except (TypeError, ValueError):
        raise ConfigError(path, f"{where}.spacing", "a distance [m]") from None
    if not 0.05 <= spacing <= 100.0:
        raise ConfigError(path, f"{where}.spacing", "between 0.05 and 100 m")
    commands = section["commands"]
    if not isinstance(commands, dict) or not commands:
        raise ConfigError(path, f"{where}.commands", "a mapping of [speed m/s, yaw rate rad/s]")
    for name, c in commands.items():
        if not (isinstance(c, list) and len(c) == 2):
            raise ConfigError(path, f"{where}.commands.{name}", "[speed m/s, yaw rate rad/s]")
    return {**section, "problem": str(Path(path).parent / section["problem"]),
            "spacing": spacing}  # fmt: skip


def route_poses(problem: Any, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """(arc lengths (K,) [m], poses (K, 3) in M) every ``spacing`` [m] along the base path."""
    from mmstab.control.reference import circle_pose

    u = np.linspace(0.0, 1.0, 4001)
    dense = np.asarray(circle_pose(problem.base_path, u).value)
    s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(dense[:, :2], axis=0), axis=1))]
    want = np.arange(0.0, s[-1] + 1e-9, spacing)
    idx = np.minimum(np.searchsorted(s, want), len(s) - 1)
    return s[idx], dense[idx]


def run_cases(robot: Any, section: dict[str, Any], sim: dict[str, Any]) -> list[dict[str, Any]]:
    """Every pose × command: MuJoCo's twist on the heightfield and the model's."""
    from mmstab.core.problem import load_problem
    from mmstab.physics.skid_sim import measure_twist_at
    from mmstab.stability.skid import skid_twist, track_patch
    from mmstab.stability.slip import terrain_friction

    ground = load_problem(section["problem"])
    mu, shear = terrain_friction(ground.terrain), float(ground.section("physics")["shear_modulus"])
    patch, b = track_patch(robot), robot.base.tracks.separation
    com = robot.overall_com(robot.arm_com(robot.stowed))
    cases = []
    for s, pose in zip(*route_poses(ground, section["spacing"]), strict=True):
        for name, (v, w) in section["commands"].items():
            belts = (v - w * b / 2, v + w * b / 2)
            m = measure_twist_at(robot, ground.terrain, pose, belts, settle=sim["settle"],
                                 transient=sim["transient"], duration=sim["duration"])  # fmt: skip
            p = skid_twist(patch, m.gravity_body, com, belts, mu, shear)
            cases.append(_case(float(s), pose, name, (float(v), float(w)), m, p, com))
    return cases


def _case(s: float, pose: Any, name: str, cmd: Any, m: Any, p: Any, com: Any) -> dict[str, Any]:
    g = np.asarray(m.gravity_body, dtype=float)
    in_plane = float(np.linalg.norm(g[:2]))
    down = g[:2] / max(in_plane, 1e-12)
    v, w = cmd
    # a left turn (w > 0) swings the nose toward +y_B: uphill where gravity in B points to -y
    toward = None
    if w != 0 and in_plane >= SLOPED * float(np.linalg.norm(g)):
        toward = "uphill" if w * g[1] < 0 else "downhill"

    def downhill(velocity: Any, yaw_rate: Any) -> float:  # the CoM's, beyond (v, 0)
        return downhill_beyond(velocity, yaw_rate, com, v, down)

    return {
        "s_m": s, "pose": [float(x) for x in pose], "command": name, "speed": v,
        "yaw_rate_commanded": w, "toward": toward,
        "tilt_deg": float(np.degrees(np.arccos(np.clip(-g[2] / np.linalg.norm(g), -1, 1)))),
        "gravity_body": g.tolist(),
        "mujoco": {"velocity_body": m.velocity_body.tolist(), "yaw_rate": m.yaw_rate,
                   "downhill": downhill(m.velocity_body, m.yaw_rate)},
        "model": {"velocity_body": [_finite(x) for x in p.velocity_body[0]],
                  "yaw_rate": _finite(p.yaw_rate[0]),
                  "downhill": _finite(downhill(p.velocity_body[0], p.yaw_rate[0])),
                  "holds": bool(p.holds[0])},
    }  # fmt: skip


def _finite(x: Any) -> float | None:
    """None where the model has no twist (its cone does not hold: NaN)."""
    return float(x) if np.isfinite(x) else None


def _nan(x: float | None) -> float:
    return float("nan") if x is None else x


def summarize(cases: list[dict[str, Any]]) -> dict[str, Any]:
    """Straight driving's downhill creep and the turns' yaw rate over the command.

    Over the cases where the model holds (its cone holds at MuJoCo's attitude): the largest
    and the median downhill creep driving straight, the poses where MuJoCo creeps more than
    1 cm/s; the median yaw rate over the commanded one for turns toward uphill and downhill,
    and the downhill slide per radian of the turns that turn (MuJoCo at least
    :data:`~experiments.skid_measures.TURNING`, as on the ramp grid): each side's median, and
    the model's over MuJoCo's.
    """
    held = [c for c in cases if c["model"]["holds"]]
    straight = [c for c in held if c["yaw_rate_commanded"] == 0 and c["speed"] != 0]
    creep = {k: [c[k]["downhill"] for c in straight] for k in ("mujoco", "model")}
    out: dict[str, Any] = {
        "cases": len(cases),
        "model_holds": len(held),
        "straight": {
            "poses": len(straight),
            "mujoco_downhill_max_m_s": max(creep["mujoco"], default=None),
            "mujoco_downhill_median_m_s": median(creep["mujoco"]),
            "model_downhill_max_m_s": max(creep["model"], default=None),
            "mujoco_creeps_over_1cm_s": [
                {
                    "s_m": c["s_m"],
                    "tilt_deg": c["tilt_deg"],
                    "downhill_m_s": c["mujoco"]["downhill"],
                }
                for c in straight
                if c["mujoco"]["downhill"] > 0.01
            ],  # fmt: skip
        },
    }
    turning = [c for c in held if c["toward"] and abs(c["mujoco"]["yaw_rate"]) >= TURNING]
    for toward in ("uphill", "downhill"):
        turns = [c for c in held if c["toward"] == toward]
        out[f"turns_{toward}"] = {
            "cases": len(turns),
            **{f"{k}_yaw_over_commanded_median": median(
                [c[k]["yaw_rate"] / c["yaw_rate_commanded"] for c in turns])
               for k in ("mujoco", "model")},
            **{f"{k}_slide_per_radian_median_m": median(
                [per_radian(c[k]) for c in turning if c["toward"] == toward])
               for k in ("mujoco", "model")},
        }  # fmt: skip
    ratio = [per_radian(c["model"]) / per_radian(c["mujoco"]) for c in turning]
    out["slide_per_radian_model_over_mujoco"] = {
        "cases": len(ratio),
        "median": median(ratio),
        "p5_p95": [float(np.percentile(ratio, q)) for q in (5, 95)] if ratio else None,
    }
    return out


def figure(cases: list[dict[str, Any]], path: Path) -> None:
    """Along the route: straight driving's downhill creep, and the turns' yaw over command."""
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
    straight = [c for c in cases if c["yaw_rate_commanded"] == 0 and c["speed"] != 0]
    s = [c["s_m"] for c in straight]
    for k, style in (("mujoco", "o-"), ("model", "s--")):
        a.plot(s, [100 * _nan(c[k]["downhill"]) for c in straight], style, ms=3, label=k)
    a.set(ylabel="downhill creep [cm/s]", title="driving straight at its speed")
    a.legend(loc="upper left")
    tilt = a.twinx()
    tilt.plot(s, [c["tilt_deg"] for c in straight], color="0.6", lw=0.8)
    tilt.set_ylabel("tilt [deg]", color="0.5")
    for toward, colour in (("uphill", "tab:red"), ("downhill", "tab:blue")):
        turns = [c for c in cases if c["toward"] == toward]
        x = [c["s_m"] for c in turns]
        for k, marker in (("mujoco", "o"), ("model", "x")):
            y = [_nan(c[k]["yaw_rate"]) / c["yaw_rate_commanded"] for c in turns]
            b.scatter(x, y, marker=marker, s=14, color=colour, label=f"{k}, toward {toward}")
    b.axhline(0.0, color="k", lw=0.6)
    b.set(xlabel="along the route [m]", ylabel="yaw rate / commanded [-]", title="arcs")
    b.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    write_figure(path, fig)
