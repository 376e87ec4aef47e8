"""Levers, flippers: μ along the lap, arm only vs arm + flippers."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from experiments.levers.common import LeversSettings, planar_slope
from mmstab.app.settings import Settings
from mmstab.core.files import write_figure
from mmstab.core.problem import Problem, load_problem
from mmstab.planner import solve_path
from mmstab.planner.levers import solve_path_flippers
from mmstab.terrain import Terrain, from_section
from mmstab.viz.plotting import new_figure


def run_flippers(
    problem: Problem, ws: Any, settings: LeversSettings
) -> tuple[dict[str, Any], dict[str, Any]]:
    """μ along the lap, arm only vs arm + flippers, on the problem's ramp and the side slope."""
    robot = problem.robot
    # the exhaustive search on both sides: no sampling noise between the two plans
    every = Settings.from_problem(problem)
    psettings = every.planner._replace(method="exhaustive")
    loaded_settings = psettings._replace(flipper_angles=settings.flipper_angles)
    poses = problem.circle.poses(psettings.poses)
    dt = every.controller.lap_time / psettings.poses
    grounds: dict[str, Terrain] = {
        "ramp": problem.terrain,
        "side_slope": planar_slope(problem, settings.side_slope),
    }
    out: dict[str, Any] = {"flipper_angles_per_pose": settings.flipper_angles}
    curves: dict[str, Any] = {"fraction": np.arange(psettings.poses) / psettings.poses}
    paths = {name: (poses, dt) for name in grounds}
    rp = (
        None
        if settings.rough_problem is None
        else load_problem(problem.path.parent / settings.rough_problem)
    )
    route = None if rp is None else rp.route
    if rp is not None and route is not None:  # the rough route's poses, its driving time
        grounds["rough_route"] = from_section(rp.path, rp.section("terrain"), robot)
        paths["rough_route"] = (route.poses(psettings.poses), route.duration / psettings.poses)
    for name, terrain in grounds.items():
        poses, dt = paths[name]
        arm_only = np.array(
            [t.mu for t in solve_path(robot, terrain, ws, poses, psettings).targets]
        )
        both = solve_path_flippers(robot, terrain, ws, poses, loaded_settings, dt)
        curves[f"{name}_arm"], curves[f"{name}_flippers"] = arm_only, both.mu
        curves[f"{name}_angles"] = both.flipper_angles
        out[name] = {
            "terrain": terrain.label,
            "mu_arm_only_min": float(arm_only.min()),
            "mu_arm_only_mean": float(arm_only.mean()),
            "mu_arm_flippers_min": float(both.mu.min()),
            "mu_arm_flippers_mean": float(both.mu.mean()),
            "flipper_angles_rad": both.flipper_angles.tolist(),
        }
    return out, curves


def draw_flippers(
    curves: dict[str, Any], summary: dict[str, Any], limits: tuple[float, float], path: Path
) -> None:
    """μ along the lap, arm only vs arm + flippers, and the flipper angle (within ``limits``)."""
    names = [n for n in ("ramp", "side_slope", "rough_route") if n in summary]
    fig, axes = new_figure(2, len(names), figsize=(5 * len(names), 5.4), sharex=True)
    s = curves["fraction"]
    for j, name in enumerate(names):
        ax, ax_a = axes[0, j], axes[1, j]
        ax.plot(s, curves[f"{name}_arm"], "o-", label="arm only (flippers fixed)")
        ax.plot(s, curves[f"{name}_flippers"], "s-", label="arm + flippers")
        ax.set(title=summary[name]["terrain"], ylabel="mu [N rad]")
        ax_a.step(s, curves[f"{name}_angles"], where="post")
        ax_a.set(xlabel="path fraction", ylabel="flipper angle [rad]", ylim=limits)
    axes[0, 0].legend(fontsize=8)
    write_figure(path, fig)


# ------------------------------------------------------------------------------------- all
