"""Levers, payload: the heaviest payload held front, left and right, arm planned/stowed/fixed."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from experiments.levers.common import (
    DIRECTIONS,
    LeversSettings,
    bisect_largest,
    planar_slope,
)
from mmstab.core.files import write_figure
from mmstab.core.problem import Problem
from mmstab.model.payload import Payload, attach_payload
from mmstab.model.robot import FloatArray, Robot
from mmstab.planner.wrench import tool_points
from mmstab.stability.static import robot_force_angle
from mmstab.viz.plotting import new_figure


def loaded(robot: Robot, mass: float, com_wrist: FloatArray) -> Robot:
    """The robot holding ``mass`` [kg] at ``com_wrist`` [m] (wrist frame)."""
    return attach_payload(robot, Payload(mass=float(mass), com_wrist=com_wrist))


def beyond_edge(
    robot: Robot, tool_body: FloatArray, direction: str, reach: float
) -> NDArray[np.bool_]:
    """Whether tool points (N, 3) [m] lie ``reach`` [m] or more beyond the tracks' edge."""
    t = robot.base.tracks
    half_l, half_w = t.length / 2 + reach, t.separation / 2 + t.width / 2 + reach
    x, y = tool_body[:, 0], tool_body[:, 1]
    return {"front": x >= half_l, "left": y >= half_w, "right": y <= -half_w}[direction]


def pointing_postures(
    robot: Robot, valid_q: FloatArray, direction: str, reach: float
) -> FloatArray:
    """V's collision-free postures holding the tool out at ``direction`` (front, left, right).

    The turret at the grid angle nearest to the direction (``DIRECTIONS``), and the tool
    point (the wrist frame's origin) at least ``reach`` [m] beyond the tracks' footprint
    edge on that side, seen from above: the load is held out beyond the robot, as when
    picking something up; every joint above the ground plane (z_B >= 0).
    """
    q = np.asarray(valid_q, dtype=float)
    turret = np.unique(np.round(q[:, 0], 12))
    gap = np.abs(np.angle(np.exp(1j * (turret - DIRECTIONS[direction]))))
    q = q[np.abs(q[:, 0] - turret[np.argmin(gap)]) < 1e-9]
    # V's postures are free of self-collision only: keep those whose joints (the link
    # frames' origins) stay above the ground plane the tracks stand on
    above = (robot.kinematics.link_frames(q)[:, :, 2, 3] >= 0).all(axis=1)
    q = q[above]
    return q[beyond_edge(robot, tool_points(robot, q), direction, reach)]


def stowed_holding(robot: Robot, direction: str) -> FloatArray:
    """The stowed posture (1, 4) [rad] whose folded arm holds the load toward ``direction``.

    Links 1-3 fold back over the turret, so the wrist lies opposite the turret's direction:
    the turret points away from where the load is (``DIRECTIONS`` + pi).
    """
    turret = (DIRECTIONS[direction] + math.pi) % (2 * math.pi)
    return np.array([[turret, *robot.stowed[1:]]])


def run_payload(problem: Problem, valid_q: FloatArray, settings: LeversSettings) -> dict[str, Any]:
    """Heaviest payload at the front and either side on the side slope, per arm mode."""
    robot = problem.robot
    ramp = planar_slope(problem, settings.side_slope)
    gravity = ramp.gravity_body(np.zeros(3))[0]  # heading 0: across, the left side uphill
    out: dict[str, Any] = {
        "slope_deg": math.degrees(settings.side_slope),
        "heading": "across the slope, left side uphill",
        "margin_N_rad": settings.margin,
        "payload_com_wrist_m": settings.payload_com.tolist(),
        "reach_beyond_tracks_m": settings.payload_reach,
        "max_payload_kg": settings.max_payload,  # the bracket: a result equal to it is a bound
    }
    for name, direction in DIRECTIONS.items():
        planned = pointing_postures(robot, valid_q, name, settings.payload_reach)
        modes = {
            "planned": planned,
            "stowed": stowed_holding(robot, name),
            "fixed": np.array([[direction % (2 * math.pi), 0.0, 0.0, 0.0]]),
        }
        row: dict[str, Any] = {"planned_postures": len(planned)}
        for mode, q in modes.items():

            def best(mass: float, q: FloatArray = q) -> float:
                r = loaded(robot, mass, settings.payload_com)
                g = np.broadcast_to(gravity, (len(q), 3))
                return float(robot_force_angle(r, g, r.arm_com(q)).mu.max())

            heaviest = bisect_largest(
                lambda m, best=best: best(m) >= settings.margin,  # type: ignore[misc]
                0.0,
                settings.max_payload,
                settings.bisection_steps,
            )
            row[mode] = {
                "heaviest_kg": None if heaviest != heaviest else heaviest,
                "mu_unloaded": best(0.0),
            }
        out[name] = row
    return out


def draw_payload(summary: dict[str, Any], path: Path) -> None:
    """Heaviest payload per direction and arm mode (bars)."""
    fig, ax = new_figure(figsize=(6.4, 3.6))
    width = 0.26
    top = summary["max_payload_kg"]
    for j, mode in enumerate(("planned", "stowed", "fixed")):
        raw = [summary[d][mode]["heaviest_kg"] for d in DIRECTIONS]
        x = np.arange(len(DIRECTIONS)) + (j - 1) * width
        bars = ax.bar(x, [v or 0.0 for v in raw], width, label=f"arm {mode}")
        labels = [
            "tips\nunloaded" if v is None else (f">= {v:.0f}" if v >= top else f"{v:.1f}")
            for v in raw
        ]
        ax.bar_label(bars, labels, fontsize=7)
    ax.set_xticks(np.arange(len(DIRECTIONS)), list(DIRECTIONS))
    ax.set(
        ylabel="heaviest payload [kg]",
        title=f"{summary['slope_deg']:.0f} deg side slope, mu >= {summary['margin_N_rad']:g} N rad",
    )
    ax.set_ylim(0, top * 1.15)
    ax.legend(fontsize=8, loc="upper center", ncols=3)
    write_figure(path, fig)
