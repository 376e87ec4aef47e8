"""``mmstab stability-map``: the stability map of a problem's ground and its 3-D view at rest.

``mmstab stability-map PROBLEM`` (``make terrain`` runs it on every shipped terrain):
mu of the stowed arm over a grid of positions x headings, the worst and the best heading
per cell (where can the robot stand at all), and the ground in 3-D with the robot at rest
at the centre, the worst and the best cell. Outputs in ``results/terrain/<problem>/``:
``stability_map.png``, ``terrain_3d.png``, ``summary.json``, ``stability_map.npz`` (arrays,
not committed) and the settings (``problem.yaml``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from mmstab.core.files import MmstabError, write_figure, write_json, write_npz
from mmstab.core.problem import Problem
from mmstab.core.sizes import Estimate, refusal
from mmstab.outputs.common import output_dir, save_settings
from mmstab.stability.stance import StabilityMap, stability_map, stance
from mmstab.terrain.factory import as_heightmap
from mmstab.terrain.heightmap_terrain import HeightmapTerrain

#: Extent and cells of a ramp sampled for its map [m], [m/cell].
RAMP_SIZE, RAMP_RESOLUTION = (6.0, 6.0), 0.1
#: One resting pose of the map and its mu: time [s] and peak memory [B] (measured on
#: problems/rough.yaml at 0.25 m and 0.1 m spacing: 1.2-1.7 ms, 10.7 kB).
MAP_SECONDS_PER_POSE, MAP_BYTES_PER_POSE = 1.7e-3, 11e3


def map_estimate(terrain: HeightmapTerrain, spacing: float, headings: int) -> Estimate:
    """The poses of a stability map (at most: the robot's reach from the edge not taken off)."""
    x0, x1, y0, y1 = terrain.heightmap.bounds
    poses = ((x1 - x0) / spacing + 1.0) * ((y1 - y0) / spacing + 1.0) * float(headings)
    return Estimate(
        "--spacing",
        f"{poses:.3g} resting poses (every {spacing:g} m, {headings} headings)",
        poses * MAP_SECONDS_PER_POSE,
        poses * MAP_BYTES_PER_POSE,
    )


def problem_heightmap_terrain(problem: Problem) -> HeightmapTerrain:
    """The problem's ground as a heightmap terrain bound to its robot (a ramp is sampled)."""
    t = problem.terrain
    if isinstance(t, HeightmapTerrain):
        return t
    hm = as_heightmap(t, RAMP_SIZE, RAMP_RESOLUTION)
    return HeightmapTerrain(hm).with_robot(problem.robot)


def _cell(sm: StabilityMap, which: str) -> tuple[int, int]:
    field = sm.worst if which == "worst" else sm.best
    v = np.where(np.isfinite(field), field, np.inf if which == "worst" else -np.inf)
    k = int(np.argmin(v) if which == "worst" else np.argmax(v))
    iy, ix = np.unravel_index(k, field.shape)
    return int(iy), int(ix)


def snapshot_poses(sm: StabilityMap) -> dict[str, list[float]]:
    """Poses drawn at rest: the map centre (heading 0), the worst and the best cell."""
    out = {"centre": [float(np.median(sm.x)), float(np.median(sm.y)), 0.0]}
    for which in ("worst", "best"):
        iy, ix = _cell(sm, which)
        h = sm.worst_heading if which == "worst" else sm.best_heading
        out[which] = [float(sm.x[ix]), float(sm.y[iy]), float(h[iy, ix])]
    return out


def draw_stability_map(sm: StabilityMap, title: str) -> Any:
    """Three panels: mu at the worst and the best heading per cell (red: < 0), slip margin.

    The third panel is the smallest slip margin over the headings (``atan(friction)`` minus
    the support's tilt, red: the tracks slide), the second limit beside the tip limit.
    """
    import matplotlib.pyplot as plt
    from matplotlib.colors import TwoSlopeNorm

    finite = np.concatenate([sm.worst[np.isfinite(sm.worst)], sm.best[np.isfinite(sm.best)]])
    vmax = float(np.max(finite)) if finite.size and np.max(finite) > 0 else 1.0
    lo = float(np.min(finite)) if finite.size else -1.0
    extent = (
        sm.x[0] - (sm.x[1] - sm.x[0]) / 2 if sm.x.size > 1 else sm.x[0] - 0.5,
        sm.x[-1] + (sm.x[1] - sm.x[0]) / 2 if sm.x.size > 1 else sm.x[0] + 0.5,
        sm.y[0] - (sm.y[1] - sm.y[0]) / 2 if sm.y.size > 1 else sm.y[0] - 0.5,
        sm.y[-1] + (sm.y[1] - sm.y[0]) / 2 if sm.y.size > 1 else sm.y[0] + 0.5,
    )
    # a map wider than tall is drawn as three rows, else as three columns: each panel (and
    # its colour bar, as tall as its slot) close to the map's own shape
    aspect = (extent[1] - extent[0]) / max(extent[3] - extent[2], 1e-9)
    rows = aspect > 2.0
    if rows:
        panel_h = min(max(8.5 / aspect, 1.6), 4.5)
        fig, axes = plt.subplots(3, 1, figsize=(10.5, 3 * (panel_h + 0.8) + 0.5),
                                 constrained_layout=True)  # fmt: skip
    else:
        panel_w = min(max(4.2 * aspect, 3.0), 5.0)
        fig, axes = plt.subplots(1, 3, figsize=(3 * (panel_w + 1.4), 4.6), constrained_layout=True)
    for ax, field, heading, name in (
        (axes[0], sm.worst, sm.worst_heading, "worst"),
        (axes[1], sm.best, sm.best_heading, "best"),
    ):
        norm = TwoSlopeNorm(vcenter=0.0, vmin=min(lo, -1e-3 * vmax), vmax=vmax)
        im = ax.imshow(field, origin="lower", extent=extent, cmap="RdYlGn", norm=norm)
        if np.nanmin(field) < 0 < np.nanmax(field) and field.shape[0] > 1 and field.shape[1] > 1:
            ax.contour(sm.x, sm.y, field, levels=[0.0], colors="k", linewidths=1.0)
        step = max(1, max(field.shape) // 12)
        Xq, Yq = np.meshgrid(sm.x[::step], sm.y[::step])
        hq = heading[::step, ::step]
        ax.quiver(Xq, Yq, np.cos(hq), np.sin(hq), color="k", alpha=0.6, scale=35 if rows else 22,
                  width=0.003 if rows else 0.005)  # fmt: skip
        ax.set_title(f"mu at the {name} heading per cell (arrows: that heading)", fontsize=10)
        ax.set_xlabel("x_G [m]")
        ax.set_ylabel("y_G [m]")
        fig.colorbar(im, ax=ax, label="mu [N rad]")
    slip = np.degrees(sm.worst_slip_margin)
    span = float(np.nanmax(np.abs(slip))) if np.isfinite(slip).any() else 1.0
    norm = TwoSlopeNorm(vcenter=0.0, vmin=-max(span, 1e-3), vmax=max(span, 1e-3))
    im = axes[2].imshow(slip, origin="lower", extent=extent, cmap="RdYlGn", norm=norm)
    if np.nanmin(slip) < 0 < np.nanmax(slip) and slip.shape[0] > 1 and slip.shape[1] > 1:
        axes[2].contour(sm.x, sm.y, slip, levels=[0.0], colors="k", linewidths=1.0)
    axes[2].set_title(f"slip margin at the worst heading (friction {sm.friction:g})", fontsize=10)
    axes[2].set_xlabel("x_G [m]")
    axes[2].set_ylabel("y_G [m]")
    fig.colorbar(im, ax=axes[2], label="atan(friction) - tilt [deg]")
    fig.suptitle(title)
    return fig


def draw_terrain_3d(problem: Problem, terrain: HeightmapTerrain, poses: dict[str, Any]) -> Any:
    """The ground in 3-D: the whole map, then a close-up of the robot at rest at each pose.

    The robot (stowed arm) is drawn over the ground (no depth sorting between them), its
    touching contacts as red dots.
    """
    import matplotlib.pyplot as plt

    from mmstab.viz.drawing import draw_robot, set_equal_aspect

    hm = terrain.heightmap
    robot = problem.robot
    fig = plt.figure(figsize=(14, 4.2 * (1 + (len(poses) + 1) // 4)))
    n = len(poses) + 1
    ax = fig.add_subplot(1, n, 1, projection="3d")
    terrain.draw(ax, alpha=0.9)
    x0, x1, y0, y1 = hm.bounds
    z = hm.elevation[np.isfinite(hm.elevation)]
    for name, pose in poses.items():
        ax.scatter(pose[0], pose[1], hm.height(pose[:2]) + 0.05, s=20, c="k")
        ax.text(pose[0], pose[1], float(hm.height(pose[:2])) + 0.3, name, fontsize=8)
    set_equal_aspect(ax, np.array([[x0, y0, z.min()], [x1, y1, z.max()]]))
    ax.set_title(f"{problem.name}: {hm.source}", fontsize=9)
    ax.set_xlabel("x_G [m]")
    ax.set_ylabel("y_G [m]")
    half = 0.9  # close-up window half-width [m]
    for k, (name, pose) in enumerate(poses.items()):
        ax = fig.add_subplot(1, n, k + 2, projection="3d")
        ax.computed_zorder = False  # draw in order: ground, then the robot on top
        st = stance(terrain, robot, pose)
        window = HeightmapTerrain(_crop(hm, pose[:2], half))
        window.draw(ax, stride=1, alpha=0.8)
        draw_robot(ax, robot, robot.stowed, st.G_T_B, edge_width=0.1)
        if len(st.contacts):
            c = st.contacts
            ax.scatter(c[:, 0], c[:, 1], c[:, 2], s=6, c="r", depthshade=False, zorder=10)
        p = st.G_T_B[:3, 3]
        set_equal_aspect(ax, np.array([p - [half, half, 0.3], p + [half, half, 0.9]]))
        flags = ", ".join(st.flags) or "no flags"
        ax.set_title(
            f"{name}: roll {np.degrees(st.roll):.1f}, pitch {np.degrees(st.pitch):.1f} deg\n"
            f"mu {st.mu:.0f} N rad; {flags}",
            fontsize=9,
        )
        ax.view_init(elev=25, azim=-60 + np.degrees(pose[2]) - 30)
        ax.set_axis_off()
    return fig


def _crop(hm: Any, xy: Any, half: float) -> Any:
    """The part of ``hm`` within ``half`` [m] of ``xy`` (a heightmap)."""
    from mmstab.terrain.heightmap import Heightmap

    ix = np.flatnonzero(np.abs(hm.x - xy[0]) <= half)
    iy = np.flatnonzero(np.abs(hm.y - xy[1]) <= half)
    e = hm.elevation[iy[0] : iy[-1] + 1, ix[0] : ix[-1] + 1]
    return Heightmap.build(e, hm.resolution, [hm.x[ix[0]], hm.y[iy[0]]], hm.source)


def run_stability_map(
    problem: Problem,
    out: str | Path | None,
    spacing: float,
    headings: int,
    force_size: bool = False,
) -> dict[str, Any]:
    """Stability map and 3-D view of the problem's terrain (see the module docstring).

    Raises:
        MmstabError: ``spacing`` [m] and ``headings`` beyond the size bounds
            (:func:`map_estimate`; ``force_size`` accepts the time, not the memory).
    """
    terrain = problem_heightmap_terrain(problem)
    why = refusal(map_estimate(terrain, spacing, headings), force_size)
    if why is not None:
        raise MmstabError(f"--spacing / --headings: {why}")
    sm = stability_map(terrain, spacing, headings)
    d = output_dir(out, f"terrain/{problem.name}")
    save_settings(d, problem, stability_map={"spacing": spacing, "headings": headings})
    poses = snapshot_poses(sm)
    write_npz(
        d / "stability_map.npz",
        x=sm.x,
        y=sm.y,
        headings=sm.headings,
        mu=sm.mu,
        flags=sm.flags,
        worst=sm.worst,
        best=sm.best,
        worst_heading=sm.worst_heading,
        best_heading=sm.best_heading,
        slip_margin=sm.slip_margin,
        worst_slip_margin=sm.worst_slip_margin,
    )
    write_figure(d / "stability_map.png", draw_stability_map(sm, f"{problem.name}: stability map"))
    write_figure(d / "terrain_3d.png", draw_terrain_3d(problem, terrain, poses))
    finite = np.isfinite(sm.mu)
    n = int(finite.sum())
    summary = {
        "problem": problem.name,
        "terrain": terrain.heightmap.source,
        "grid": {"nx": int(sm.x.size), "ny": int(sm.y.size), "headings": headings},
        "spacing_m": spacing,
        "poses": int(sm.mu.size),
        "poses_on_map": n,
        "rest_seconds": sm.seconds_rest,
        "rest_ms_per_pose": 1e3 * sm.seconds_rest / max(sm.mu.size, 1),
        # stable: neither tips nor slides; the two limits apart beside it
        "share_stable": float(sm.holds()[finite].mean()) if n else None,
        "share_no_tip": float((sm.mu[finite] > 0).mean()) if n else None,
        "share_no_slide": float((sm.slip_margin[finite] >= 0).mean()) if n else None,
        "friction": sm.friction,
        "slip_margin_worst_min_rad": float(np.nanmin(sm.worst_slip_margin)) if n else None,
        "cells_unstable_at_every_heading": int(np.sum(sm.best <= 0)),
        "cells_stable_at_every_heading": int(np.sum(sm.holds().all(axis=2))),
        "cells_no_tip_at_every_heading": int(np.sum(sm.worst > 0)),
        "mu_worst_min": float(np.nanmin(sm.worst)),
        "mu_best_max": float(np.nanmax(sm.best)),
        "high_centred_poses": int(np.sum((sm.flags & 1) > 0)),
        "line_contact_poses": int(np.sum((sm.flags & 2) > 0)),
        "tips_over_poses": int(np.sum((sm.flags & 4) > 0)),
        "not_converged_poses": int(np.sum((sm.flags & 8) > 0)),
        "sliding_poses": int(np.sum((sm.flags & 16) > 0)),
        "snapshots": poses,
    }
    write_json(d / "summary.json", summary)
    return summary
