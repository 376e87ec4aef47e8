"""How good a plan is: against the exhaustive reference and the best achievable stability.

Along the lap of a plan (``results/fig8/``): per planned pose the exhaustive Eq. 6 optimum
over V's samples at the same previous CoM (the planner's fitness gap; within the pose's
turret window when the plan has one; for ``method: sequence``, whose previous CoM is its own
choice, the gap is the price of its joint-space constraints), and on a dense set of
poses the best force-angle measure mu over V's samples, over those whose arm keeps
``planner.ground_clearance`` above the plane the tracks rest on (what the ground check
costs; V's best posture is in the ground at most poses of the ramp lap), over every
collision-free grid CoM (inside V or not: what V's hull difference costs) and with the arm
stowed.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from mmstab.core.files import write_figure
from mmstab.core.problem import Problem
from mmstab.planner import (
    Plan,
    PlanningRegion,
    best_mu,
    gravity_body_at,
    pose_fitness,
    region_samples,
    solve_exhaustive,
)
from mmstab.planner.regions import as_region
from mmstab.planner.searches.sequence import above_ground
from mmstab.stability.static import mu_max, robot_force_angle
from mmstab.viz.plotting import new_figure

#: Poses of the dense lap curve.
DENSE_POSES = 72


def _pct(reference: np.ndarray, value: np.ndarray) -> np.ndarray:
    return 100.0 * (reference - value) / np.abs(reference)


def lap_quality(
    problem: Problem, region: PlanningRegion, plan: Plan, dense: int = DENSE_POSES
) -> dict[str, Any]:
    """Planned vs exhaustive vs best achievable along the problem's lap.

    Args:
        problem: the problem (robot, terrain, circle).
        region: the workspace the plan used (its samples: ``valid_com_in_V``; all
            collision-free grid CoMs: ``valid_com``).
        plan: the plan.
        dense: poses of the dense curve over one lap.

    Returns:
        ``per_pose`` lists (fitness and mu of plan and reference, gap [%], best mu in V,
        in V above the ground (``mu_best_above_ground``: ``planner.ground_clearance``; None
        when not checked) and over all valid CoMs [N rad]), the ``dense`` curves and
        summary statistics.
    """
    robot = problem.robot
    samples, valid = region_samples(region), np.asarray(region.valid_com)
    g = gravity_body_at(problem.terrain, plan.poses)
    norm = mu_max(robot)
    previous = np.vstack([robot.arm_com(robot.stowed)[None], plan.target_com[:-1]])
    fit_ref, mu_ref, seconds = [], [], []
    for k, target in enumerate(plan.targets):
        fitness = pose_fitness(robot, g[k], previous[k], plan.settings, norm, region.diameter)
        # against the exhaustive optimum under the pose's own turret window (if any)
        window = target.window
        ex = solve_exhaustive(
            fitness, samples if window is None else region.windowed(window).samples
        )
        fit_ref.append(ex.best_fitness)
        mu_ref.append(float(fitness.mu(ex.best_com)[0]))
        seconds.append(ex.seconds)
    fit_plan = np.array([t.fitness for t in plan.targets])
    mu_plan = np.array([t.mu for t in plan.targets])
    best_V = np.array([best_mu(robot, gk, samples)[0] for gk in g])
    best_valid = np.array([best_mu(robot, gk, valid)[0] for gk in g])
    fractions = np.arange(dense) / dense
    poses = problem.circle.pose_at(fractions)
    gd = gravity_body_at(problem.terrain, poses)
    dense_V = np.array([best_mu(robot, gk, samples)[0] for gk in gd])
    ground = plan.settings.ground_clearance
    best_up = dense_up = None
    if ground is not None:
        up = samples[above_ground(robot, as_region(region), ground)]
        best_up = np.array([best_mu(robot, gk, up)[0] for gk in g])
        dense_up = np.array([best_mu(robot, gk, up)[0] for gk in gd])
    dense_valid = np.array([best_mu(robot, gk, valid)[0] for gk in gd])
    stowed = np.broadcast_to(robot.arm_com(robot.stowed), (dense, 3))
    dense_stowed = robot_force_angle(robot, gd, stowed).mu
    gap = _pct(np.array(fit_ref), fit_plan)
    v_loss = _pct(dense_valid, dense_V)
    return {
        "per_pose": {
            "fraction": plan.fractions,
            "fitness_planned": fit_plan,
            "fitness_exhaustive": np.array(fit_ref),
            "fitness_gap_pct": gap,
            "mu_planned": mu_plan,
            "mu_exhaustive": np.array(mu_ref),
            "mu_best_in_V": best_V,
            "mu_best_above_ground": best_up,
            "mu_best_valid": best_valid,
            "exhaustive_seconds": np.array(seconds),
        },
        "dense": {
            "fraction": fractions,
            "mu_best_in_V": dense_V,
            "mu_best_above_ground": dense_up,
            "mu_best_valid": dense_valid,
            "mu_stowed": dense_stowed,
        },
        "fitness_gap_pct": {"median": float(np.median(gap)), "max": float(np.max(gap))},
        "v_loss_pct": {"median": float(np.median(v_loss)), "max": float(np.max(v_loss))},
        "samples_in_V": len(samples),
        "valid_samples": len(valid),
    }


def draw_lap_quality(
    quality: dict[str, Any],
    path: str | Path,
    title: str,
    along: tuple[Any, Any] | None = None,
    verdicts: dict[str, dict[str, Any]] | None = None,
) -> Path:
    """The figure: planned and reference mu at the plan's poses over the dense curves.

    Args:
        quality: :func:`lap_quality`'s report.
        path: the PNG to write.
        title: the figure's title.
        along: (lap fractions, μ [N rad]) every few cm with the planned arm (the worse of
            the postures the arm moves between, :func:`mmstab.runs.plan_verdicts.lap_along`).
        verdicts: the plan's verdicts, their ``where`` in lap fractions: marked over the plot.
    """
    from mmstab.outputs.routes import mark_verdicts

    fig, ax = new_figure(figsize=(8, 4.2))
    d, p = quality["dense"], quality["per_pose"]
    if along is not None:
        ax.plot(*along, "-", lw=0.8, color="C3", alpha=0.5, label="planned arm, every few cm")
    ax.plot(d["fraction"], d["mu_best_valid"], "k--", lw=1, label="best, all collision-free CoMs")
    ax.plot(d["fraction"], d["mu_best_in_V"], "C0-", label="best in V (grid samples)")
    if d.get("mu_best_above_ground") is not None:
        ax.plot(
            d["fraction"], d["mu_best_above_ground"], "C0-.", label="best in V, arm above ground"
        )
    ax.plot(d["fraction"], d["mu_stowed"], "C2:", label="arm stowed")
    ax.plot(
        p["fraction"],
        p["mu_exhaustive"],
        "s",
        mfc="none",
        color="C1",
        label="Eq. 6 optimum in V (exhaustive)",
    )
    ax.plot(p["fraction"], p["mu_planned"], "x", color="C3", ms=8, label="planned (Eq. 6)")
    if verdicts is not None:
        mark_verdicts(ax, verdicts)
    ax.set(xlabel="path fraction", ylabel="mu [N rad]", title=title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return write_figure(Path(path), fig)
