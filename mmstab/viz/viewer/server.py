"""The interactive viewer: a viser server showing a problem (and a stored run) in the browser.

Scene tree (names in :data:`NODES`): the terrain mesh and grid, the base route (reference
and travelled), the planned arm-CoM targets, the robot (``/robot`` posed by ``G_T_B``; its
base bodies in B, arm links posed by ``B_T_R[i]``) and, at the current instant, the support
polygon coloured by μ, the overall CoM, its projection along gravity and the closest
tip-over axis. The GUI has a timeline (slider, play/pause, speed) over the run, the arm mode
(planned / stowed / arm removed) and a single-pose editor (x, y, yaw, joints) with μ live.
The scene's nodes are added by :mod:`~mmstab.viz.viewer.static` and
:mod:`~mmstab.viz.viewer.robot_view`, the GUI by :mod:`~mmstab.viz.viewer.controls`; the
:class:`Viewer` here connects them and plays the run.
"""

from __future__ import annotations

import contextlib
import io
import threading
import time
from typing import Any

import numpy as np

from mmstab.runs.store import Run
from mmstab.stability.static import mu_max
from mmstab.viz.viewer.controls import SPEEDS, add_controls
from mmstab.viz.viewer.ground import problem_ground
from mmstab.viz.viewer.robot_view import (
    BASE_OPACITY,
    SUPPORT_LIFT,
    add_robot_view,
    draw_instant,
    set_see_through,
)
from mmstab.viz.viewer.scene import ARM_MODES, Instant, arm_posture, instant, mu_color, route_points
from mmstab.viz.viewer.static import _wrap, _wrap_pose, add_static_scene

__all__ = ["BASE_OPACITY", "FRAME_S", "NODES", "RUN_NODES", "SPEEDS", "SUPPORT_LIFT", "Viewer"]

#: Scene nodes the viewer always adds (the run adds ``/route/travelled`` and ``/plan/...``).
NODES = (
    "/terrain",
    "/terrain/grid",
    "/route/reference",
    "/robot",
    "/robot/body",
    "/robot/track_left",
    "/robot/track_right",
    "/robot/flipper_left",
    "/robot/flipper_right",
    "/robot/arm_link_0",
    "/robot/arm_link_1",
    "/robot/arm_link_2",
    "/robot/arm_link_3",
    "/stability/support_polygon",
    "/stability/com",
    "/stability/com_projection",
    "/stability/gravity_line",
    "/stability/tip_axis",
)
#: Nodes added with a run.
RUN_NODES = ("/route/travelled", "/plan/arm_com_targets")
#: Playback frame period [s].
FRAME_S = 0.05


class Viewer:
    """A running viewer of one problem, and optionally one stored run of it.

    Args:
        problem: the problem (robot, terrain, path).
        run: a run of that problem (:func:`mmstab.runs.store.load_run`), or ``None``.
        host: interface to listen on (``127.0.0.1``: this machine only; ``0.0.0.0``: all).
        port: TCP port (0: any free port; a busy port makes viser try the next one).
    """

    def __init__(self, problem: Any, run: Run | None, host: str = "127.0.0.1", port: int = 8080):
        import viser

        self.problem = problem
        self.robot = problem.robot
        self.ground = problem_ground(problem)
        self.run = run
        self.mu_scale = mu_max(self.robot)
        self.mode = "planned"
        self.index = 0
        self.editing = run is None
        self._lock = threading.RLock()
        self._quiet = False  # set while sliders are moved by the program, not the user
        self._stop = threading.Event()
        self._playing = threading.Event()
        with contextlib.redirect_stdout(io.StringIO()):  # viser's banner: the CLI prints the URL
            self.server = viser.ViserServer(host=host, port=port, verbose=False)
        self.server.gui.set_panel_label("mmstab")
        self._build_scene()
        self._build_gui()
        self.current: Instant = self._compute()
        self._draw(self.current)
        self._player = threading.Thread(
            target=self._play_loop, name="mmstab-view-play", daemon=True
        )
        self._player.start()

    # ---------------------------------------------------------------------------- lifecycle
    @property
    def host(self) -> str:
        """The interface the server listens on."""
        return self.server.get_host()

    @property
    def port(self) -> int:
        """The TCP port the server listens on."""
        return self.server.get_port()

    @property
    def url(self) -> str:
        """The address to open in a browser (``localhost`` for a server on all interfaces)."""
        host = self.host
        shown = "localhost" if host in ("0.0.0.0", "::", "") else host
        shown = f"[{shown}]" if ":" in shown else shown
        return f"http://{shown}:{self.port}/"

    def stop(self) -> None:
        """Stop playback and the server."""
        self._stop.set()
        self._playing.clear()
        self._player.join(timeout=2.0)
        with contextlib.redirect_stdout(io.StringIO()):
            self.server.stop()

    # ----------------------------------------------------------------- the scene and GUI
    def _build_scene(self) -> None:
        problem, ground = self.problem, self.ground
        self.extent, reference = add_static_scene(self.server, problem, ground, self.run)
        self._view = add_robot_view(self.server, self.robot)
        centre = route_points(ground, reference).mean(axis=0)
        self.server.initial_camera.look_at = tuple(centre)
        span = max(self.extent.x_max - self.extent.x_min, self.extent.y_max - self.extent.y_min)
        self.server.initial_camera.position = tuple(centre + np.array([0.35, -0.5, 0.38]) * span)

    def _build_gui(self) -> None:
        c = add_controls(self.server, self.problem, self.run, self.extent, self.mode, self.editing)
        self._readout, self._mode, self._see_through = c.readout, c.mode, c.see_through
        self._time, self._play, self._speed = c.time, c.play, c.speed
        self._edit = c.edit
        self._pose_sliders, self._joint_sliders = c.pose_sliders, c.joint_sliders
        self._mode.on_update(lambda _: self._set_mode(self._mode.value))
        self._see_through.on_update(lambda _: self._set_see_through(self._see_through.value))
        if self._time is not None:
            self._time.on_update(lambda _: self._on_time())
            self._play.on_click(lambda _: self._toggle_clicked())
        self._edit.on_update(lambda _: self._set_editing(self._edit.value))
        for slider in self._pose_sliders + self._joint_sliders:
            slider.on_update(lambda _: self._on_pose())

    # ------------------------------------------------------------------------------- state
    def _compute(self) -> Instant:
        """The instant shown: the run sample, or the edited pose."""
        if self.editing or self.run is None:
            pose = np.array([s.value for s in self._pose_sliders], dtype=float)
            q = np.array([s.value for s in self._joint_sliders], dtype=float)
        else:
            pose, q = self.run.poses[self.index], self.run.q[self.index]
        return instant(self.robot, self.ground, pose, arm_posture(self.robot, self.mode, q))

    def shown_mu(self) -> float:
        """μ shown [N rad]: the run's stored value at the sample, else computed live."""
        if self.run is not None and not self.editing:
            return float(self.run.mu[self.mode][self.index])
        return self.current.mu

    def refresh(self) -> Instant:
        """Recompute the current instant and send it to the browsers."""
        with self._lock:
            self.current = self._compute()
            self._draw(self.current)
            return self.current

    def _draw(self, now: Instant) -> None:
        mu = self.shown_mu()
        draw_instant(self.server, self._view, now, mu_color(mu, self.mu_scale))
        self._readout.content = self._readout_text(now, mu)

    def _readout_text(self, now: Instant, mu: float) -> str:
        if self.run is not None and not self.editing:
            where = f"t = {self.run.t[self.index]:.2f} s of {self.run.t[-1]:.2f} s (stored run)"
        else:
            where = "single pose (μ computed live)"
        x, y, yaw = now.pose
        return (
            f"**μ = {mu:.1f} N rad** ({100 * mu / self.mu_scale:.0f} % of μ_max "
            f"{self.mu_scale:.0f}, flat ground, arm stowed)  \n"
            f"arm: {self.mode}; {where}  \n"
            f"pose x {x:.2f} m, y {y:.2f} m, yaw {np.degrees(_wrap(yaw)):.0f} deg; "
            f"closest tip-over axis: {now.axis}"
        )

    # ---------------------------------------------------------------------------- controls
    def show_sample(self, index: int) -> Instant:
        """Show run sample ``index`` (leaves the pose editor)."""
        if self.run is None:
            raise ValueError("no run loaded")
        self.index = int(np.clip(index, 0, self.run.samples - 1))
        if self._time is not None:
            self._quiet = True
            try:
                self._time.value = float(self.run.t[self.index])
            finally:
                self._quiet = False
        if self.editing:
            self.editing = False
            self._quiet = True
            try:
                self._edit.value = False
            finally:
                self._quiet = False
        return self.refresh()

    def show_pose(self, pose: Any, q: Any) -> Instant:
        """Show one base pose (x [m], y [m], yaw [rad]) and arm posture (4,) [rad], μ live."""
        self._quiet = True
        try:
            for slider, value in zip(self._pose_sliders, pose, strict=True):
                slider.value = float(np.clip(value, slider.min, slider.max))
            for slider, value in zip(self._joint_sliders, q, strict=True):
                slider.value = float(np.clip(value, slider.min, slider.max))
            self.editing = True
            self._edit.value = True
        finally:
            self._quiet = False
        return self.refresh()

    def _set_mode(self, mode: str) -> None:
        self.mode = mode
        self.refresh()

    def _set_see_through(self, see_through: bool) -> None:
        set_see_through(self._view, see_through)

    def set_mode(self, mode: str) -> Instant:
        """Show the arm as ``planned``, ``stowed`` or ``arm removed``."""
        if mode not in ARM_MODES:
            raise ValueError(f"arm mode must be one of {ARM_MODES}, got {mode!r}")
        self._mode.value = mode  # calls _set_mode
        return self.current

    def _set_editing(self, editing: bool) -> None:
        if self._quiet or editing == self.editing:
            return
        if editing and self.run is not None:  # start from the instant shown
            self.pause()
            self.show_pose(_wrap_pose(self.run.poses[self.index]), self.run.q[self.index])
            return
        self.editing = editing if self.run is not None else True
        self.refresh()

    def _on_pose(self) -> None:
        if not self._quiet:
            self.pause()
            self.editing = True
            if not self._edit.value:
                self._quiet = True
                self._edit.value = True
                self._quiet = False
            self.refresh()

    def _on_time(self) -> None:
        if self._quiet or self.run is None:
            return
        self.index = int(np.argmin(np.abs(self.run.t - self._time.value)))
        if self.editing:
            self.editing = False
            self._quiet = True
            self._edit.value = False
            self._quiet = False
        self.refresh()

    @property
    def playing(self) -> bool:
        """Whether the run is playing."""
        return self._playing.is_set()

    def _toggle_clicked(self) -> None:
        self.toggle_play()

    def toggle_play(self) -> bool:
        """Start or pause playback of the run; returns whether it now plays."""
        if self.run is None:
            return False
        if self._playing.is_set():
            self.pause()
        else:
            if self.index >= self.run.samples - 1:
                self.index = 0
            if self.editing:
                self.show_sample(self.index)
            self._play.label = "Pause"
            self._playing.set()
        return self._playing.is_set()

    def pause(self) -> None:
        """Pause playback (no-op if paused)."""
        self._playing.clear()
        if self.run is not None:
            self._play.label = "Play"

    def _play_loop(self) -> None:
        while not self._stop.is_set():
            if not self._playing.wait(timeout=0.2) or self.run is None:
                continue
            t = self.run.t
            clock, shown, wall = float(t[self.index]), self.index, time.monotonic()
            while self._playing.is_set() and not self._stop.is_set():
                self._stop.wait(FRAME_S)
                if self.index != shown:  # moved on the slider meanwhile: go on from there
                    clock = float(t[self.index])
                now = time.monotonic()
                clock += float(self._speed.value.rstrip("x")) * (now - wall)
                wall = now
                if clock >= t[-1]:
                    self.show_sample(self.run.samples - 1)
                    self.pause()
                    break
                shown = max(int(np.searchsorted(t, clock, side="right")) - 1, 0)
                if shown != self.index:
                    self.show_sample(shown)
