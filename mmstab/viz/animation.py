"""Animated GIF of a run on the ramp: the robot, its support polygon and the stability margin.

A building block for the tracking experiment: hand it the time series the run produced
(base poses in S, arm postures, force-angle margin) and an output path::

    render_animation(robot, terrain, t, base_poses, q_arm, mu, "results/tracking/animation.gif")

Left, the robot (drawn by :mod:`mmstab.viz.drawing` from its collision geometry) on the ramp,
with the base's planned and travelled track and the support polygon filled in the colour
of the current margin (red: tipping, mu <= 0; green: mu at ``mu_scale``). Right, mu over
time with the current instant marked, and a bar of the current mu in the same colour.
Long runs are thinned to ``max_frames`` evenly spaced frames (the last one kept).
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray
from tqdm import tqdm

from mmstab.model.robot import FloatArray, Robot
from mmstab.model.urdf import default_file_mode
from mmstab.terrain import Terrain
from mmstab.viz.drawing import (
    PATH_RANK,
    LayerLines,
    draw_ground,
    draw_path_on_ground,
    draw_robot,
    mesh_points,
    robot_meshes,
    set_equal_aspect,
    transform_points,
)
from mmstab.viz.plotting import plt

#: Colour map of the margin: 0 (tipping) .. mu_scale (as stable as the run gets).
MU_CMAP = "RdYlGn"
#: Resolution of the GIF's figure [dots per inch].
DPI = 80


class AnimationInfo(NamedTuple):
    """What :func:`render_animation` wrote.

    Attributes:
        path: the GIF file.
        frames: number of frames in it.
        indices: the samples of the input time series shown, (frames,).
    """

    path: Path
    frames: int
    indices: NDArray[np.intp]


def frame_indices(n_samples: int, max_frames: int | None) -> NDArray[np.intp]:
    """Evenly spaced sample indices, at most ``max_frames``, first and last included."""
    if max_frames is None or n_samples <= max_frames:
        return np.arange(n_samples, dtype=np.intp)
    picks = np.round(np.linspace(0, n_samples - 1, max(max_frames, 2))).astype(np.intp)
    return np.unique(picks)


def _check_inputs(
    times: FloatArray, poses: FloatArray, q: FloatArray, mu: FloatArray, joints: int
) -> None:
    n = times.shape[0]
    if times.ndim != 1 or n < 1:
        raise ValueError(f"times must be (T,) with T >= 1, got {times.shape}")
    for name, arr, shape in (("base_poses", poses, (n, 3)), ("q_arm", q, (n, joints))):
        if arr.shape != shape:
            raise ValueError(f"{name} must be {shape}, got {arr.shape}")
    if mu.shape != (n,):
        raise ValueError(f"mu must be ({n},), got {mu.shape}")
    if not (np.all(np.isfinite(times)) and np.all(np.isfinite(poses)) and np.all(np.isfinite(q))):
        raise ValueError("times, base_poses and q_arm must be finite")


def render_animation(
    robot: Robot,
    terrain: Terrain,
    times: ArrayLike,
    base_poses: ArrayLike,
    q_arm: ArrayLike,
    mu: ArrayLike,
    out_path: str | os.PathLike[str],
    fps: int = 10,
    size: tuple[int, int] = (560, 320),
    max_frames: int | None = 120,
    mu_scale: float | None = None,
    view: tuple[float, float] = (32.0, -65.0),
    progress: bool = True,
    body_poses: ArrayLike | None = None,
) -> AnimationInfo:
    """Render a run as an animated GIF (matplotlib ``FuncAnimation`` + ``PillowWriter``).

    Args:
        robot: the robot.
        terrain: the ground the run is on.
        times: sample times (T,) [s].
        base_poses: base poses (T, 3) of (x, y, yaw) in the map frame M [m, m, rad].
        q_arm: arm joint angles (T, n), one column per arm joint [rad].
        mu: force-angle stability margin (T,) [N rad] (``NaN`` = unknown, drawn grey).
        out_path: the GIF to write (atomically: temp file + rename); folders are created.
        fps: frames per second of the GIF [1/s].
        size: (width, height) of the GIF [px].
        max_frames: at most this many frames, evenly thinned; ``None`` = every sample.
        mu_scale: margin [N rad] shown full green; default the largest finite ``mu``.
        view: camera (elevation, azimuth) [deg], as ``Axes3D.view_init``.
        progress: show a tqdm progress bar while rendering.
        body_poses: the body's poses ``G_T_B`` (T, 4, 4) to draw (a physics run's attitude);
            None: the terrain's resting pose at each base pose.

    Returns:
        ``AnimationInfo(path, frames, indices)``.

    Raises:
        ValueError: inconsistent shapes or non-finite poses/postures/times.
    """
    import matplotlib

    t = np.asarray(times, dtype=float)
    poses = np.asarray(base_poses, dtype=float)
    q = np.asarray(q_arm, dtype=float)
    m = np.asarray(mu, dtype=float)
    _check_inputs(t, poses, q, m, robot.arm_joints)
    idx = frame_indices(len(t), max_frames)
    finite_mu = m[np.isfinite(m)]
    scale = mu_scale if mu_scale is not None else float(finite_mu.max(initial=0.0))
    scale = scale if scale > 0 else 1.0

    fig = plt.figure(figsize=(size[0] / DPI, size[1] / DPI), dpi=DPI)
    ax3d: Any = fig.add_axes((0.0, 0.0, 0.6, 0.92), projection="3d")
    frames_G = None if body_poses is None else np.asarray(body_poses, dtype=float)
    if frames_G is not None and frames_G.shape != (len(t), 4, 4):
        raise ValueError(f"body_poses: expected ({len(t)}, 4, 4), got {frames_G.shape}")
    G_T_Bs, travelled = _draw_scene(ax3d, robot, terrain, poses, q, idx, view, frames_G)
    panel = _draw_margin_panel(fig, t, m, scale)
    cmap = matplotlib.colormaps[MU_CMAP]
    frames = _Frames(ax3d, robot, terrain, t, poses, q, m, cmap, scale, G_T_Bs, travelled, panel)
    path = _save_gif(fig, frames, idx, Path(out_path), fps, progress)
    return AnimationInfo(path=path, frames=len(idx), indices=idx)


def _draw_scene(
    ax3d: Any,
    robot: Robot,
    terrain: Terrain,
    poses: FloatArray,
    q: FloatArray,
    idx: NDArray[np.intp],
    view: tuple[float, float],
    body_poses: FloatArray | None = None,
) -> tuple[dict[int, FloatArray], LayerLines]:
    """The static scene: the ground, the planned and the (empty) travelled track, the camera.

    The ground patch holds every drawn robot (cut to the map).

    Returns:
        The body poses ``G_T_B`` of the frames' samples, and the travelled track's artist.
    """
    if body_poses is None:
        G_T_Bs = {int(k): terrain.G_T_B(poses[k]) for k in idx}
    else:
        G_T_Bs = {int(k): body_poses[k] for k in idx}
    pts_G = np.concatenate([mesh_points(robot_meshes(robot, q[k], G_T_Bs[int(k)])) for k in idx])
    pts_S = transform_points(np.linalg.inv(terrain.G_T_M()), pts_G)
    lo, hi = pts_S.min(axis=0) - 0.15, pts_S.max(axis=0) + 0.15
    draw_ground(ax3d, terrain, (lo[0], hi[0], lo[1], hi[1]))
    draw_path_on_ground(ax3d, terrain, poses[:, :2], color="0.55", linewidths=0.8)
    travelled = LayerLines([np.zeros((2, 3))], PATH_RANK - 1, colors="C0", linewidths=1.6)
    ax3d.add_collection3d(travelled)
    corners_G = transform_points(terrain.G_T_M(), np.array([[lo[0], lo[1], 0], [hi[0], hi[1], 0]]))
    set_equal_aspect(ax3d, np.vstack([pts_G, corners_G]), margin=0.0, zoom=1.3)
    ax3d.view_init(elev=view[0], azim=view[1])
    ax3d.set_axis_off()
    return G_T_Bs, travelled


class MarginPanel(NamedTuple):
    """The right-hand panel's moving artists.

    Attributes:
        done: the margin so far (line).
        now: the current instant (marker).
        bar: the current margin (bar).
        title: the figure's title (time and margin).
    """

    done: Any
    now: Any
    bar: Any
    title: Any


def _draw_margin_panel(fig: Any, t: FloatArray, m: FloatArray, scale: float) -> MarginPanel:
    """Margin ``m`` [N rad] over time ``t`` [s], the current instant, and a bar of it."""
    ax_mu = fig.add_axes((0.67, 0.16, 0.21, 0.7))
    ax_bar = fig.add_axes((0.9, 0.16, 0.03, 0.7))
    finite_mu = m[np.isfinite(m)]
    ax_mu.plot(t, m, color="0.75", lw=1.0)
    (mu_done,) = ax_mu.plot([], [], color="C0", lw=1.4)
    (mu_now,) = ax_mu.plot([], [], "o", ms=5, mec="k", mew=0.6)
    ax_mu.axhline(0.0, color="C3", lw=0.8, ls=":")
    ax_mu.set(xlabel="t [s]", ylabel="$\\mu$ [N rad]")
    ax_mu.tick_params(labelsize=7)
    ax_mu.xaxis.label.set_fontsize(8)
    ax_mu.yaxis.label.set_fontsize(8)
    top = max(scale, float(finite_mu.max(initial=0.0))) * 1.08
    bottom = min(0.0, float(finite_mu.min(initial=0.0))) - 0.05 * top
    ax_mu.set_ylim(bottom, top)
    if len(t) > 1:
        ax_mu.set_xlim(t[0], t[-1])
    bar = ax_bar.bar([0.0], [0.0], width=1.0, color="0.6", edgecolor="k", lw=0.6)[0]
    ax_bar.axhline(0.0, color="C3", lw=0.8, ls=":")
    ax_bar.set_ylim(bottom, top)
    ax_bar.set_xlim(-0.5, 0.5)
    ax_bar.set_xticks([])
    ax_bar.tick_params(labelsize=7, labelleft=False, labelright=True, right=True, left=False)
    title = fig.suptitle("", fontsize=9)
    return MarginPanel(mu_done, mu_now, bar, title)


@dataclass
class _Frames:
    """Draws frame ``k`` (a sample index): the robot there, the track so far, the margin."""

    ax3d: Any
    robot: Robot
    terrain: Terrain
    t: FloatArray
    poses: FloatArray
    q: FloatArray
    m: FloatArray
    cmap: Any
    scale: float
    G_T_Bs: dict[int, FloatArray]
    travelled: LayerLines
    panel: MarginPanel
    robot_artists: list[Any] = field(default_factory=list)

    def mu_color(self, value: float) -> Any:
        """The colour of margin ``value`` [N rad] (grey when unknown)."""
        if not np.isfinite(value):
            return "0.6"
        return self.cmap(float(np.clip(value / self.scale, 0, 1)))

    def __call__(self, k: int) -> list[Any]:
        for art in self.robot_artists:
            art.remove()
        self.robot_artists.clear()
        t, m, panel = self.t, self.m, self.panel
        color = self.mu_color(m[k])
        self.robot_artists.extend(
            draw_robot(
                self.ax3d, self.robot, self.q[k], self.G_T_Bs[k], support=True, support_color=color
            )
        )
        done = np.column_stack([self.poses[: k + 1, :2], np.full(k + 1, 2e-3)])
        if k == 0:
            done = np.vstack([done, done])
        self.travelled.set_segments([transform_points(self.terrain.G_T_M(), done)])
        panel.done.set_data(t[: k + 1], m[: k + 1])
        panel.now.set_data([t[k]], [m[k]])
        panel.now.set_color(color)
        panel.bar.set_height(m[k] if np.isfinite(m[k]) else 0.0)
        panel.bar.set_color(color)
        panel.bar.set_edgecolor("k")
        panel.title.set_text(f"t = {t[k]:.2f} s    $\\mu$ = {m[k]:.1f} N rad")
        return self.robot_artists


def _save_gif(
    fig: Any, frames: _Frames, idx: NDArray[np.intp], path: Path, fps: int, progress: bool
) -> Path:
    """Render ``frames`` at the samples ``idx`` into the GIF ``path`` (atomically); close ``fig``.

    The GIF is written to a temporary file and renamed, so ``path`` is never half-written.
    """
    from matplotlib.animation import FuncAnimation, PillowWriter

    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=".gif")
    os.close(fd)
    anim = FuncAnimation(fig, frames, frames=[int(k) for k in idx], blit=False, repeat=False)
    bar_progress = tqdm(total=len(idx), desc="animation", unit="frame", disable=not progress)
    try:
        anim.save(
            tmp,
            writer=PillowWriter(fps=fps),
            dpi=DPI,
            progress_callback=lambda i, n: bar_progress.update(1),
        )
        os.chmod(tmp, default_file_mode())  # mkstemp makes it private (0600)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    finally:
        bar_progress.close()
        plt.close(fig)
    return path
