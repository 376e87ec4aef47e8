"""Paper Fig. 5 and Fig. 6: stability while link0 sweeps a full turn, the arm stretched.

Fig. 5: one base pose with roll and no pitch. Fig. 6: poses along the circle on the ramp.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from experiments.common import circular_extrema
from mmstab.core.files import write_figure, write_json, write_npz
from mmstab.core.problem import Problem
from mmstab.model.robot import FloatArray, Robot
from mmstab.outputs.common import output_dir, save_settings
from mmstab.stability.static import robot_force_angle
from mmstab.stability.support import stability_along
from mmstab.terrain import Terrain, roll_pitch
from mmstab.viz.plotting import draw_base_topview, draw_circle, new_figure


class Sweep(NamedTuple):
    """Stability of link0 sweeps at several base poses.

    Attributes:
        link0: link0 angles (S,) [rad], 0 .. 2 pi (exclusive).
        poses: base poses (P, 3) in S [m, m, rad].
        mu: force-angle measure (P, S) [N rad].
        mu_arm_removed: mu of the base alone at each pose (P,) [N rad].
        mu_stowed: mu with the arm stowed at each pose (P,) [N rad].
    """

    link0: FloatArray
    poses: FloatArray
    mu: FloatArray
    mu_arm_removed: FloatArray
    mu_stowed: FloatArray


def link0_sweep(robot: Robot, terrain: Terrain, poses: FloatArray, samples: int) -> Sweep:
    """Sweep link0 over a full turn (joints 1-3 at zero) at each base pose.

    Args:
        robot: the robot.
        terrain: the ground.
        poses: base poses (P, 3) in the map frame M [m, m, rad].
        samples: number of link0 samples; step 2 pi / samples [rad].
    """
    link0 = np.arange(samples) * 2 * np.pi / samples
    q = np.zeros((samples, 4))
    q[:, 0] = link0
    com = robot.arm_com(q)
    gravity = terrain.gravity_body(poses)  # (P, 3)
    mu = np.stack(
        [robot_force_angle(robot, np.broadcast_to(g, (samples, 3)), com).mu for g in gravity]
    )
    cases = stability_along(robot, terrain, poses, robot.arm_com(robot.stowed))
    return Sweep(
        link0=link0,
        poses=poses,
        mu=mu,
        mu_arm_removed=cases.arm_removed,
        mu_stowed=cases.stowed,
    )


def sweep_collisions(robot: Robot, link0: FloatArray) -> NDArray[np.bool_]:
    """Which samples of a link0 sweep (other joints zero) are in self-collision (FCL).

    The paper's sweep ignores collisions; with the flippers raised, the stretched arm
    passes through them, so those samples are marked, not hidden.
    """
    from mmstab.model.collision import CollisionChecker

    q = np.zeros((len(link0), 4))
    q[:, 0] = link0
    return np.asarray(CollisionChecker(robot).collides(q), dtype=bool)


def run_fig5(problem: Problem, out: str | Path | None = None) -> dict[str, Any]:
    """Paper Fig. 5: base with roll and zero pitch, link0 swept; writes ``results/fig5``."""
    cfg = problem.section("sweep")
    pose = np.array([cfg["roll_pose"]], dtype=float)
    sw = link0_sweep(problem.robot, problem.terrain, pose, cfg["samples"])
    mu = sw.mu[0]
    maxima, minima = circular_extrema(mu)
    roll, pitch = roll_pitch(problem.terrain, pose[0])
    collides = sweep_collisions(problem.robot, sw.link0)
    d = output_dir(out, "fig5")
    fig, ax = new_figure(figsize=(6.4, 3.6))
    ax.plot(np.degrees(sw.link0), mu, "-", color="C0", label="arm stretched, link0 swept")
    ax.plot(
        np.degrees(sw.link0[collides]),
        mu[collides],
        "x",
        color="0.3",
        ms=4,
        label="arm hits a flipper (not a valid posture)",
    )
    ax.plot(np.degrees(sw.link0[maxima]), mu[maxima], "v", color="C3", label="local maxima")
    ax.axhline(sw.mu_arm_removed[0], color="0.4", ls="--", label="arm removed")
    ax.axhline(sw.mu_stowed[0], color="C2", ls=":", label="arm stowed")
    ax.set(
        xlabel="link0 angle [deg]",
        ylabel="force-angle stability $\\mu$ [N rad]",
        title=f"Fig. 5: roll {round(np.degrees(roll), 1) + 0.0} deg, "
        f"pitch {round(np.degrees(pitch), 1) + 0.0} deg",
        xlim=(0, 360),
        xticks=np.arange(0, 361, 45),
    )
    ax.legend(fontsize=8, loc="lower center")
    ax.grid(alpha=0.3)
    write_figure(d / "fig5.png", fig)
    write_npz(d / "sweep.npz", link0=sw.link0, mu=mu)
    summary = {
        "pose": pose[0],
        "roll_rad": roll,
        "pitch_rad": pitch,
        "link0": sw.link0,
        "mu": mu,
        "local_maxima_rad": sw.link0[maxima],
        "local_maxima_mu": mu[maxima],
        "local_minima_rad": sw.link0[minima],
        "mu_arm_removed": float(sw.mu_arm_removed[0]),
        "mu_stowed": float(sw.mu_stowed[0]),
        "colliding_link0_rad": sw.link0[collides],
    }
    save_settings(d, problem)
    write_json(d / "summary.json", summary)
    return summary


def poses3d_figure(problem: Problem, sw: Sweep) -> Any:
    """Paper Fig. 6(a) in 3-D: the robot at each pose on the ramp, arm at its best link0.

    Args:
        problem: the problem (robot, ramp).
        sw: the sweep of :func:`link0_sweep` (its poses and mu).

    Returns:
        The matplotlib figure.
    """
    from mmstab.viz.drawing import draw_poses_on_ground

    cmap = __import__("matplotlib").colormaps["viridis"]
    postures = np.zeros((len(sw.poses), 4))
    postures[:, 0] = sw.link0[np.argmax(sw.mu, axis=1)]  # link0 of highest mu; others zero
    fig, ax = new_figure(figsize=(7.5, 6.0), subplot_kw={"projection": "3d"})
    colors = [cmap(k / max(len(sw.poses) - 1, 1)) for k in range(len(sw.poses))]
    labels = [str(k) for k in range(len(sw.poses))]
    path_S = problem.circle.pose_at(np.linspace(0, 1, 121))[:, :2]
    draw_poses_on_ground(
        ax, problem.robot, problem.terrain, sw.poses, postures, colors, labels, path_S=path_S
    )
    ax.view_init(elev=35, azim=-70)
    ax.set_title(
        f"(a) the {len(sw.poses)} poses on the {problem.terrain.label} (uphill +y),"
        " arm at the link0 of highest $\\mu$",
        fontsize=9,
    )
    return fig


def run_fig6(problem: Problem, out: str | Path | None = None) -> dict[str, Any]:
    """Paper Fig. 6: poses along the circle, one sweep each; writes ``results/fig6``."""
    cfg = problem.section("sweep")
    poses = problem.circle.poses(cfg["poses"])
    sw = link0_sweep(problem.robot, problem.terrain, poses, cfg["samples"])
    d = output_dir(out, "fig6")
    fig, (ax_a, ax_b) = new_figure(1, 2, figsize=(11, 4.4), width_ratios=[1, 1.5])
    draw_circle(ax_a, problem.circle)
    cmap = __import__("matplotlib").colormaps["viridis"]
    per_pose = []
    for k, (pose, mu) in enumerate(zip(sw.poses, sw.mu, strict=True)):
        c = cmap(k / max(len(poses) - 1, 1))
        draw_base_topview(ax_a, problem.robot, pose, color=c, label=str(k))
        ax_b.plot(np.degrees(sw.link0), mu, color=c, lw=1.2, label=f"pose {k}")
        maxima, minima = circular_extrema(mu)
        ax_b.plot(np.degrees(sw.link0[maxima]), mu[maxima], "v", color=c, ms=4)
        roll, pitch = roll_pitch(problem.terrain, pose)
        per_pose.append(
            {
                "pose": pose,
                "roll_rad": roll,
                "pitch_rad": pitch,
                "local_maxima_rad": sw.link0[maxima],
                "local_maxima_mu": mu[maxima],
                "local_minima_rad": sw.link0[minima],
                "mu_min": float(mu.min()),
                "mu_max": float(mu.max()),
                "mu_arm_removed": float(sw.mu_arm_removed[k]),
                "mu_stowed": float(sw.mu_stowed[k]),
            }
        )
    ax_a.set(
        aspect="equal",
        xlabel="$x_S$ [m]",
        ylabel="$y_S$ [m] (uphill)",
        title=f"(a) poses on the {problem.terrain.label}",
    )
    ax_b.set(
        xlabel="link0 angle [deg]",
        ylabel="$\\mu$ [N rad]",
        xlim=(0, 360),
        xticks=np.arange(0, 361, 45),
        title="(b) stability over link0 at each pose",
    )
    ax_b.legend(fontsize=7, ncol=2)
    ax_b.grid(alpha=0.3)
    write_figure(d / "fig6.png", fig)
    write_figure(d / "fig6_poses3d.png", poses3d_figure(problem, sw))
    write_npz(d / "sweep.npz", link0=sw.link0, mu=sw.mu, poses=sw.poses)
    counts = [len(p["local_maxima_rad"]) for p in per_pose]
    summary = {
        "link0": sw.link0,
        "poses": per_pose,
        "poses_with_two_maxima": int(sum(c == 2 for c in counts)),
        "maxima_per_pose": counts,
    }
    save_settings(d, problem)
    write_json(d / "summary.json", summary)
    return summary
