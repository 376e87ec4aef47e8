"""Levers, variants: μ and the steepest side slope per robot file."""

from __future__ import annotations

import copy
import functools
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from experiments.levers.common import LeversSettings, bisect_largest, planar_slope
from mmstab.app.settings import Settings
from mmstab.core.files import ConfigError, write_figure
from mmstab.core.problem import Problem, load_problem, problem_from_dict
from mmstab.model.robot import FloatArray, Robot
from mmstab.planner import best_mu, solve_path
from mmstab.stability.static import contact_force_angle, robot_force_angle
from mmstab.terrain import GRAVITY_G, Terrain, from_section
from mmstab.viz.plotting import new_figure


def variant_problem(problem: Problem, robot_file: str, grid: tuple[int, ...]) -> Problem:
    """The problem with another robot file (relative to the problem) and workspace grid."""
    data = copy.deepcopy(problem.data)
    data["robot"] = robot_file
    data["workspace"]["grid"] = list(grid)
    return problem_from_dict(data, problem.path, force_size=problem.force_size)


def check_variant_files(problem: Problem, settings: LeversSettings) -> None:
    """Load ``levers.robots`` and ``levers.rough_problem`` before any work (bad input: exit 2).

    Without it a missing robot file was found after the workspace, the plan and two figures.

    Raises:
        ConfigError: naming the robot (or rough problem) file and its field, or the
            ``levers.robots[i]`` entry whose robot does not fit the problem.
    """
    for i, robot_file in enumerate(settings.robots):
        where = (problem.path.parent / robot_file).resolve()
        if not where.is_file():
            raise ConfigError(
                problem.path, f"levers.robots[{i}]", f"no robot description at {where}"
            )
        try:
            variant_problem(problem, robot_file, settings.variant_grid)
        except ConfigError as exc:
            if Path(exc.path) != problem.path:
                raise  # the robot file's own field
            msg = f"{robot_file}: {exc.field}: {exc.message}"
            raise ConfigError(problem.path, f"levers.robots[{i}]", msg) from None
    if settings.rough_problem is not None:
        load_problem(problem.path.parent / settings.rough_problem)


def steepest_side_slope(
    problem: Problem, mu_of: Callable[[Robot, FloatArray], float], settings: LeversSettings
) -> float | None:
    """Steepest ramp [deg] across which (either side downhill) ``mu_of`` >= the margin."""

    def ok(slope: float) -> bool:
        ground = planar_slope(problem, slope)
        g = ground.gravity_body(np.array([[0.0, 0.0, 0.0], [0.0, 0.0, math.pi]]))
        return min(mu_of(problem.robot, g[0]), mu_of(problem.robot, g[1])) >= settings.margin

    found = bisect_largest(ok, 0.0, settings.max_slope, settings.bisection_steps)
    return None if found != found else math.degrees(found)


def contact_mu(
    robot: Robot, terrain: Terrain, poses: FloatArray, arm_com_body: ArrayLike
) -> FloatArray:
    """μ [N rad] (N,) on the bearing contacts (``Terrain.support``) at poses (N, 3) in M.

    The 3-D contacts that carry the base at rest (its stowed-arm rest pose: the touching
    ones and the tracks' bottom run within the compliance), not the planner's track
    rectangle: on uneven ground the polygon is what the robot stands on (``mmstab rest``).
    """
    coms = np.broadcast_to(np.asarray(arm_com_body, dtype=float), (len(poses), 3))
    out = np.empty(len(poses))
    for i, pose in enumerate(poses):
        stand = terrain.support(robot, pose)
        T = stand.G_T_B
        com_G = T[:3, :3] @ robot.overall_com(coms[i]) + T[:3, 3]
        out[i] = contact_force_angle(stand.bearing(), com_G, robot.total_mass * GRAVITY_G).mu
    return out


def _best_mu_of(robot: Robot, gravity_body: FloatArray, samples: FloatArray) -> float:
    """The best μ over arm-CoM samples (N, 3) [m] at gravity ``gravity_body`` [m/s^2]."""
    return best_mu(robot, gravity_body, samples)[0]


def run_variants(problem: Problem, settings: LeversSettings) -> dict[str, Any]:
    """Each robot file on the problem's lap and on side slopes (module text)."""
    from mmstab.workspace import load_or_build_workspace

    psettings = Settings.from_problem(problem).planner
    out: dict[str, Any] = {"workspace_grid": list(settings.variant_grid), "robots": {}}
    for robot_file in settings.robots:
        t0 = time.perf_counter()
        vp = variant_problem(problem, robot_file, settings.variant_grid)
        ws = load_or_build_workspace(vp, progress=False)
        robot = vp.robot
        poses = vp.circle.poses(psettings.poses)
        plan = solve_path(robot, vp.terrain, ws, poses, psettings)
        gravity = vp.terrain.gravity_body(poses)
        stowed = robot_force_angle(robot, gravity, robot.arm_com(robot.stowed)).mu
        planned = np.array([t.mu for t in plan.targets])
        samples = ws.valid_com_in_V
        rough: dict[str, Any] = {}
        if settings.rough_problem is not None:
            rp = load_problem(problem.path.parent / settings.rough_problem)
            ground = from_section(rp.path, rp.section("terrain"), robot)
            rough_poses = rp.base_path.poses(psettings.poses)
            rough_plan = solve_path(robot, ground, ws, rough_poses, psettings)
            planned_c = contact_mu(robot, ground, rough_poses, rough_plan.target_com)
            stowed_c = contact_mu(robot, ground, rough_poses, robot.arm_com(robot.stowed))
            own = np.array([t.mu for t in rough_plan.targets])
            rough = {
                "rough_mu_planner_own_min": float(own.min()),  # on the track rectangle
                "rough_poses_tipping_on_contacts": int(np.sum(planned_c < 0)),
                "rough_mu_planned_min": float(planned_c.min()),
                "rough_mu_planned_mean": float(planned_c.mean()),
                "rough_mu_stowed_min": float(stowed_c.min()),
                "rough_mu_stowed_mean": float(stowed_c.mean()),
            }
        out["robots"][robot.name] = {
            "file": robot_file,
            "arm_mass_kg": robot.arm_mass,
            "lap_mu_planned_min": float(planned.min()),
            "lap_mu_planned_mean": float(planned.mean()),
            "lap_mu_stowed_min": float(stowed.min()),
            "lap_mu_stowed_mean": float(stowed.mean()),
            "steepest_side_slope_planned_deg": steepest_side_slope(
                vp, functools.partial(_best_mu_of, samples=samples), settings
            ),
            "steepest_side_slope_stowed_deg": steepest_side_slope(
                vp,
                lambda r, g: float(robot_force_angle(r, g, r.arm_com(r.stowed)).mu),
                settings,
            ),
            **rough,
            "seconds": time.perf_counter() - t0,
        }
    if settings.rough_problem is not None:
        out["rough_problem"] = settings.rough_problem
    return out


def draw_variants(summary: dict[str, Any], path: Path) -> None:
    """Lap μ (planned, stowed) and the steepest side slope per robot variant."""
    names = list(summary["robots"])
    rows = [summary["robots"][n] for n in names]
    fig, (ax0, ax1) = new_figure(1, 2, figsize=(10, 3.6))
    x = np.arange(len(names))
    keys = [("lap_mu_planned_min", "ramp, planned"), ("lap_mu_stowed_min", "ramp, stowed")]
    if "rough_problem" in summary:
        keys += [
            ("rough_mu_planned_min", "rough, planned (on the contacts)"),
            ("rough_mu_stowed_min", "rough, stowed (on the contacts)"),
        ]
    w = 0.8 / len(keys)
    for j, (key, label) in enumerate(keys):
        bars = ax0.bar(x + (j - (len(keys) - 1) / 2) * w, [r[key] for r in rows], w, label=label)
        ax0.bar_label(bars, fmt="%.0f", fontsize=6)
    ax0.set_xticks(x, names, fontsize=8)
    ax0.set(ylabel="lowest mu along the lap [N rad]", title="laps: ramp (and rough ground)")
    low, high = ax0.get_ylim()
    ax0.set_ylim(low, high + 0.45 * (high - low))  # room for the legend above the bars
    ax0.legend(fontsize=7, loc="upper center", ncols=2)
    for j, (key, label) in enumerate(
        (
            ("steepest_side_slope_planned_deg", "arm planned"),
            ("steepest_side_slope_stowed_deg", "arm stowed"),
        )
    ):
        bars = ax1.bar(x + (j - 0.5) * 0.38, [r[key] or 0.0 for r in rows], 0.38, label=label)
        ax1.bar_label(bars, fmt="%.1f", fontsize=7)
    ax1.set_xticks(x, names, fontsize=8)
    ax1.set(ylabel="steepest side slope [deg]", title="side slope, mu >= margin")
    ax1.legend(fontsize=8, loc="lower right")
    write_figure(path, fig)


def variants_table(summary: dict[str, Any]) -> str:
    """The variants as a Markdown table."""
    rough = "rough_problem" in summary
    lines = [
        "| robot | arm mass [kg] | ramp lap μ planned min / mean [N rad] | ramp lap μ stowed "
        "min / mean [N rad] | "
        + ("rough lap μ planned / stowed, min [N rad] | " if rough else "")
        + "steepest side slope, planned / stowed [deg] |",
        "|---|---|---|---|---|" + ("---|" if rough else ""),
    ]
    for name, r in summary["robots"].items():
        slope = [r["steepest_side_slope_planned_deg"], r["steepest_side_slope_stowed_deg"]]
        lines.append(
            f"| {name} | {r['arm_mass_kg']:.1f} | {r['lap_mu_planned_min']:.1f} / "
            f"{r['lap_mu_planned_mean']:.1f} | {r['lap_mu_stowed_min']:.1f} / "
            f"{r['lap_mu_stowed_mean']:.1f} | "
            + (
                f"{r['rough_mu_planned_min']:.1f} / {r['rough_mu_stowed_min']:.1f} | "
                if rough
                else ""
            )
            + " / ".join("-" if v is None else f"{v:.1f}" for v in slope)
            + " |"
        )
    return "\n".join(lines) + "\n"
