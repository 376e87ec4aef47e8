"""The tracking run as an animated GIF: the robot driving the circle on the ramp.

It renders the stored run of ``mmstab track`` (``results/tracking/run.npz``), so
``make demo`` simulates the lap once; only when no run of this problem is stored does it
run the tracking experiment first.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from mmstab.app.settings import Settings
from mmstab.core.files import MmstabError, write_json
from mmstab.core.problem import Problem
from mmstab.outputs.common import output_dir
from mmstab.outputs.tracking import run_tracking
from mmstab.runs.store import Run, load_run
from mmstab.stability.static import mu_max
from mmstab.viz.animation import render_animation


def stored_or_new_run(
    problem: Problem, directory: Path, progress: bool, allow_unstable: bool = True
) -> Run:
    """The stored run of ``problem`` in ``directory``; tracked and stored first if there is none.

    Args:
        problem: the problem.
        directory: the run's folder (``results/tracking``).
        progress: show progress bars when tracking.
        allow_unstable: track even when the plan made here is unstable (``run_tracking``).
    """
    try:
        return load_run(directory, problem)
    except MmstabError as exc:
        print(f"animation: no stored run to render ({exc}); tracking first", file=sys.stderr)
    run_tracking(problem, directory, progress=progress, allow_unstable=allow_unstable)
    return load_run(directory, problem)


def track_summary(run: Run) -> dict[str, Any] | None:
    """The ``summary.json`` ``mmstab track`` wrote beside the stored run, or None (none)."""
    summary = run.directory / "summary.json"
    return json.loads(summary.read_text()) if summary.is_file() else None


def stored_verdicts(summary: dict[str, Any] | None) -> dict[str, Any]:
    """The stored run's slide and arm-contact records (``slip``, the arm's ``arm_*``).

    ``arm_self_collision`` and ``arm_in_ground``: those of ``mmstab track``'s summary
    (:func:`track_summary`), with its ``steps`` (the samples the slide record counts); none
    for a run stored without its summary.
    """
    if summary is None:
        return {}
    keys = ("steps", "slip", "arm_self_collision", "arm_in_ground")
    return {k: summary[k] for k in keys if summary.get(k) is not None}


def tipping_of(run: Run, dt: float, summary: dict[str, Any] | None = None) -> dict[str, Any] | None:
    """The ``tipped`` record of a stored run, or None: its ``summary.json``'s.

    The run's verdict is the tip rule's (:mod:`mmstab.runs.tip_rule`: μ < 0 held where no
    rock catches it), which the stored μ alone does not show. A run stored without its
    summary: its last sample, where a run that tips stops, if μ < 0 there.

    Args:
        run: the stored run.
        dt: its control period [s] (the problem's ``controller.dt``).
        summary: its :func:`track_summary`, if already read.
    """
    summary = track_summary(run) if summary is None else summary
    if summary is not None:
        record = summary.get("tipped")
        return None if record is None else dict(record)
    mu = run.mu["planned"]
    if not mu[-1] < 0:
        return None
    t = float(run.t[-1])
    return {"step": int(round(t / dt)), "time_s": t, "pose": run.poses[-1], "mu": float(mu[-1])}


def run_animation(
    problem: Problem,
    out: str | Path | None = None,
    progress: bool = True,
    allow_unstable: bool = True,
) -> dict[str, Any]:
    """Render ``results/tracking/animation.gif`` from the stored tracking run.

    The frame count, rate and size come from the problem's ``animation`` section; the
    margin colour scale is mu_max (flat ground, arm stowed), so green means "as stable as
    parked on the flat".

    Args:
        problem: the problem.
        out: the run's folder and output folder (default ``results/tracking``).
        progress: show progress bars.
        allow_unstable: track (when no run is stored) even with an unstable plan; a run
            that tips over is rendered up to that instant (``tipped`` in the summary).

    Returns:
        What was rendered (also written to ``animation.json``), with the run's verdicts as
        ``track`` wrote them (``tipped``, ``slip``, ``arm_self_collision``).
    """
    cfg = problem.section("animation")
    d = output_dir(out, "tracking")
    run = stored_or_new_run(problem, d, progress, allow_unstable)
    track = track_summary(run)  # its verdicts, as `track` wrote them
    info = render_animation(
        problem.robot,
        problem.terrain,
        run.t,
        run.poses,
        run.q,
        run.mu["planned"],
        d / "animation.gif",
        fps=cfg["fps"],
        size=(cfg["width"], cfg["height"]),
        max_frames=cfg["frames"],
        mu_scale=mu_max(problem.robot),
        progress=progress,
    )
    summary = {
        "gif": info.path,
        "frames": info.frames,
        "fps": cfg["fps"],
        "size_px": [cfg["width"], cfg["height"]],
        "simulated_s": float(run.t[-1]),
        "mu_min": float(np.min(run.mu["planned"])),
        "source": str(d / "run.npz"),
        "tipped": tipping_of(run, Settings.from_problem(problem).controller.dt, track),
        **stored_verdicts(track),
    }
    write_json(d / "animation.json", summary)
    return summary
