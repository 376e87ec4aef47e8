"""make levers: payload, flippers, speed and robot variants as stability levers.

Four experiments on the problem's ramp (``docs/levers.md``), settings in its ``levers:``
section, every number in ``results/levers/summary.json``:

- **dynamic**: static vs dynamic force-angle μ along the lap at several lap speeds, the
  planned arm and the stowed arm; the fastest safe lap (bisection on the lap speed). The
  accelerations are those of the *reference motion*, differentiated numerically: the base
  drives the circle at constant speed, the arm follows a periodic cubic spline through the
  planned postures, every body's CoM is placed in M and differentiated twice in time
  (periodic central differences). Bodies are point masses (the description has no inertia
  tensors), so the inertial moments about their own CoMs are zero. A cross-check runs the
  closed loop (``app.track``) at each speed and measures the simulated states' second
  differences over ``SIM_WINDOW`` (:func:`simulated_check`).
- **payload**: the heaviest payload held at the front, left and right on a side slope,
  arm planned (the best collision-free grid posture of V with the turret pointing there and
  the tool held out ``payload_reach`` beyond the tracks' footprint on that side), stowed
  (links 1-3 folded, turret pointing away: the folded arm holds the load over the base on
  that side, :func:`stowed_holding`) and fixed (the
  arm stretched level, turret pointing there); bisection on the mass.
- **variants**: per robot file, the planned and stowed μ along the lap (CMA-ES, V on
  ``levers.variant_grid``), optionally along the circle of a rough-ground problem
  (``levers.rough_problem``: the planner on the heightmap, μ then measured on the resting
  contacts), and the steepest side slope with μ >= margin, arm planned (the best of V's
  samples, both sides downhill) and stowed; bisection on the slope.
- **flippers**: μ along the lap, arm only vs arm + flippers
  (:func:`mmstab.planner.levers.solve_path_flippers`), on the problem's ramp and on the
  side slope's ramp; both with the exhaustive Eq. 6 search (no sampling noise between them).
"""

from __future__ import annotations

import copy
import functools
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import CubicSpline

from mmstab.core.files import ConfigError, write_figure, write_json, write_text
from mmstab.core.problem import Problem, load_problem, problem_from_dict
from mmstab.experiments.common import output_dir, save_settings
from mmstab.model.payload import Payload, attach_payload
from mmstab.model.robot import FloatArray, Robot
from mmstab.paths.circle import CirclePath
from mmstab.planner import PlannerSettings, best_mu, solve_path
from mmstab.planner.levers import solve_path_flippers
from mmstab.planner.wrench import tool_points
from mmstab.stability.dynamic import dynamic_force_angle, net_wrench
from mmstab.stability.static import base_polygon, contact_force_angle, robot_force_angle
from mmstab.terrain import GRAVITY_G, Terrain, from_section
from mmstab.viz.plotting import new_figure

#: Window of the second differences of simulated states [s] (module text).
SIM_WINDOW = 0.02
#: Directions the payload is held in: turret angle [rad] (0 = forward, positive = left).
DIRECTIONS = {"front": 0.0, "left": math.pi / 2, "right": -math.pi / 2}


class LeversSettings(NamedTuple):
    """The ``levers:`` section (see ``problems/levers.yaml``)."""

    margin: float  # [N rad]
    speeds: tuple[float, ...]  # lap-speed factors
    samples: int  # per lap
    side_slope: float  # [rad]
    max_payload: float  # [kg]
    payload_com: FloatArray  # in the wrist frame (3,) [m]
    payload_reach: float  # [m] beyond the tracks' edge
    bisection_steps: int
    max_slope: float  # [rad]
    robots: tuple[str, ...]
    variant_grid: tuple[int, int, int, int]
    flipper_angles: int
    rough_problem: str | None  # a problem file whose terrain and circle are the rough lap


def levers_settings(problem: Problem) -> LeversSettings:
    """The problem's ``levers:`` section.

    Raises:
        ConfigError: the section is missing.
    """
    if "levers" not in problem.data:
        raise ConfigError(problem.path, "levers", "missing section: make levers needs it")
    s = problem.section("levers")
    rough = s.get("rough_problem")
    if rough is not None and not (problem.path.parent / rough).is_file():
        raise ConfigError(problem.path, "levers.rough_problem", f"no problem file {rough}")
    return LeversSettings(
        margin=float(s["margin"]),
        speeds=tuple(float(v) for v in s["speeds"]),
        samples=int(s["samples"]),
        side_slope=float(s["side_slope"]),
        max_payload=float(s["max_payload"]),
        payload_com=np.asarray(s["payload_com"], dtype=float),
        payload_reach=float(s["payload_reach"]),
        bisection_steps=int(s["bisection_steps"]),
        max_slope=float(s["max_slope"]),
        robots=tuple(s["robots"]),
        variant_grid=tuple(int(n) for n in s["variant_grid"]),  # type: ignore[arg-type]
        flipper_angles=int(s["flipper_angles"]),
        rough_problem=rough,
    )


def planar_slope(problem: Problem, slope: float) -> Terrain:
    """A planar slope of ``slope`` [rad] (the terrain factory's ``{slope}`` form)."""
    return from_section(problem.path, {"slope": float(slope)}, problem.robot)


def bisect_largest(ok: Callable[[float], bool], lo: float, hi: float, steps: int) -> float:
    """Largest x in [lo, hi] with ``ok(x)``, assuming ok holds below a threshold.

    Returns ``lo - 0`` = ``lo`` when ``ok(lo)`` fails is signalled by NaN; ``hi`` when
    ``ok(hi)`` holds (the bracket's end: a lower bound).
    """
    if not ok(lo):
        return math.nan
    if ok(hi):
        return hi
    for _ in range(steps):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if ok(mid) else (lo, mid)
    return lo


# -------------------------------------------------------------------------------- dynamics
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
    com_b, f_b, n_b, f_s = (np.empty((n, 3)) for _ in range(4))
    for j, i in enumerate(keep):
        R, t = motion.M_T_B[i, :3, :3], motion.M_T_B[i, :3, 3]
        w = net_wrench(motion.masses, p[i], acc[j], g_M)
        com_b[j], f_b[j], n_b[j] = R.T @ (w.com - t), R.T @ w.force, R.T @ w.moment
        f_s[j] = R.T @ (motion.masses.sum() * g_M)
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
    (``controller.approach_time``) is left out.
    """
    from mmstab.app import track

    c = problem.section("controller")
    out: dict[str, Any] = {"window_s": window, "after_s": float(c["approach_time"])}
    for k in settings.speeds:
        data = copy.deepcopy(problem.data)
        data["controller"]["lap_time"] = data["controller"]["duration"] = c["lap_time"] / k
        pk = problem_from_dict(data, problem.path, force_size=problem.force_size)
        _, _, run = track(pk, plan, progress=False)
        after = run.t >= float(c["approach_time"])
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

    c = rough.section("controller")
    _, _, run = track(rough, progress=False)
    after = run.t >= float(c["approach_time"])
    steps = max(1, int(round(window / run.dt)))
    out: dict[str, Any] = {
        "window_s": window,
        "after_s": float(c["approach_time"]),
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
    lap_time = float(problem.section("controller")["lap_time"])
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


# --------------------------------------------------------------------------------- payload
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


# -------------------------------------------------------------------------------- variants
def variant_problem(problem: Problem, robot_file: str, grid: tuple[int, ...]) -> Problem:
    """The problem with another robot file (relative to the problem) and workspace grid."""
    data = copy.deepcopy(problem.data)
    data["robot"] = robot_file
    data["workspace"]["grid"] = list(grid)
    return problem_from_dict(data, problem.path, force_size=problem.force_size)


def steepest_side_slope(
    problem: Problem, mu_of: Callable[[Robot, FloatArray], float], settings: LeversSettings
) -> float | None:
    """Steepest ramp [deg] across which (either side downhill) ``mu_of`` >= the margin."""

    def ok(slope: float) -> bool:
        ground = planar_slope(problem, slope)
        g = ground.gravity_body(np.array([[0.0, 0.0, 0.0], [0.0, 0.0, math.pi]]))
        return min(mu_of(problem.robot, g[0]), mu_of(problem.robot, g[1])) >= settings.margin

    found = bisect_largest(ok, 0.0, settings.max_slope, settings.bisection_steps)
    return None if found != found else math.degrees(found)


def contact_mu(
    robot: Robot, terrain: Terrain, poses: FloatArray, arm_com_body: ArrayLike
) -> FloatArray:
    """μ [N rad] (N,) on the bearing contacts (``Terrain.support``) at poses (N, 3) in M.

    The 3-D contacts that carry the base at rest (its stowed-arm rest pose: the touching
    ones and the tracks' bottom run within the compliance), not the planner's track
    rectangle: on uneven ground the polygon is what the robot stands on (``mmstab rest``).
    """
    coms = np.broadcast_to(np.asarray(arm_com_body, dtype=float), (len(poses), 3))
    out = np.empty(len(poses))
    for i, pose in enumerate(poses):
        stand = terrain.support(robot, pose)
        T = stand.G_T_B
        com_G = T[:3, :3] @ robot.overall_com(coms[i]) + T[:3, 3]
        out[i] = contact_force_angle(stand.bearing(), com_G, robot.total_mass * GRAVITY_G).mu
    return out


def _best_mu_of(robot: Robot, gravity_body: FloatArray, samples: FloatArray) -> float:
    """The best μ over arm-CoM samples (N, 3) [m] at gravity ``gravity_body`` [m/s^2]."""
    return best_mu(robot, gravity_body, samples)[0]


def run_variants(problem: Problem, settings: LeversSettings) -> dict[str, Any]:
    """Each robot file on the problem's lap and on side slopes (module text)."""
    from mmstab.workspace import load_or_build_workspace

    psettings = PlannerSettings.from_section(problem.section("planner"))
    out: dict[str, Any] = {"workspace_grid": list(settings.variant_grid), "robots": {}}
    for robot_file in settings.robots:
        t0 = time.perf_counter()
        vp = variant_problem(problem, robot_file, settings.variant_grid)
        ws = load_or_build_workspace(vp, progress=False)
        robot = vp.robot
        poses = vp.circle.poses(psettings.poses)
        plan = solve_path(robot, vp.terrain, ws, poses, psettings)
        gravity = vp.terrain.gravity_body(poses)
        stowed = robot_force_angle(robot, gravity, robot.arm_com(robot.stowed)).mu
        planned = np.array([t.mu for t in plan.targets])
        samples = ws.valid_com_in_V
        rough: dict[str, Any] = {}
        if settings.rough_problem is not None:
            rp = load_problem(problem.path.parent / settings.rough_problem)
            ground = from_section(rp.path, rp.section("terrain"), robot)
            rough_poses = rp.base_path.poses(psettings.poses)
            rough_plan = solve_path(robot, ground, ws, rough_poses, psettings)
            planned_c = contact_mu(robot, ground, rough_poses, rough_plan.target_com)
            stowed_c = contact_mu(robot, ground, rough_poses, robot.arm_com(robot.stowed))
            own = np.array([t.mu for t in rough_plan.targets])
            rough = {
                "rough_mu_planner_own_min": float(own.min()),  # on the track rectangle
                "rough_poses_tipping_on_contacts": int(np.sum(planned_c < 0)),
                "rough_mu_planned_min": float(planned_c.min()),
                "rough_mu_planned_mean": float(planned_c.mean()),
                "rough_mu_stowed_min": float(stowed_c.min()),
                "rough_mu_stowed_mean": float(stowed_c.mean()),
            }
        out["robots"][robot.name] = {
            "file": robot_file,
            "arm_mass_kg": robot.arm_mass,
            "lap_mu_planned_min": float(planned.min()),
            "lap_mu_planned_mean": float(planned.mean()),
            "lap_mu_stowed_min": float(stowed.min()),
            "lap_mu_stowed_mean": float(stowed.mean()),
            "steepest_side_slope_planned_deg": steepest_side_slope(
                vp, functools.partial(_best_mu_of, samples=samples), settings
            ),
            "steepest_side_slope_stowed_deg": steepest_side_slope(
                vp,
                lambda r, g: float(robot_force_angle(r, g, r.arm_com(r.stowed)).mu[0]),
                settings,
            ),
            **rough,
            "seconds": time.perf_counter() - t0,
        }
    if settings.rough_problem is not None:
        out["rough_problem"] = settings.rough_problem
    return out


def draw_variants(summary: dict[str, Any], path: Path) -> None:
    """Lap μ (planned, stowed) and the steepest side slope per robot variant."""
    names = list(summary["robots"])
    rows = [summary["robots"][n] for n in names]
    fig, (ax0, ax1) = new_figure(1, 2, figsize=(10, 3.6))
    x = np.arange(len(names))
    keys = [("lap_mu_planned_min", "ramp, planned"), ("lap_mu_stowed_min", "ramp, stowed")]
    if "rough_problem" in summary:
        keys += [
            ("rough_mu_planned_min", "rough, planned (on the contacts)"),
            ("rough_mu_stowed_min", "rough, stowed (on the contacts)"),
        ]
    w = 0.8 / len(keys)
    for j, (key, label) in enumerate(keys):
        bars = ax0.bar(x + (j - (len(keys) - 1) / 2) * w, [r[key] for r in rows], w, label=label)
        ax0.bar_label(bars, fmt="%.0f", fontsize=6)
    ax0.set_xticks(x, names, fontsize=8)
    ax0.set(ylabel="lowest mu along the lap [N rad]", title="laps: ramp (and rough ground)")
    low, high = ax0.get_ylim()
    ax0.set_ylim(low, high + 0.45 * (high - low))  # room for the legend above the bars
    ax0.legend(fontsize=7, loc="upper center", ncols=2)
    for j, (key, label) in enumerate(
        (
            ("steepest_side_slope_planned_deg", "arm planned"),
            ("steepest_side_slope_stowed_deg", "arm stowed"),
        )
    ):
        bars = ax1.bar(x + (j - 0.5) * 0.38, [r[key] or 0.0 for r in rows], 0.38, label=label)
        ax1.bar_label(bars, fmt="%.1f", fontsize=7)
    ax1.set_xticks(x, names, fontsize=8)
    ax1.set(ylabel="steepest side slope [deg]", title="side slope, mu >= margin")
    ax1.legend(fontsize=8, loc="lower right")
    write_figure(path, fig)


def variants_table(summary: dict[str, Any]) -> str:
    """The variants as a Markdown table."""
    rough = "rough_problem" in summary
    lines = [
        "| robot | arm mass [kg] | ramp lap μ planned min / mean [N rad] | ramp lap μ stowed "
        "min / mean [N rad] | "
        + ("rough lap μ planned / stowed, min [N rad] | " if rough else "")
        + "steepest side slope, planned / stowed [deg] |",
        "|---|---|---|---|---|" + ("---|" if rough else ""),
    ]
    for name, r in summary["robots"].items():
        slope = [r["steepest_side_slope_planned_deg"], r["steepest_side_slope_stowed_deg"]]
        lines.append(
            f"| {name} | {r['arm_mass_kg']:.1f} | {r['lap_mu_planned_min']:.1f} / "
            f"{r['lap_mu_planned_mean']:.1f} | {r['lap_mu_stowed_min']:.1f} / "
            f"{r['lap_mu_stowed_mean']:.1f} | "
            + (
                f"{r['rough_mu_planned_min']:.1f} / {r['rough_mu_stowed_min']:.1f} | "
                if rough
                else ""
            )
            + " / ".join("-" if v is None else f"{v:.1f}" for v in slope)
            + " |"
        )
    return "\n".join(lines) + "\n"


# -------------------------------------------------------------------------------- flippers
def run_flippers(
    problem: Problem, ws: Any, settings: LeversSettings
) -> tuple[dict[str, Any], dict[str, Any]]:
    """μ along the lap, arm only vs arm + flippers, on the problem's ramp and the side slope."""
    robot = problem.robot
    # the exhaustive search on both sides: no sampling noise between the two plans
    psettings = PlannerSettings.from_section(problem.section("planner"))._replace(
        method="exhaustive"
    )
    loaded_settings = psettings._replace(flipper_angles=settings.flipper_angles)
    poses = problem.circle.poses(psettings.poses)
    dt = float(problem.section("controller")["lap_time"]) / psettings.poses
    grounds: dict[str, Terrain] = {
        "ramp": problem.terrain,
        "side_slope": planar_slope(problem, settings.side_slope),
    }
    out: dict[str, Any] = {"flipper_angles_per_pose": settings.flipper_angles}
    curves: dict[str, Any] = {"fraction": np.arange(psettings.poses) / psettings.poses}
    paths = {name: (poses, dt) for name in grounds}
    rp = (
        None
        if settings.rough_problem is None
        else load_problem(problem.path.parent / settings.rough_problem)
    )
    route = None if rp is None else rp.route
    if rp is not None and route is not None:  # the rough route's poses, its driving time
        grounds["rough_route"] = from_section(rp.path, rp.section("terrain"), robot)
        paths["rough_route"] = (route.poses(psettings.poses), route.duration / psettings.poses)
    for name, terrain in grounds.items():
        poses, dt = paths[name]
        arm_only = np.array(
            [t.mu for t in solve_path(robot, terrain, ws, poses, psettings).targets]
        )
        both = solve_path_flippers(robot, terrain, ws, poses, loaded_settings, dt)
        curves[f"{name}_arm"], curves[f"{name}_flippers"] = arm_only, both.mu
        curves[f"{name}_angles"] = both.flipper_angles
        out[name] = {
            "terrain": terrain.label,
            "mu_arm_only_min": float(arm_only.min()),
            "mu_arm_only_mean": float(arm_only.mean()),
            "mu_arm_flippers_min": float(both.mu.min()),
            "mu_arm_flippers_mean": float(both.mu.mean()),
            "flipper_angles_rad": both.flipper_angles.tolist(),
        }
    return out, curves


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


def draw_flippers(
    curves: dict[str, Any], summary: dict[str, Any], limits: tuple[float, float], path: Path
) -> None:
    """μ along the lap, arm only vs arm + flippers, and the flipper angle (within ``limits``)."""
    names = [n for n in ("ramp", "side_slope", "rough_route") if n in summary]
    fig, axes = new_figure(2, len(names), figsize=(5 * len(names), 5.4), sharex=True)
    s = curves["fraction"]
    for j, name in enumerate(names):
        ax, ax_a = axes[0, j], axes[1, j]
        ax.plot(s, curves[f"{name}_arm"], "o-", label="arm only (flippers fixed)")
        ax.plot(s, curves[f"{name}_flippers"], "s-", label="arm + flippers")
        ax.set(title=summary[name]["terrain"], ylabel="mu [N rad]")
        ax_a.step(s, curves[f"{name}_angles"], where="post")
        ax_a.set(xlabel="path fraction", ylabel="flipper angle [rad]", ylim=limits)
    axes[0, 0].legend(fontsize=8)
    write_figure(path, fig)


# ------------------------------------------------------------------------------------- all
def run_levers(problem: Problem, out: str | Path | None = None) -> dict[str, Any]:
    """Every levers experiment; figures, ``variants.md`` and ``summary.json`` in ``out``."""
    from mmstab.app import plan as plan_of
    from mmstab.app import workspace

    settings = levers_settings(problem)
    d = output_dir(out, "levers")
    t0 = time.perf_counter()
    ws = workspace(problem)
    plan = plan_of(problem, ws=ws)
    summary: dict[str, Any] = {"problem": str(problem.path), "margin_N_rad": settings.margin}
    dyn, dyn_curves = run_dynamic(problem, plan.postures, settings)
    dyn["simulated_planned"] = simulated_check(problem, plan, settings)
    if settings.rough_problem is not None:
        rough = load_problem(problem.path.parent / settings.rough_problem)
        if rough.route is not None:
            dyn["rough_route"], route_curves = route_dynamic(rough)
            draw_route_dynamic(route_curves, settings, d / "dynamic_route.png")
    summary["dynamic"] = dyn
    draw_dynamic(dyn_curves, settings, d / "dynamic.png")
    summary["payload"] = run_payload(problem, ws.valid_q, settings)
    draw_payload(summary["payload"], d / "payload.png")
    summary["variants"] = run_variants(problem, settings)
    draw_variants(summary["variants"], d / "variants.png")
    write_text(d / "variants.md", variants_table(summary["variants"]))
    flip, flip_curves = run_flippers(problem, ws, settings)
    summary["flippers"] = flip
    lim = problem.robot.base.flippers.limits
    span = (lim.lower, lim.upper) if lim is not None else (-math.pi / 2, math.pi / 2)
    draw_flippers(flip_curves, flip, span, d / "flippers.png")
    summary["seconds"] = time.perf_counter() - t0
    save_settings(d, problem)
    write_json(d / "summary.json", summary)
    return summary
