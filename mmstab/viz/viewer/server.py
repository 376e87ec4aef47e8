"""The interactive viewer: a viser server showing a problem (and a stored run) in the browser.

Scene tree (names in :data:`NODES`): the terrain mesh and grid, the base route (reference
and travelled), the planned arm-CoM targets, the robot (``/robot`` posed by ``G_T_B``; its
base bodies in B, arm links posed by ``B_T_R[i]``) and, at the current instant, the support
polygon coloured by μ, the overall CoM, its projection along gravity and the closest
tip-over axis. The GUI has a timeline (slider, play/pause, speed) over the run, the arm mode
(planned / stowed / arm removed) and a single-pose editor (x, y, yaw, joints) with μ live.
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
from mmstab.viz.viewer.ground import (
    problem_ground,
)
from mmstab.viz.viewer.scene import (
    ARM_MODES,
    Instant,
    arm_posture,
    instant,
    mu_color,
    polygon_fan,
    robot_body_meshes,
    route_points,
)
from mmstab.viz.viewer.static import _wrap, _wrap_pose, add_static_scene, wxyz

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
#: Playback speeds offered (run seconds per wall-clock second).
SPEEDS = ("0.25x", "0.5x", "1x", "2x", "5x")
#: The support polygon and the CoM's projection are drawn this far above the ground [m].
SUPPORT_LIFT = 3e-3
#: Opacity of the base bodies when seen through (the support polygon lies under them).
BASE_OPACITY = 0.45
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

    # ---------------------------------------------------------------------------- the scene
    def _build_scene(self) -> None:
        scene: Any = self.server.scene
        problem, ground = self.problem, self.ground
        self.extent, reference = add_static_scene(self.server, problem, ground, self.run)
        self._robot = scene.add_frame("/robot", show_axes=False)
        self._links: list[Any] = []
        self._base_bodies: list[Any] = []
        for body in robot_body_meshes(self.robot):
            handle = scene.add_mesh_simple(
                f"/robot/{body.name}",
                body.vertices,
                body.faces,
                color=body.rgb,
                flat_shading=body.link is None,
                opacity=BASE_OPACITY if body.link is None else None,
            )
            (self._base_bodies if body.link is None else self._links).append(handle)
        self._support = scene.add_mesh_simple(
            "/stability/support_polygon",
            np.zeros((3, 3)),
            np.array([[0, 1, 2]]),
            color=(0, 160, 0),
            opacity=0.55,
            side="double",
            cast_shadow=False,
        )
        self._com = scene.add_icosphere("/stability/com", radius=0.03, color=(20, 20, 20))
        self._projection = scene.add_icosphere(
            "/stability/com_projection", radius=0.02, color=(120, 60, 160)
        )
        self._gravity = scene.add_line_segments(
            "/stability/gravity_line", np.zeros((1, 2, 3)), (120, 60, 160), thickness=0.006
        )
        self._axis = scene.add_line_segments(
            "/stability/tip_axis", np.zeros((1, 2, 3)), (200, 0, 0), thickness=0.025
        )
        centre = route_points(ground, reference).mean(axis=0)
        self.server.initial_camera.look_at = tuple(centre)
        span = max(self.extent.x_max - self.extent.x_min, self.extent.y_max - self.extent.y_min)
        self.server.initial_camera.position = tuple(centre + np.array([0.35, -0.5, 0.38]) * span)

    # ------------------------------------------------------------------------------ the GUI
    def _build_gui(self) -> None:
        gui: Any = self.server.gui  # handles typed loosely: viser's setters confuse mypy
        robot = self.robot
        self._readout = gui.add_markdown("")
        self._mode = gui.add_dropdown("arm", ARM_MODES, initial_value=self.mode)
        self._mode.on_update(lambda _: self._set_mode(self._mode.value))
        self._see_through = gui.add_checkbox("see-through base", initial_value=True)
        self._see_through.on_update(lambda _: self._set_see_through(self._see_through.value))
        self._time: Any = None
        if self.run is not None:
            run = self.run
            with gui.add_folder("Run"):
                step = float(np.median(np.diff(run.t))) if run.samples > 1 else 1.0
                self._time = gui.add_slider("time [s]", 0.0, float(run.t[-1]), max(step, 1e-6), 0.0)
                self._play = gui.add_button("Play")
                self._speed = gui.add_dropdown("speed", SPEEDS, initial_value="1x")
            self._time.on_update(lambda _: self._on_time())
            self._play.on_click(lambda _: self._toggle_clicked())
        with gui.add_folder("Pose", expand_by_default=self.run is None):
            self._edit = gui.add_checkbox("move a single pose", initial_value=self.editing)
            e = self.extent
            pose0 = self.problem.base_path.pose_at([0.0])[0]
            self._pose_sliders = [
                gui.add_slider("x [m]", e.x_min, e.x_max, 0.01, round(float(pose0[0]), 2)),
                gui.add_slider("y [m]", e.y_min, e.y_max, 0.01, round(float(pose0[1]), 2)),
                gui.add_slider("yaw [rad]", -np.pi, np.pi, 0.01, round(_wrap(pose0[2]), 2)),
            ]
            self._joint_sliders = [
                gui.add_slider(
                    f"{link.name} [rad]",
                    float(link.lower),
                    float(link.upper),
                    0.01,
                    float(np.clip(robot.stowed[i], link.lower, link.upper)),
                )
                for i, link in enumerate(robot.links)
            ]
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
        rgb = mu_color(mu, self.mu_scale)
        lift = SUPPORT_LIFT * now.G_T_B[:3, 2]  # off the ground along the body's z, to show
        with self.server.atomic():
            self._robot.position = now.G_T_B[:3, 3]
            self._robot.wxyz = wxyz(now.G_T_B[:3, :3])
            for i, handle in enumerate(self._links):
                handle.visible = now.B_T_R is not None
                if now.B_T_R is not None:
                    handle.position = now.B_T_R[i][:3, 3]
                    handle.wxyz = wxyz(now.B_T_R[i][:3, :3])
            self._support.vertices = (now.polygon_G + lift).astype(np.float32)
            self._support.faces = polygon_fan(now.polygon_G)
            self._support.color = rgb
            self._com.position = now.com_G
            self._projection.position = now.com_projection_G + lift
            self._gravity.points = np.array([[now.com_G, now.com_projection_G]], dtype=np.float32)
            self._axis.points = (now.axis_G + 2 * lift)[None].astype(np.float32)
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
        for handle in self._base_bodies:
            handle.opacity = BASE_OPACITY if see_through else None

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
