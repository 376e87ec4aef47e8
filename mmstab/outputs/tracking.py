"""Paper Fig. 9-12: one tracking run around the circle on the ramp, four figures.

Fig. 9: desired and actual paths of the base control point and the arm CoM on the slope.
Fig. 10: tracking errors of both. Fig. 11: joint speeds of the arm and of the two tracks, with
their limits. Fig. 12: stability μ along the run with the arm reconfiguring, removed, stowed.
Writes ``results/tracking/`` (figures, ``summary.json``, ``run.npz``, ``run.mcap`` for
Foxglove/RViz (:mod:`mmstab.runs.recording`), the settings used).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mmstab.app import Backend, track
from mmstab.core.files import write_figure, write_json, write_npz
from mmstab.core.problem import Problem
from mmstab.model.robot import FloatArray
from mmstab.outputs.common import output_dir, route_corners, save_settings
from mmstab.planner import Plan, RoutePlan
from mmstab.runs.plan_verdicts import exit_status
from mmstab.runs.recording import frames_at, write_run
from mmstab.runs.tracking import (
    InitialArm,
    TrackingPlan,
    TrackingRun,
    joint_names,
    state_names,
    summarize,
)
from mmstab.runs.tracking.checks import run_verdicts, saved_samples, tracked_checks
from mmstab.runs.verdict_settings import VerdictSettings
from mmstab.stability.static import mu_max as stowed_flat_mu
from mmstab.viz.plotting import draw_base_topview, new_figure

#: Sample rate of the run's recording (``run.mcap``) [Hz].
BAG_RATE = 10.0


def run_tracking(
    problem: Problem,
    out: str | Path | None = None,
    plugin: str | None = None,
    *,
    backend: Backend = "interpreted",
    duration: float | None = None,
    plan: TrackingPlan | None = None,
    initial_arm: InitialArm = "stowed",
    progress: bool = True,
    allow_unstable: bool = True,
) -> dict[str, Any]:
    """Plan (unless given), track one lap, write Fig. 9-12 and the summary.

    The run stops at the first sample where the robot would tip over (μ < 0); the summary's
    ``tipped`` says when and where (None when it did not).

    Args:
        problem: the problem.
        out: output folder (default ``results/tracking``).
        plugin: QP plugin (default the problem's ``controller.plugin``, or ``codegen.plugin``
            for the generated backend).
        backend: ``interpreted`` (CasADi ``conic``) or ``generated`` (compiled C).
        duration: simulated time [s] (default the problem's ``controller.duration``).
        plan: an arm plan; default :func:`mmstab.app.plan` on the problem.
        initial_arm: ``stowed`` or ``planned`` (see :mod:`mmstab.runs.tracking`).
        progress: show progress bars.
        allow_unstable: go on when the plan made here is unstable (some pose's μ at or
            below ``planner.margin``); else :class:`~mmstab.core.files.UnstableError` before
            tracking.

    Returns:
        The summary written to ``summary.json``.
    """
    problem, plan, run = track(
        problem,
        plan,
        plugin=plugin,
        backend=backend,
        duration=duration,
        initial_arm=initial_arm,
        progress=progress,
        allow_unstable=allow_unstable,
    )
    d = output_dir(out, "tracking")
    keep, collisions, slip, in_ground = run_checks(problem, run)
    _fig9(d, problem, run)
    _fig10(d, run, collisions["intervals_s"])
    _fig11(d, run)
    _fig12(d, problem, run)
    _write_bag(d, problem, run)
    _write_arrays(d, plan, run, keep)
    summary = summarize(run)
    summary["plan_poses"] = int(np.asarray(plan.fractions).size)
    summary["arm_self_collision"] = collisions
    if in_ground is not None:  # a heightmap's: the arm against the ground at the rests
        summary["arm_in_ground"] = in_ground
    summary |= {"slip": slip} | route_corners(problem)
    save_settings(
        d,
        problem,
        tracking={
            "plugin": run.plugin,
            "backend": run.backend,
            "duration": float(run.t[-1]),
            "initial_arm": run.initial_arm,
        },
    )
    write_json(d / "summary.json", summary)
    return summary


def run_checks(
    problem: Problem, run: TrackingRun
) -> tuple[NDArray[np.int_], dict[str, Any], dict[str, Any], dict[str, Any] | None]:
    """The verdicts beside ``run.tipped`` of a problem's run (:func:`tracked_checks`)."""
    return tracked_checks(problem.robot, problem.terrain, _verdict_settings(problem), run)


def _verdict_settings(problem: Problem) -> VerdictSettings:
    """The problem's slide limits (its ``planner:`` and ``physics:`` sections)."""
    return VerdictSettings.from_sections(problem.section("planner"), problem.section("physics"))


def track_verdict(problem: Problem, plan: Plan | RoutePlan | None = None) -> str:
    """``mmstab track``'s verdict on a problem, without its files (one of :data:`TRACK_VERDICTS`).

    As the command decides its exit status: ``tips`` (3: the plan is unstable, or the run
    tips), else ``slides`` (4), else ``arm collision`` (5), else ``accepted`` (0).

    Args:
        problem: the problem.
        plan: its arm plan (:func:`mmstab.app.plan`; made here when None). A given plan is
            checked as the command checks the plan it makes (``plan_stability``).
    """
    from mmstab.app import plan as plan_of
    from mmstab.core.files import UnstableError
    from mmstab.runs.verdict import check_plan, plan_stability

    made = plan_of(problem) if plan is None else plan
    try:
        check_plan(plan_stability(problem, made), len(made.poses), False)
    except UnstableError:
        return "tips"
    problem, _, run = track(problem, made, progress=False)
    verdicts = run_verdicts(problem.robot, problem.terrain, _verdict_settings(problem), run)
    status = exit_status(verdicts)
    return next(k for k, v in TRACK_VERDICTS.items() if v == status)


#: ``mmstab track``'s verdicts, and its exit status for each.
TRACK_VERDICTS = {"accepted": 0, "tips": 3, "slides": 4, "arm collision": 5}


def _write_arrays(d: Path, plan: TrackingPlan, run: TrackingRun, keep: NDArray[np.int_]) -> None:
    """The run's arrays at the kept samples, and the plan's, as ``run.npz``."""
    applied = np.vstack([run.qdot, run.qdot[-1:]])  # q̇ over [t_k, t_k+1), repeated at the end
    write_npz(
        d / "run.npz",
        t=run.t[keep],
        state=run.state[keep],
        state_names=np.array(state_names(run.state.shape[1] - 5)),
        qdot=applied[keep],
        joint_names=np.array(joint_names(run.qdot.shape[1] - 2)),
        xi=run.xi[keep],
        xi_des=run.xi_des[keep],
        q_ref=run.q_ref[keep],
        base_error=run.base_error[keep],
        heading_error=run.heading_error[keep],
        arm_com_error=run.arm_com_error[keep],
        mu_reconfigured=run.mu.reconfigured[keep],
        mu_arm_removed=run.mu.arm_removed[keep],
        mu_stowed=run.mu.stowed[keep],
        failure_times=np.array([f.time for f in run.failures]),
        plan_fractions=np.asarray(plan.fractions),
        plan_target_com=np.asarray(plan.target_com),
        plan_postures=np.asarray(plan.postures),
        posture_knot_fractions=run.posture.fractions,
        posture_knots=run.posture.postures,
    )


def _write_bag(d: Path, problem: Problem, run: TrackingRun) -> None:
    """The run as ``run.mcap`` at ``BAG_RATE`` (:mod:`mmstab.runs.recording`; Foxglove, RViz)."""
    k = saved_samples(run, 1.0 / BAG_RATE)
    frames = frames_at(problem.terrain, problem.robot, run.t[k], run.state[k, :3],
                       run.state[k, 5:], run.mu.reconfigured[k])  # fmt: skip
    write_run(d / "run.mcap", problem.robot, frames, stowed_flat_mu(problem.robot))


# ------------------------------------------------------------------------------------ figures
def _fig9(d: Path, problem: Problem, run: TrackingRun) -> None:
    fig, (ax, ax_z) = new_figure(1, 2, figsize=(11, 4.8), width_ratios=[1.25, 1])
    xi, des = run.xi, run.xi_des
    ax.plot(des[:, 0], des[:, 1], "--", color="0.45", lw=1.2, label="base point, desired")
    ax.plot(xi[:, 0], xi[:, 1], "-", color="C0", lw=1.4, label="base point, actual")
    ax.plot(des[:, 3], des[:, 4], "--", color="C3", lw=1.2, alpha=0.7, label="arm CoM, desired")
    ax.plot(xi[:, 3], xi[:, 4], "-", color="C1", lw=1.2, label="arm CoM, actual")
    ax.plot(xi[0, 3], xi[0, 4], "o", color="C1", ms=5, label="arm CoM at t = 0")
    for k in np.linspace(0, run.t.size - 1, 7)[:-1].astype(int):
        draw_base_topview(ax, problem.robot, run.state[k, :3], color="0.75")
    ax.set(
        aspect="equal",
        xlabel="$x_S$ [m]",
        ylabel="$y_S$ [m] (uphill)",
        title=f"(a) on the {problem.terrain.label}, seen from above",
    )
    ax.legend(fontsize=7, loc="center")
    ax_z.plot(run.t, des[:, 5], "--", color="C3", label="desired")
    ax_z.plot(run.t, xi[:, 5], "-", color="C1", label="actual")
    ax_z.set(xlabel="time [s]", ylabel="arm CoM height above the slope [m]", title="(b) height")
    ax_z.legend(fontsize=8)
    for a in (ax, ax_z):
        a.grid(alpha=0.3)
    fig.suptitle("Fig. 9: desired and actual paths of the base control point and the arm CoM")
    write_figure(d / "fig9.png", fig)


def _mark_failures(ax: Any, run: TrackingRun) -> None:
    for i, f in enumerate(run.failures[:200]):
        ax.axvline(f.time, color="r", lw=0.5, alpha=0.5, label="QP failure" if i == 0 else None)


def _fig10(d: Path, run: TrackingRun, collision_intervals: list[list[float]]) -> None:
    fig, (ax_b, ax_a, ax_q) = new_figure(3, 1, figsize=(8, 8), sharex=True)

    def positive(v: FloatArray) -> FloatArray:  # exact zeros (t = 0) left off the log axis
        return np.where(v > 0, v, np.nan)

    ax_b.semilogy(run.t, positive(run.base_error), color="C0", label="base point [m]")
    ax_b.semilogy(run.t, positive(np.abs(run.heading_error)), color="C2", label="|heading| [rad]")
    ax_a.semilogy(run.t, positive(run.arm_com_error), color="C1", label="arm CoM [m]")
    arm = joint_names(run.posture_error.shape[1])[2:]  # the robot's arm joints
    for j, name in enumerate(arm):
        ax_q.semilogy(
            run.t,
            positive(np.abs(run.posture_error[:, j])),
            color=f"C{j + 2}",
            lw=0.9,
            label=name,
        )
    ax_b.set(ylabel="error", title="(a) base: control point distance and heading")
    ax_a.set(ylabel="error [m]", title="(b) arm CoM distance")
    ax_q.set(
        xlabel="time [s]",
        ylabel="|q_ref − q| [rad]",
        title="(c) arm posture (posture task; the approach from stowed until "
        f"{0.0 if run.approach is None else run.approach.duration:g} s)",
    )
    for i, (a, b) in enumerate(collision_intervals):
        label = "arm intersects the base or itself" if i == 0 else None
        for ax in (ax_a, ax_q):
            ax.axvspan(a, b, color="C3", alpha=0.12, lw=0, label=label)
    for ax in (ax_b, ax_a, ax_q):
        _mark_failures(ax, run)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8, ncol=2 if ax is ax_q else 1)
    fig.suptitle("Fig. 10: tracking errors")
    write_figure(d / "fig10.png", fig)


def _fig11(d: Path, run: TrackingRun) -> None:
    fig, axes = new_figure(2, 2, figsize=(12, 6.5), width_ratios=[1.6, 1])
    t_q = run.t[:-1]  # q̇ holds over [t_k, t_k+1)
    zoom = t_q <= min(1.0, float(t_q[-1]))
    names = joint_names(run.qdot.shape[1] - 2)  # the tracks, then the robot's arm joints
    groups = [(slice(2, len(names)), "(a) arm joints"), (slice(0, 2), "(b) tracks (sprockets)")]
    for row, (cols, title) in enumerate(groups):
        for col, mask in enumerate((np.ones_like(zoom), zoom)):
            ax = axes[row, col]
            for j in range(len(names))[cols]:
                ax.plot(t_q[mask], run.qdot[mask, j], lw=1.0, color=f"C{j}", label=names[j])
            lim = float(np.max(run.qdot_limit[cols]))
            for sign in (1, -1):
                ax.axhline(
                    sign * lim, color="k", ls="--", lw=0.8, label="limit" if sign > 0 else None
                )
            ax.set(ylabel="[rad/s]", title=title + (" (first second)" if col else ""))
            ax.grid(alpha=0.3)
            if col == 0:
                ax.legend(fontsize=7, ncol=3, loc="lower right")
    for ax in axes[1]:
        ax.set_xlabel("time [s]")
    fig.suptitle("Fig. 11: joint speeds and their limits (±4π rad/s)")
    write_figure(d / "fig11.png", fig)


def _fig12(d: Path, problem: Problem, run: TrackingRun) -> None:
    fig, ax = new_figure(figsize=(8, 4.2))
    mu = run.mu
    ax.plot(run.t, mu.reconfigured, color="C0", label="arm reconfiguring (tracked)")
    ax.plot(run.t, mu.stowed, color="C2", ls=":", label="arm held stowed")
    ax.plot(run.t, mu.arm_removed, color="0.4", ls="--", label="arm removed")
    ax.set(
        xlabel="time [s]",
        ylabel="force-angle stability $\\mu$ [N rad]",
        title=f"Fig. 12: stability along the run ({problem.terrain.label})",
    )
    _mark_failures(ax, run)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    write_figure(d / "fig12.png", fig)
