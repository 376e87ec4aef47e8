"""Paper Fig. 7 (the planner at one rolled pose) and Fig. 8 (ten poses along the circle).

Fig. 8 also writes ``fig8_mu.png``: planned vs best-achievable mu along the lap
(:mod:`mmstab.outputs.plan_quality`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from mmstab.app import plan as plan_of
from mmstab.app import stability_along, workspace
from mmstab.app.settings import Settings
from mmstab.core.files import MmstabError, write_figure, write_json, write_npz
from mmstab.core.problem import Problem
from mmstab.outputs.common import output_dir, save_settings
from mmstab.outputs.plan_quality import draw_lap_quality, lap_quality
from mmstab.planner import Plan, planning_region, solve_pose
from mmstab.runs.along import lap_stage
from mmstab.runs.plan_verdicts import arm_path_check, lap_along, lap_verdicts
from mmstab.runs.verdict import plan_verdict
from mmstab.stability.dynamic import robot_mu
from mmstab.stability.static import mu_max
from mmstab.terrain import roll_pitch
from mmstab.viz.drawing import (
    draw_poses_on_ground,
    draw_robot,
    mesh_points,
    robot_meshes,
    set_equal_aspect,
)
from mmstab.viz.plotting import draw_arm_3d, draw_circle, new_figure
from mmstab.workspace.ik import PostureSolver


def _side(com_body: np.ndarray) -> str:
    return "left" if com_body[1] > 0 else "right"


def run_fig7(problem: Problem, out: str | Path | None = None) -> dict[str, Any]:
    """Paper Fig. 7: the first CMA samples and the converged CoM at the rolled pose."""
    robot = problem.robot
    ws = workspace(problem)
    every = Settings.from_problem(problem)
    settings = every.planner
    if settings.method == "sequence":  # one pose: the per-pose search the figure shows
        settings = settings._replace(method="cmaes")
    pose = np.array(problem.section("sweep")["roll_pose"], dtype=float)
    rng = np.random.default_rng(settings.seed)
    region = planning_region(ws, every.workspace.method)
    stowed = robot.arm_com(robot.stowed)
    target = solve_pose(robot, problem.terrain, region, pose, stowed, settings, rng)
    solver = PostureSolver(robot, ws)
    realised = solver.posture(target.target_com, robot.stowed)
    first = target.runs[target.best_start].first_samples if target.runs else np.empty((0, 3))
    d = output_dir(out, "fig7")

    fig = new_figure(figsize=(12, 4.2))[0]
    fig.clf()
    ax_a = fig.add_subplot(1, 3, 1, projection="3d")
    ax_b = fig.add_subplot(1, 3, 2, projection="3d")
    ax_c = fig.add_subplot(1, 3, 3)
    draw_robot(ax_a, robot, robot.stowed, alpha=0.15)  # the base, for scale
    for com in first:
        draw_arm_3d(ax_a, robot, ws.nearest_valid_posture(com), color="0.5", lw=0.8)
    if len(first):
        ax_a.scatter(*first.T, color="C0", s=12, label="sampled arm CoMs")
        ax_a.scatter(*first.mean(axis=0), color="C3", marker="*", s=80, label="mean")
        ax_a.legend(fontsize=7)
    ax_a.set_title("(a) first population (body frame)" if len(first) else "(a) exhaustive: no CMA")
    draw_robot(ax_b, robot, realised.q, support=True)
    set_equal_aspect(ax_b, mesh_points(robot_meshes(robot, realised.q)))
    ax_b.scatter(*target.target_com, color="C3", marker="*", s=80, label="optimal arm CoM")
    ax_b.set_title(f"(b) converged, mu = {target.mu:.0f} N rad")
    ax_b.legend(fontsize=7)
    for ax in (ax_a, ax_b):
        ax.set(xlabel="x_B [m]", ylabel="y_B [m]", zlabel="z_B [m]")
    for run in target.runs:
        start = ", ".join(f"{x:.2f}" for x in run.start_com)
        ax_c.plot(run.history, label=f"start [{start}] m, population {run.popsize}")
    ax_c.set(xlabel="CMA-ES iteration", ylabel="best fitness (Eq. 6)", title="(c) fitness")
    ax_c.legend(fontsize=8)
    ax_c.grid(alpha=0.3)
    write_figure(d / "fig7.png", fig)
    summary = {
        "pose": pose,
        "roll_pitch_rad": roll_pitch(problem.terrain, pose),
        "target_com": target.target_com,
        "mu_planned": target.mu,
        "fitness": target.fitness,
        "method": settings.method,
        "seeding": settings.seeding,
        "best_run": target.best_start,
        "runs": [
            {
                "start_com": r.start_com,
                "best_com": r.best_com,
                "best_fitness": r.best_fitness,
                "evaluations": r.evaluations,
                "resamples": r.resamples,
                "iterations": r.iterations,
                "popsize": r.popsize,
                "sigma0_m": r.sigma0,
                "history": r.history,
            }
            for r in target.runs
        ],
        "posture": realised.q,
        "realised_com_error_m": realised.com_error,
        "collision_free": realised.collision_free,
        "seconds": target.seconds,
    }
    summary["stability"] = plan_verdict([summary], every.verdicts.margin)
    save_settings(d, problem)
    write_json(d / "summary.json", summary)
    return summary


def plan_summary(problem: Problem, plan: Plan) -> dict[str, Any]:
    """Per-pose numbers of a plan (``results/fig8/summary.json``)."""
    robot = problem.robot
    mu = stability_along(problem, plan.poses, robot.arm_com(plan.postures))
    mu_realised, mu_stowed, mu_removed = mu.reconfigured, mu.stowed, mu.arm_removed
    if robot.tool_wrench is not None:  # payload.wrench: at the postures' tool points
        gravity = problem.terrain.gravity_body(plan.poses)
        mu_realised = robot_mu(robot, gravity, np.asarray(plan.postures))
    poses = []
    for k, t in enumerate(plan.targets):
        poses.append(
            {
                "pose": t.pose,
                "fraction": plan.fractions[k],
                "target_com": t.target_com,
                "posture": plan.postures[k],
                "realised_com_error_m": plan.realised_com_error[k],
                "collision_free": bool(plan.collision_free[k]),
                "mu_planned": t.mu,
                "mu_realised": mu_realised[k],
                "mu_stowed": mu_stowed[k],
                "mu_arm_removed": mu_removed[k],
                "fallback": bool(t.fallback),
                "side": _side(t.target_com),
                "front": bool(t.target_com[0] > 0),
                "fitness": t.fitness,
                "start_com": t.runs[t.best_start].start_com if t.runs else None,
                "evaluations": sum(r.evaluations for r in t.runs)
                + (t.exhaustive.evaluations if t.exhaustive is not None else 0),
                "resamples": sum(r.resamples for r in t.runs),
                "seconds": t.seconds,
            }
        )
    return {
        "mu_max": mu_max(robot),
        "settings": plan.settings._asdict(),
        "poses": poses,
        "sides": [p["side"] for p in poses],
    }


def run_fig8(problem: Problem, out: str | Path | None = None) -> dict[str, Any]:
    """Paper Fig. 8: the planned configurations along the circle, drawn on the ramp."""
    ws = workspace(problem)
    _ = problem.circle  # Fig. 8 is a circle's figure: a route problem is refused here
    plan = plan_of(problem, ws=ws, progress=True)
    if not isinstance(plan, Plan):
        raise MmstabError(f"{problem.path}: path: Fig. 8 needs a circle")
    d = output_dir(out, "fig8")
    summary = plan_summary(problem, plan)
    settings = Settings.from_problem(problem)
    lap_time = settings.controller.lap_time  # a circle: one lap
    arm_path = arm_path_check(problem.robot, plan, lap_time, settings.controller.dt)
    lap = problem.circle
    along = lap_along(problem.robot, problem.terrain, lap, lap_stage(plan, lap))
    v = lap_verdicts(
        problem.robot,
        problem.terrain,
        lap,
        plan,
        summary["poses"],
        settings.verdicts,
        lap_time,
        arm_path,
        along,
    )  # the verdicts mmstab.plan returns
    for key in ("stability", "slip", "climb", "high_centred", "along_path", "verdicts"):
        summary[key] = v[key]
    if arm_path is not None:
        summary["arm_path"] = v["arm_path"]
    quality = lap_quality(problem, planning_region(ws, settings.workspace.method), plan)
    for k, p in enumerate(summary["poses"]):
        for key, values in quality["per_pose"].items():
            if key != "fraction" and values is not None:
                p[key] = values[k]
    summary["lap_quality"] = {k: v for k, v in quality.items() if k != "per_pose"}
    draw_lap_quality(
        quality,
        d / "fig8_mu.png",
        f"planned vs best-achievable mu along the lap ({plan.settings.method}, "
        f"{plan.settings.seeding if plan.settings.method == 'cmaes' else 'all samples'})",
        (along.s / lap.length, along.mu),
        {k: {**x, "where": [[a / lap.length, b / lap.length] for a, b in x["where"]]}
         for k, x in v["verdicts"].items()},
    )  # fmt: skip
    fig = new_figure(figsize=(11, 5))[0]
    fig.clf()
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    colors = ["tab:red" if p["side"] == "right" else "tab:blue" for p in summary["poses"]]
    draw_poses_on_ground(
        ax,
        problem.robot,
        problem.terrain,
        plan.poses,
        np.nan_to_num(plan.postures),
        arm_colors=colors,
        labels=[str(k) for k in range(len(plan.poses))],
        path_S=problem.circle.pose_at(np.linspace(0, 1, 200))[:, :2],
    )
    ax.set(
        xlabel="x_G [m]",
        ylabel="y_G [m]",
        zlabel="z_G [m]",
        title=f"(a) planned arm configurations, {problem.terrain.label}",
    )
    ax2 = fig.add_subplot(1, 2, 2)
    draw_circle(ax2, problem.circle)
    for k, p in enumerate(summary["poses"]):
        x, y, h = p["pose"]
        c, s = np.cos(h), np.sin(h)
        g = p["target_com"]
        ax2.plot(
            [x, x + c * g[0] - s * g[1]],
            [y, y + s * g[0] + c * g[1]],
            color="C3" if p["side"] == "right" else "C0",
        )
        ax2.annotate(f"{k}", (x, y), fontsize=8)
    ax2.set(
        aspect="equal",
        xlabel="$x_S$ [m]",
        ylabel="$y_S$ [m] (uphill)",
        title="(b) base poses and arm CoM offsets (red right, blue left)",
    )
    write_figure(d / "fig8.png", fig)
    write_npz(
        d / "plan.npz",
        poses=plan.poses,
        fractions=plan.fractions,
        target_com=plan.target_com,
        postures=plan.postures,
    )
    save_settings(d, problem)
    write_json(d / "summary.json", summary)
    return summary
