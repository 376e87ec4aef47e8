"""Paper Fig. 3: the arm-CoM workspace V, the hull of the invalid CoMs, the hull of all CoMs.

Writes ``results/fig3/``: ``fig3a_V.png``, ``fig3b_invalid_hull.png``,
``fig3c_all_hull.png``, ``summary.json`` (counts, volumes, diameter, recall, precision,
build time) and the settings used. The workspace comes from the cache when it matches.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from mmstab.app import workspace
from mmstab.app.settings import Settings
from mmstab.core.files import write_figure, write_json
from mmstab.core.problem import Problem
from mmstab.model.robot import Robot
from mmstab.outputs.common import output_dir, save_settings
from mmstab.viz.plotting import new_figure
from mmstab.workspace import (
    Workspace,
    convex_hull,
)
from mmstab.workspace.fidelity import measure_fidelity, sample_in_workspace

#: Points drawn per scatter cloud in the figures (subsampled: the figures stay small).
PLOT_POINTS = 3000


def _subsample(points: ArrayLike, n: int, rng: np.random.Generator) -> np.ndarray:
    pts = np.asarray(points, dtype=float)
    return pts if len(pts) <= n else pts[rng.choice(len(pts), n, replace=False)]


def _axes3d(title: str) -> tuple[Any, Any]:
    fig, ax = new_figure(figsize=(4.8, 4.4), subplot_kw={"projection": "3d"})
    ax.set(xlabel="$x_B$ [m]", ylabel="$y_B$ [m]", zlabel="$z_B$ [m]")
    ax.set_title(title, fontsize=9)
    ax.tick_params(labelsize=7)
    return fig, ax


def _draw_base(ax: Any, robot: Robot) -> None:
    """Wireframes of the base collision boxes (body frame), for scale."""
    for box in robot.base.collision_boxes().values():
        c = box.corners()  # index 4 ix + 2 iy + iz
        for a in range(8):
            for bit in (1, 2, 4):
                if not a & bit:
                    seg = c[[a, a | bit]]
                    ax.plot(seg[:, 0], seg[:, 1], seg[:, 2], color="0.55", lw=0.6)


def _draw_hull(ax: Any, points: np.ndarray, what: str, color: str) -> None:
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    hull = convex_hull(points, what)
    faces = Poly3DCollection(hull.points[hull.simplices], alpha=0.18, linewidths=0.2)
    faces.set_facecolor(color)
    faces.set_edgecolor(color)
    ax.add_collection3d(faces)


def _frame(ax: Any, lo: np.ndarray, hi: np.ndarray) -> None:
    ax.set(xlim=(lo[0], hi[0]), ylim=(lo[1], hi[1]), zlim=(lo[2], hi[2]))
    ax.set_box_aspect(hi - lo)


def plot_fig3(
    robot: Robot, ws: Workspace, in_V: np.ndarray, out_dir: Path, rng: np.random.Generator
) -> list[Path]:
    """The three panels of Fig. 3 as separate PNGs.

    Args:
        robot: the robot (base boxes drawn for scale).
        ws: the workspace.
        in_V: points drawn uniformly in V (n, 3), body frame [m].
        out_dir: output folder.
        rng: subsampling generator.
    """
    all_com = np.vstack([ws.valid_com, ws.invalid_com])
    corners = np.vstack([all_com, *(b.corners() for b in robot.base.collision_boxes().values())])
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    paths = []

    fig, ax = _axes3d(f"(a) V = hull(all) \\ hull(invalid): {len(in_V)} points uniform in V")
    pts = _subsample(in_V, PLOT_POINTS, rng)
    ax.scatter(*pts.T, s=1.5, c=pts[:, 2], cmap="viridis", depthshade=False)
    _draw_base(ax, robot)
    _frame(ax, lo, hi)
    paths.append(write_figure(out_dir / "fig3a_V.png", fig))

    fig, ax = _axes3d(f"(b) hull of the {len(ws.invalid_com)} invalid (colliding) CoMs")
    if len(ws.invalid_com):
        _draw_hull(ax, ws.invalid_com, "invalid arm CoMs", "C3")
        ax.scatter(*_subsample(ws.invalid_com, PLOT_POINTS, rng).T, s=1, color="C3")
    _draw_base(ax, robot)
    _frame(ax, lo, hi)
    paths.append(write_figure(out_dir / "fig3b_invalid_hull.png", fig))

    fig, ax = _axes3d(f"(c) hull of all {ws.postures} CoMs (blue valid, red invalid)")
    _draw_hull(ax, all_com, "all arm CoMs", "C0")
    n = PLOT_POINTS // 2
    ax.scatter(*_subsample(ws.valid_com, n, rng).T, s=1, color="C0")
    if len(ws.invalid_com):
        ax.scatter(*_subsample(ws.invalid_com, n, rng).T, s=1, color="C3")
    _draw_base(ax, robot)
    _frame(ax, lo, hi)
    paths.append(write_figure(out_dir / "fig3c_all_hull.png", fig))
    return paths


def run_fig3(
    problem: Problem, out: str | Path | None = None, force: bool = False
) -> dict[str, Any]:
    """Paper Fig. 3 and the workspace's numbers; writes ``results/fig3``.

    Args:
        problem: the problem (robot and ``workspace`` section).
        out: output folder (default ``results/fig3``).
        force: rebuild the workspace even when the cache matches.
    """
    cfg = Settings.from_problem(problem).workspace
    ws = workspace(problem, force=force)
    fid = measure_fidelity(problem.robot, ws, cfg.precision_samples, cfg.seed)
    rng = np.random.default_rng(cfg.seed)
    d = output_dir(out, "fig3")
    plot_fig3(problem.robot, ws, sample_in_workspace(ws, PLOT_POINTS, rng), d, rng)
    summary = {
        "grid": list(ws.grid),
        "postures": ws.postures,
        "valid": len(ws.valid_com),
        "invalid": len(ws.invalid_com),
        "volume_all": ws.volume_all,
        "volume_invalid": ws.volume_invalid,
        "volume_V": ws.volume_V,
        "volume_V_method": "exact: hull(invalid) lies inside hull(all), so V = all - invalid",
        "diameter": ws.diameter,
        "recall": fid.recall,
        "precision": fid.precision,
        "precision_half_cell": fid.precision_half_cell,
        "cell_size": fid.cell_size,
        "precision_samples": fid.samples,
        "facets_all": len(ws.b_all),
        "facets_invalid": len(ws.b_bad),
        "build_seconds": ws.build_seconds,
        "postures_per_second": ws.postures / ws.build_seconds if ws.build_seconds else None,
    }
    save_settings(d, problem)
    write_json(d / "summary.json", summary)
    return summary
