"""The tracking run as an animated GIF (issue 7): the robot driving the circle on the ramp."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from mmstab.animation import render_animation
from mmstab.app import track
from mmstab.config import write_json
from mmstab.experiments.common import output_dir
from mmstab.problem import Problem
from mmstab.stability import mu_max


def run_animation(
    problem: Problem, out: str | Path | None = None, progress: bool = True
) -> dict[str, Any]:
    """Plan, track one lap (as ``mmstab track``) and render ``results/tracking/animation.gif``.

    The frame count, rate and size come from the problem's ``animation`` section; the
    margin colour scale is mu_max (flat ground, arm stowed), so green means "as stable as
    parked on the flat".

    Args:
        problem: the problem.
        out: output folder (default ``results/tracking``).
        progress: show progress bars.

    Returns:
        What was rendered (also written to ``animation.json``).
    """
    cfg = problem.section("animation")
    run = track(problem, progress=progress).run
    d = output_dir(out, "tracking")
    info = render_animation(
        problem.robot,
        problem.terrain,
        run.t,
        run.state[:, :3],
        run.state[:, 5:9],
        run.mu.reconfigured,
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
        "mu_min": float(np.min(run.mu.reconfigured)),
    }
    write_json(d / "animation.json", summary)
    return summary
