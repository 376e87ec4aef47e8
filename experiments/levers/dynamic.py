"""Levers, dynamic: static vs dynamic force-angle μ along the lap at several speeds."""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike
from scipy.interpolate import CubicSpline

from experiments.levers.common import SIM_WINDOW, LeversSettings, bisect_largest
from mmstab.app.settings import Settings
from mmstab.core.files import write_figure
from mmstab.core.problem import Problem, problem_from_dict
from mmstab.model.robot import FloatArray, Robot
from mmstab.paths.circle import CirclePath
from mmstab.stability.dynamic import dynamic_force_angle, net_wrench
from mmstab.stability.static import base_polygon
from mmstab.terrain import GRAVITY_G, Terrain
from mmstab.viz.plotting import new_figure


def posture_spline(postures: ArrayLike) -> Callable[[ArrayLike], FloatArray]:
    """Periodic cubic spline q(s) through postures at fractions k/K of one lap [rad].

    A turret that turns a whole number of turns over the lap is unwrapped and its drift
    added back, so the spline is smooth and the lap closes.
    """
    q = np.asarray(postures, dtype=float).reshape(-1, 4)
    closed = np.unwrap(np.vstack([q, q[:1]]), axis=0)
    drift = closed[-1] - closed[0]
    s = np.arange(len(closed)) / len(q)
    spline = CubicSpline(s, closed - np.outer(s, drift), bc_type="periodic", axis=0)
    return lambda x: spline(np.mod(x, 1.0)) + np.outer(np.atleast_1d(x), drift)


class LapMotion(NamedTuple):
    """The bodies' motion along one lap in the map frame M.

    Attributes:
        poses: base poses (N, 3) in M.
        M_T_B: resting body poses (N, 4, 4).
        masses: body masses (k,) [kg]: base, then the arm links.
        positions: body CoMs in M (N, k, 3) [m].
        postures: arm postures (N, 4) [rad].
    """

    poses: FloatArray
    M_T_B: FloatArray
    masses: FloatArray
    positions: FloatArray
    postures: FloatArray


def lap_motion(
    robot: Robot,
    terrain: Terrain,
    circle: CirclePath,
    posture: Callable[[ArrayLike], FloatArray],
    samples: int,
) -> LapMotion:
    """Every body's CoM along one lap (fractions k/samples) in M."""
    s = np.arange(samples) / samples
    return body_motion(robot, terrain, circle.pose_at(s), posture(s))


class LapMeasure(NamedTuple):
    """Force-angle μ along one lap [N rad] (N,), static and dynamic, and the peak acceleration."""

    static: FloatArray
    dynamic: FloatArray
    peak_acceleration: float  # largest body CoM acceleration [m/s^2]
    peak_joint_speed: FloatArray  # per arm joint [rad/s]


def body_motion(robot: Robot, terrain: Terrain, poses: ArrayLike, q: ArrayLike) -> LapMotion:
    """Every body's CoM in M at base poses (N, 3) in M and arm postures (N, 4) [rad]."""
    P = np.asarray(poses, dtype=float)
    Q = np.asarray(q, dtype=float)
    T = terrain.M_T_B(P).reshape(-1, 4, 4)
    body = np.concatenate(
        [np.broadcast_to(robot.base.com, (len(Q), 1, 3)), robot.kinematics.link_coms(Q)], axis=1
    )
    positions = np.einsum("nij,nkj->nki", T[:, :3, :3], body) + T[:, None, :3, 3]
    masses = np.array([robot.base.mass, *(link.mass for link in robot.links)])
    return LapMotion(P, T, masses, positions, Q)


def measure_motion(
    robot: Robot,
    terrain: Terrain,
    motion: LapMotion,
    h: float,
    window: int = 1,
    periodic: bool = True,
) -> LapMeasure:
    """Static and dynamic μ of a sampled motion (step ``h`` [s] between samples).

    Accelerations are second differences over ``window`` samples (``window * h`` [s]);
    ``periodic``: the samples close a lap (``np.roll``); else the ``window`` samples at
    each end are dropped.
    """
    p, k = motion.positions, int(window)
    if periodic:
        acc = (np.roll(p, -k, axis=0) - 2 * p + np.roll(p, k, axis=0)) / (k * h) ** 2
        dq = (np.roll(motion.postures, -1, axis=0) - np.roll(motion.postures, 1, axis=0)) / (2 * h)
        keep = np.arange(len(p))
    else:
        acc = (p[2 * k :] - 2 * p[k:-k] + p[: -2 * k]) / (k * h) ** 2
        dq = np.diff(motion.postures, axis=0) / h
        keep = np.arange(k, len(p) - k)
    n = len(keep)
    g_M = terrain.G_T_M()[:3, :3].T @ GRAVITY_G
    polygon = base_polygon(robot).vertices
    R, t = motion.M_T_B[keep, :3, :3], motion.M_T_B[keep, :3, 3]
    w = net_wrench(motion.masses, p[keep], acc, np.broadcast_to(g_M, (n, 3)))  # all at once
    com_b, f_b, n_b = (np.einsum("nji,nj->ni", R, v) for v in (w.com - t, w.force, w.moment))
    f_s = np.einsum("nji,j->ni", R, motion.masses.sum() * g_M)
    return LapMeasure(
        static=dynamic_force_angle(polygon, com_b, f_s, np.zeros((n, 3))).mu,
        dynamic=dynamic_force_angle(polygon, com_b, f_b, n_b).mu,
        peak_acceleration=float(np.linalg.norm(acc, axis=2).max()),
        peak_joint_speed=np.abs(dq).max(axis=0),
    )


def lap_measure(robot: Robot, terrain: Terrain, motion: LapMotion, lap_time: float) -> LapMeasure:
    """Static and dynamic μ of a lap driven in ``lap_time`` [s] (module text)."""
    return measure_motion(robot, terrain, motion, lap_time / len(motion.poses))


def simulated_check(
    problem: Problem, plan: Any, settings: LeversSettings, window: float = SIM_WINDOW
) -> dict[str, Any]:
    """The dynamic μ from closed-loop runs of the planned arm at each lap speed.

    One tracking run per speed (``app.track``, the lap time divided by the factor, one
    lap); accelerations are second differences of the simulated states over ``window``
    [s]. The plant is velocity-level (the QP's joint speeds are applied as steps), so
    these accelerations carry the controller's corrections; the arm's start-up approach
    (as it ran: :func:`after_approach`) is left out.
    """
    from mmstab.app import track

    c = problem.section("controller")
    out: dict[str, Any] = {"window_s": window, "after_s": float(c["approach_time"])}
    for k in settings.speeds:
        data = copy.deepcopy(problem.data)
        data["controller"]["lap_time"] = data["controller"]["duration"] = c["lap_time"] / k
        pk = problem_from_dict(data, problem.path, force_size=problem.force_size)
        _, _, run = track(pk, plan, progress=False)
        after = after_approach(run)
        motion = body_motion(pk.robot, pk.terrain, run.state[after, :3], run.state[after, 5:9])
        steps = max(1, int(round(window / run.dt)))
        m = measure_motion(pk.robot, pk.terrain, motion, run.dt, steps, periodic=False)
        out[f"{k:g}x"] = {
            "lap_time_s": c["lap_time"] / k,
            "tipped": run.tipped is not None,
            "mu_dynamic_min": float(m.dynamic.min()),
            "mu_static_min": float(m.static.min()),
            "peak_acceleration_m_s2": m.peak_acceleration,
        }
    return out


#: Window of the second differences along the rough route [s]: the resting pose jumps where
#: the contacts switch (rocking over a crest), and a shorter window turns each jump into an
#: acceleration no robot has.
ROUTE_WINDOW = 0.2


def after_approach(run: Any) -> np.ndarray:
    """The samples (T,) after the arm's start-up approach as it ran.

    The time law may stretch it beyond ``controller.approach_time``: rough.yaml's takes
    1.75 s of the 1.0 s set.
    """
    from mmstab.runs.tracking import transient_end

    return np.arange(len(run.t)) >= transient_end(run)


def route_dynamic(
    rough: Problem, window: float = ROUTE_WINDOW
) -> tuple[dict[str, Any], dict[str, Any]]:
    """Static vs dynamic μ along the rough route, from a closed-loop run at the route's speed.

    The route's own speed profile (slower in turns, from and to rest); accelerations are
    second differences of the simulated states over ``window`` [s] after the start-up
    approach (module text). Arm planned (the problem's search) and the same run's base with
    the arm stowed.
    """
    from mmstab.app import track

    _, _, run = track(rough, progress=False)
    after = after_approach(run)
    steps = max(1, int(round(window / run.dt)))
    out: dict[str, Any] = {
        "window_s": window,
        "after_s": float(run.t[after][0]),
        "duration_s": float(run.t[-1]),
        "tipped": run.tipped is not None,
    }
    curves: dict[str, Any] = {}
    for name, q in (
        ("planned", run.state[after, 5:9]),
        ("stowed", np.broadcast_to(rough.robot.stowed, (int(after.sum()), 4))),
    ):
        motion = body_motion(rough.robot, rough.terrain, run.state[after, :3], q)
        m = measure_motion(rough.robot, rough.terrain, motion, run.dt, steps, periodic=False)
        out[name] = {
            "mu_static_min": float(m.static.min()),
            "mu_dynamic_min": float(m.dynamic.min()),
            "mu_dynamic_mean": float(m.dynamic.mean()),
            "peak_acceleration_m_s2": m.peak_acceleration,
        }
        t = run.t[after][steps:-steps]
        curves[f"route_{name}_t"], curves[f"route_{name}_static"] = t, m.static
        curves[f"route_{name}_dynamic"] = m.dynamic
    return out, curves


def run_dynamic(
    problem: Problem, plan_postures: FloatArray, settings: LeversSettings
) -> tuple[dict[str, Any], dict[str, Any]]:
    """Static vs dynamic μ at the lap speeds; the fastest safe lap (summary, curves)."""
    robot, terrain, circle = problem.robot, problem.terrain, problem.circle
    lap_time = Settings.from_problem(problem).controller.lap_time
    arms = {
        "planned": posture_spline(plan_postures),
        "stowed": lambda s: np.broadcast_to(robot.stowed, (np.size(s), 4)).copy(),
    }
    curves: dict[str, Any] = {}
    out: dict[str, Any] = {"accelerations": "reference motion, periodic central differences"}
    v_limit = robot.base.tracks.sprocket_radius * robot.base.tracks.velocity_limit
    outer = circle.radius + robot.base.tracks.separation / 2
    out["track_speed_limit_lap_time_s"] = 2 * math.pi * outer / v_limit
    for name, posture in arms.items():
        motion = lap_motion(robot, terrain, circle, posture, settings.samples)
        by_speed = {}
        for k in settings.speeds:
            m = lap_measure(robot, terrain, motion, lap_time / k)
            curves[f"{name}_{k:g}x"] = m.dynamic
            by_speed[f"{k:g}x"] = {
                "lap_time_s": lap_time / k,
                "mu_dynamic_min": float(m.dynamic.min()),
                "mu_static_min": float(m.static.min()),
                "peak_acceleration_m_s2": m.peak_acceleration,
                "peak_joint_speed_rad_s": m.peak_joint_speed.tolist(),
            }
        curves[f"{name}_static"] = m.static

        def safe(k: float, motion: LapMotion = motion) -> bool:
            return bool(
                lap_measure(robot, terrain, motion, lap_time / k).dynamic.min() >= settings.margin
            )

        k_max = bisect_largest(safe, 1.0, 64.0, settings.bisection_steps)
        out[name] = {
            "by_speed": by_speed,
            "fastest_safe_speed_factor": k_max,
            "fastest_safe_lap_time_s": lap_time / k_max if k_max == k_max else None,
            "fastest_safe_base_speed_m_s": 2 * math.pi * circle.radius * k_max / lap_time
            if k_max == k_max
            else None,
        }
    curves["fraction"] = np.arange(settings.samples) / settings.samples
    return out, curves


def draw_dynamic(curves: dict[str, Any], settings: LeversSettings, path: Path) -> None:
    """Static vs dynamic μ along the lap, planned arm and stowed arm."""
    fig, axes = new_figure(1, 2, figsize=(10, 3.6), sharey=True)
    s = curves["fraction"]
    for ax, name in zip(axes, ("planned", "stowed"), strict=True):
        ax.plot(s, curves[f"{name}_static"], "k-", lw=2, label="static")
        for k in settings.speeds:
            ax.plot(s, curves[f"{name}_{k:g}x"], label=f"dynamic, {k:g}x lap speed")
        ax.axhline(settings.margin, color="r", ls=":", label="margin")
        ax.set(title=f"arm {name}", xlabel="lap fraction")
    axes[0].set_ylabel("force-angle mu [N rad]")
    axes[1].legend(fontsize=8)
    write_figure(path, fig)


def draw_route_dynamic(curves: dict[str, Any], settings: LeversSettings, path: Path) -> None:
    """Static and dynamic μ along the rough route's run, arm planned and stowed."""
    fig, ax = new_figure(figsize=(9, 4))
    for name, style in (("planned", "-"), ("stowed", "--")):
        t = curves[f"route_{name}_t"]
        ax.plot(t, curves[f"route_{name}_static"], style, color="C0", lw=1, label=f"{name}, static")
        ax.plot(
            t, curves[f"route_{name}_dynamic"], style, color="C3", lw=1, label=f"{name}, dynamic"
        )
    ax.axhline(settings.margin, color="k", lw=0.8, ls=":", label="margin")
    ax.set(xlabel="time [s]", ylabel="mu [N rad]", title="rough route: static vs dynamic mu")
    ax.legend(fontsize=8, ncol=3)
    write_figure(path, fig)
