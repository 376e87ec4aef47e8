"""The viewer's GUI panel: readout, arm mode, timeline (slider, play, speed), pose editor.

:func:`add_controls` adds the widgets and returns their handles (:class:`Controls`); the
viewer (:mod:`mmstab.viz.viewer.server`) connects them to what they do. Needs ``viser``
(through the server handed in).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from mmstab.runs.store import Run
from mmstab.viz.viewer.ground import Extent
from mmstab.viz.viewer.scene import ARM_MODES
from mmstab.viz.viewer.static import _wrap

#: Playback speeds offered (run seconds per wall-clock second).
SPEEDS = ("0.25x", "0.5x", "1x", "2x", "5x")


@dataclass
class Controls:
    """The GUI's handles (typed loosely: viser's setters confuse mypy).

    Attributes:
        readout: the markdown readout (μ, pose, instant).
        mode: the arm mode dropdown (:data:`~mmstab.viz.viewer.scene.ARM_MODES`).
        see_through: the see-through-base checkbox.
        time: the run's time slider [s] (None without a run).
        play: the play/pause button (None without a run).
        speed: the playback speed dropdown (None without a run).
        edit: the "move a single pose" checkbox.
        pose_sliders: x [m], y [m], yaw [rad].
        joint_sliders: one per arm joint [rad].
    """

    readout: Any
    mode: Any
    see_through: Any
    time: Any
    play: Any
    speed: Any
    edit: Any
    pose_sliders: list[Any]
    joint_sliders: list[Any]


def add_controls(
    server: Any, problem: Any, run: Run | None, extent: Extent, mode: str, editing: bool
) -> Controls:
    """Add the GUI of a viewer of ``problem`` (and ``run``) to ``server``, not yet connected.

    Args:
        server: the ``viser.ViserServer``.
        problem: the problem (its robot's joints, its path's start pose).
        run: the stored run shown, or None (no timeline).
        extent: the terrain's extent (the pose sliders' ranges) [m].
        mode: the initial arm mode.
        editing: the pose editor is on at first.
    """
    gui: Any = server.gui
    robot = problem.robot
    readout = gui.add_markdown("")
    mode_menu = gui.add_dropdown("arm", ARM_MODES, initial_value=mode)
    see_through = gui.add_checkbox("see-through base", initial_value=True)
    time_slider = play = speed = None
    if run is not None:
        with gui.add_folder("Run"):
            step = float(np.median(np.diff(run.t))) if run.samples > 1 else 1.0
            time_slider = gui.add_slider("time [s]", 0.0, float(run.t[-1]), max(step, 1e-6), 0.0)
            play = gui.add_button("Play")
            speed = gui.add_dropdown("speed", SPEEDS, initial_value="1x")
    with gui.add_folder("Pose", expand_by_default=run is None):
        edit = gui.add_checkbox("move a single pose", initial_value=editing)
        e = extent
        pose0 = problem.base_path.pose_at([0.0])[0]
        pose_sliders = [
            gui.add_slider("x [m]", e.x_min, e.x_max, 0.01, round(float(pose0[0]), 2)),
            gui.add_slider("y [m]", e.y_min, e.y_max, 0.01, round(float(pose0[1]), 2)),
            gui.add_slider("yaw [rad]", -np.pi, np.pi, 0.01, round(_wrap(pose0[2]), 2)),
        ]
        joint_sliders = [
            gui.add_slider(
                f"{link.name} [rad]",
                float(link.lower),
                float(link.upper),
                0.01,
                float(np.clip(robot.stowed[i], link.lower, link.upper)),
            )
            for i, link in enumerate(robot.links)
        ]
    return Controls(
        readout,
        mode_menu,
        see_through,
        time_slider,
        play,
        speed,
        edit,
        pose_sliders,
        joint_sliders,
    )
