"""The picture of a ``mmstab simulate`` run (``physics.png``).

Four panels: the path seen from above (the reference and the simulated body origin, where
each event happened), the chassis' tilt off mmstab's predicted resting attitude over time
(the disagreement threshold), μ over time (mmstab's at the simulated pose and MuJoCo's
loaded contacts; the tip threshold μ = 0) and the tracking errors. Events (tipped, slid,
left the map, stalled, disagreement) are vertical lines on the time axes and markers on the
path.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from mmstab.core.files import write_figure
from mmstab.core.problem import Problem
from mmstab.physics.closed_loop import LoopSettings, PhysicsRun

#: event -> (label, colour, marker).
EVENTS = {
    "tipped": ("tipped", "C3", "X"),
    "slid": ("slid", "C1", "v"),
    "left_map": ("left the map", "k", "s"),
    "stalled": ("stalled", "C5", "P"),
    "disagreement": ("tilt off rest > threshold", "C4", "D"),
}


def run_events(run: PhysicsRun) -> dict[str, float]:
    """The run's events and their times [s] (those that happened)."""
    times = {k: getattr(run, k) for k in EVENTS}
    return {k: float(v) for k, v in times.items() if v is not None}


def draw_run(problem: Problem, run: PhysicsRun, loop: LoopSettings) -> Any:
    """The run's figure (module text)."""
    import matplotlib.pyplot as plt

    from mmstab.control.reference import circle_pose

    fig, ((a, b), (c, d)) = plt.subplots(2, 2, figsize=(11, 7.5))
    ref = circle_pose(problem.base_path, np.linspace(0.0, 1.0, 600)).value
    a.plot(ref[:, 0], ref[:, 1], color="0.6", lw=2.5, label="reference (body origin)")
    a.plot(run.state[:, 0], run.state[:, 1], color="C0", lw=1.2, label="MuJoCo: body origin")
    a.plot(*run.state[0, :2], "o", color="C2", label="start")
    events = run_events(run)
    for kind, t_event in events.items():
        label, colour, marker = EVENTS[kind]
        k = min(int(np.searchsorted(run.t, t_event)), len(run.t) - 1)
        a.plot(*run.state[k, :2], marker, color=colour, ms=10, label=f"{label} {t_event:.2f} s")
    a.set(xlabel="x in M [m]", ylabel="y in M [m]", title="path from above")
    a.set_aspect("equal", adjustable="datalim")
    a.legend(fontsize=7)
    ok = np.isfinite(run.tilt_error)
    b.plot(run.t[ok], np.degrees(run.tilt_error[ok]), lw=1, color="C4")
    b.axhline(np.degrees(loop.disagreement_angle), color="C4", ls="--", lw=0.8,
              label="disagreement threshold")  # fmt: skip
    b.set(xlabel="t [s]", ylabel="[deg]", title="chassis tilt off mmstab's predicted rest")
    b.legend(fontsize=7)
    ok = np.isfinite(run.mu_simulated)
    c.plot(run.t, run.mu_predicted, lw=1, label="mmstab at the simulated pose")
    c.plot(run.t[ok], run.mu_simulated[ok], lw=1, label="MuJoCo: loaded contacts")
    c.axhline(0.0, color="k", lw=0.8, label="support lost below")
    c.set(xlabel="t [s]", ylabel="mu [N rad]", title="stability")
    c.legend(fontsize=7)
    d.plot(run.t, run.base_error, lw=1, label="base control point")
    if run.base_origin_error is not None:
        d.plot(run.t, run.base_origin_error, lw=1, label="body origin")
    d.plot(run.t, run.arm_com_error, lw=1, label="arm CoM")
    d.plot(run.t, run.slip, lw=1, label="drift downhill over the slip window (< 0: uphill)")
    d.set(xlabel="t [s]", ylabel="[m]", title="tracking errors")
    d.legend(fontsize=7)
    for ax in (b, c, d):
        for kind, t_event in events.items():
            ax.axvline(t_event, color=EVENTS[kind][1], lw=0.9, ls=":")
    fig.suptitle(
        f"{problem.name} in MuJoCo: "
        + (", ".join(f"{EVENTS[k][0]} at {v:.2f} s" for k, v in events.items()) or "no event"),
        fontsize=10,
    )
    fig.tight_layout()
    return fig


def write_run_figure(path: Path, problem: Problem, run: PhysicsRun, loop: LoopSettings) -> None:
    """Draw the run (:func:`draw_run`) to ``path`` (PNG)."""
    write_figure(path, draw_run(problem, run, loop))


def write_run_gif(path: Path, problem: Problem, run: PhysicsRun, progress: bool = False) -> Any:
    """A replay of the run (``physics.gif``): MuJoCo's body attitude at every check.

    The robot is drawn where MuJoCo had it (``run.body_G_T_B``, not mmstab's resting pose),
    coloured by the μ of MuJoCo's loaded contacts; frame count, rate and size come from the
    problem's ``animation`` section. Returns :class:`mmstab.viz.animation.AnimationInfo`.
    """
    from mmstab.stability.static import mu_max
    from mmstab.viz.animation import render_animation

    if run.body_G_T_B is None:
        raise ValueError("write_run_gif: the run has no recorded body poses")
    frames = run.body_G_T_B
    at = np.flatnonzero(np.isfinite(frames[:, 0, 0]))
    n = problem.robot.arm_joints
    cfg = problem.section("animation")
    return render_animation(
        problem.robot,
        problem.terrain,
        run.t[at],
        run.state[at, :3],
        run.state[at, -n:],
        run.mu_simulated[at],
        path,
        fps=cfg["fps"],
        size=(cfg["width"], cfg["height"]),
        max_frames=cfg["frames"],
        mu_scale=mu_max(problem.robot),
        progress=progress,
        body_poses=frames[at],
    )
