"""``mmstab simulate`` / ``make physics``: the tracking run in MuJoCo, controller in the loop.

Plans the problem (as ``mmstab track`` does), then runs the closed loop of
:mod:`mmstab.physics.closed_loop` on the whole robot in MuJoCo along the problem's path
(the ramp lap or a route) and, beside it for comparison, the kinematic run of
:mod:`mmstab.runs.tracking`. Writes to the output folder: ``summary.json`` (verdicts:
tipped and its cause, slid, the disagreement with the predicted rest; base and arm-CoM
errors; predicted against simulated μ; QP failures; the real-time factor), ``physics.png``
(:mod:`mmstab.outputs.simulate_figure`: path, tilt, μ and errors over time, the events)
and the settings (``problem.yaml``).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from mmstab.app import generated_step, plan
from mmstab.app.settings import Settings
from mmstab.control.controller import ControllerSettings, build_controller
from mmstab.control.reference import initial_state
from mmstab.core.files import write_json
from mmstab.core.problem import Problem
from mmstab.outputs.common import output_dir, save_settings
from mmstab.outputs.simulate_figure import write_run_figure, write_run_gif
from mmstab.physics.closed_loop import LoopSettings, PhysicsRun, run_closed_loop
from mmstab.physics.governor import GovernorSettings
from mmstab.runs.high_centred import high_centred_verdict, path_samples
from mmstab.runs.plan_verdicts import high_centred_along, path_along
from mmstab.runs.tracking.simulation import settings_for_path
from mmstab.stability.drive import resolve_turn_ratio
from mmstab.stability.support import is_heightmap


def loop_settings(problem: Problem) -> LoopSettings:
    """The problem's ``physics:`` section (defaults filled in)."""
    s = problem.section("physics")
    return LoopSettings(
        control_dt=float(s["control_dt"]),
        duration=None if s["duration"] is None else float(s["duration"]),
        # ``tip_angle``: its former name, still read from older problem files
        disagreement_angle=float(s.get("tip_angle", s["disagreement_angle"])),
        tip_hold=float(s["tip_hold"]),
        slip_distance=float(s["slip_distance"]),
        slip_window=float(s["slip_window"]),
        check_dt=float(s["check_dt"]),
        backend=str(s["backend"]),
        wheel=str(s["wheel"]),
        timestep=float(s["timestep"]),
        arm=str(s["arm"]),
        turn_ratio=s["turn_ratio"] if s["turn_ratio"] == "auto" else float(s["turn_ratio"]),
        governor=None if s["governor"] is None else GovernorSettings(**s["governor"]),
        suspension_travel=suspension_travel(problem),
        pivot_centre=s["pivot_centre"] if s["pivot_centre"] == "auto" else float(s["pivot_centre"]),
    )


def suspension_travel(problem: Problem) -> float:
    """``physics.suspension_travel`` [m]; ``auto``: the support mmstab assumes on this ground.

    On a heightmap the tracks' bottom runs bear load within ``terrain.compliance`` of the
    ground, so MuJoCo's wheels may drop that far below their stops; on a plane the support
    is the rigid track rectangle: stiff wheels (0).
    """
    value = problem.section("physics")["suspension_travel"]
    if value != "auto":
        return float(value)
    if not is_heightmap(problem.terrain):
        return 0.0
    return float(problem.terrain.settings.compliance)  # type: ignore[attr-defined]


def controller_settings(problem: Problem) -> ControllerSettings:
    """The controller's settings; a route sets its own lap time and duration."""
    return settings_for_path(Settings.from_problem(problem).controller, problem.base_path)


def stowed_plan(robot: Any, arm_plan: Any) -> Any:
    """The plan with the arm held stowed at every pose (the planned arm's peer)."""
    k = len(arm_plan.fractions)
    return arm_plan._replace(
        target_com=np.tile(robot.arm_com(robot.stowed), (k, 1)),
        postures=np.tile(robot.stowed, (k, 1)),
        moves=(),
    )


def simulate_run(problem: Problem, loop: LoopSettings, arm_plan: Any = None) -> PhysicsRun:
    """The closed loop of ``mmstab simulate`` with the settings ``loop``.

    Args:
        problem: the problem.
        loop: the loop's settings (:func:`loop_settings`, maybe changed).
        arm_plan: the problem's plan (:func:`mmstab.app.plan`); None: planned here.
    """
    arm_plan = plan(problem) if arm_plan is None else arm_plan
    problem = problem.following(arm_plan)  # a route plan's slowed turns (runs.time_law)
    cs = controller_settings(problem)
    if loop.backend == "generated":
        step = generated_step(problem).function
        cs = dataclasses.replace(cs, plugin=Settings.from_problem(problem).codegen.plugin)
    else:
        step = build_controller(problem.robot, cs).step
    if loop.arm == "stowed":
        arm_plan = stowed_plan(problem.robot, arm_plan)
    state0 = initial_state(problem.base_path, problem.robot.stowed)
    return run_closed_loop(problem, arm_plan, step, cs, loop, state0)


def run_simulate(
    problem: Problem,
    out: str | Path | None = None,
    duration: float | None = None,
    arm: str | None = None,
    gif: bool = False,
) -> dict[str, Any]:
    """Plan, run the closed loop in MuJoCo, write the summary and figure (module text).

    Args:
        problem: the problem (its ``physics:`` section).
        out: output folder.
        duration: simulated time [s]; None: the section's.
        arm: ``planned`` or ``stowed`` (the arm held stowed along the path); None: the
            section's.
        gif: also write ``physics.gif``, a replay of the run in MuJoCo's attitudes.
    """
    loop = loop_settings(problem)
    if duration is not None:
        loop = dataclasses.replace(loop, duration=float(duration))
    if arm is not None:
        loop = dataclasses.replace(loop, arm=arm)
    arm_plan = plan(problem)
    problem = problem.following(arm_plan)  # the route timed with its slowed turns
    run = simulate_run(problem, loop, arm_plan)
    d = output_dir(out, "physics")
    summary = summarize(run, loop)
    summary["backend"], summary["arm"] = loop.backend, loop.arm
    summary["model"] = {"wheel": loop.wheel, "timestep_s": loop.timestep}
    summary["drive"] = {"turn_ratio": resolve_turn_ratio(problem.robot, loop.turn_ratio),
                        "setting": loop.turn_ratio}  # fmt: skip
    if loop.arm == "planned":  # the plan's own record: the path rested with the planned arm
        along = path_along(problem.robot, problem.terrain, problem.base_path, arm_plan)
        summary["high_centred"] = high_centred_along(along)
    else:
        summary["high_centred"] = high_centred_verdict(
            problem.terrain, *path_samples(problem.base_path)
        )
    place_events(summary, run, problem.base_path)
    write_run_figure(d / "physics.png", problem, run, loop)
    if gif:
        info = write_run_gif(d / "physics.gif", problem, run)
        summary["replay"] = {"path": "physics.gif", "frames": info.frames}
    save_settings(d, problem, physics=dataclasses.asdict(loop))
    write_json(d / "summary.json", summary)
    return summary


def summarize(run: PhysicsRun, loop: LoopSettings) -> dict[str, Any]:
    """The run's numbers: verdicts, errors, μ predicted against simulated, speed."""
    both = np.isfinite(run.mu_simulated) & np.isfinite(run.mu_predicted)
    arm = np.zeros(0) if run.arm_ground is None else run.arm_ground
    checked, touching = np.isfinite(arm), np.flatnonzero(arm == 1)
    diff = run.mu_simulated[both] - run.mu_predicted[both]
    return {
        "duration_s": float(run.t[-1]),
        "control_dt_s": float(run.t[1] - run.t[0]) if len(run.t) > 1 else None,
        "tipped": None if run.tipped is None else {"time_s": run.tipped, "cause": run.tip_cause},
        "tip_hold_s": loop.tip_hold,
        "disagreement": None
        if run.disagreement is None
        else {"time_s": run.disagreement, "tilt_off_rest_max_rad": _nanmax(run.tilt_error)},
        "disagreement_angle_rad": loop.disagreement_angle,
        "slid": None if run.slid is None else {"time_s": run.slid},
        "left_map": None if run.left_map is None else {"time_s": run.left_map},
        "tilt_off_rest_max_rad": _nanmax(run.tilt_error),
        "slip_distance_m": loop.slip_distance,
        "slip_window_s": loop.slip_window,
        "downhill_drift_max_m": float(np.max(run.slip)),
        "base_error_max_m": float(run.base_error.max()),
        "base_error_final_m": float(run.base_error[-1]),
        "base_origin_error_max_m": None
        if run.base_origin_error is None
        else float(run.base_origin_error.max()),
        "arm_com_error_max_m": float(run.arm_com_error.max()),
        "arm_com_error_final_m": float(run.arm_com_error[-1]),
        "qp_failures": int(np.sum(run.status != 0)),
        **_where_no_slip(run, loop),
        "arm_ground_contact": None
        if len(touching) == 0
        else {
            "first_time_s": float(run.t[touching[0]]),
            "fraction_of_checks": float(len(touching) / checked.sum()),
            # the body's attitude then, off mmstab's predicted rest [rad] (NaN: off the map)
            "tilt_off_rest_rad": _nanmax(run.tilt_error[touching[:1]]),
        },
        "mu_predicted_min": float(np.min(run.mu_predicted)),
        "mu_simulated_min": float(np.nanmin(run.mu_simulated)),
        "mu_difference": {
            "median_abs": float(np.median(np.abs(diff))),
            "median_relative": float(np.median(np.abs(diff) / np.abs(run.mu_predicted[both]))),
            "max_abs": float(np.max(np.abs(diff))),
            "samples": int(both.sum()),
        },
        "real_time_factor": run.real_time_factor,
        "wall_seconds": run.wall_seconds,
        "real_time_factor_cpu": float(run.t[-1] / run.cpu_seconds) if run.cpu_seconds else None,
        "arm_timing": run.timing,
        "reference_wait_s": run.reference_wait_s,
        "approach": {"base_wait_s": run.base_wait_s},  # as ``mmstab track``'s summary
        "stalled": None if run.stalled is None else {"time_s": run.stalled, **(run.stall or {})},
    }


def place_events(summary: dict[str, Any], run: PhysicsRun, path: Any) -> None:
    """Add where each event of ``summary`` happened (in place).

    The body origin ``xy_m`` (x, y) in M [m] at the event's time (``time_s``; the arm's
    first ground contact's ``first_time_s``) and, on a route, ``s_m``: the distance along
    it of the path's nearest point [m], as the plan's verdicts name places.
    """
    u = np.linspace(0.0, 1.0, 4001)
    on_route = hasattr(path, "s_at")
    xy_path = np.asarray(path.pose_at(u))[:, :2] if on_route else None
    for key in ("tipped", "slid", "left_map", "stalled", "disagreement", "arm_ground_contact"):
        event = summary.get(key)
        if event is None:
            continue
        when = event["time_s"] if "time_s" in event else event["first_time_s"]
        k = min(int(np.searchsorted(run.t, when)), len(run.t) - 1)
        xy = run.state[k, :2]
        event["xy_m"] = [float(xy[0]), float(xy[1])]
        if xy_path is not None:
            j = int(np.argmin(np.linalg.norm(xy_path - xy, axis=1)))
            event["s_m"] = float(np.asarray(path.s_at(u[j : j + 1]))[0])


def _nanmax(values: np.ndarray) -> float | None:
    """The largest finite value, None when there is none."""
    ok = np.isfinite(values)
    return float(np.max(values[ok])) if ok.any() else None


def _where_no_slip(run: PhysicsRun, loop: LoopSettings) -> dict[str, Any]:
    """The base error away from mmstab's predicted slip.

    Where none of the simulated poses of the last ``slip_window`` is flagged by mmstab's
    slip check (the issue's bar: the routes track where mmstab predicts no slide): the
    friction cone at the simulated pose (:mod:`mmstab.stability.slip`) or the reference
    path's slide (its turns, :mod:`mmstab.stability.skid`, or its pose beyond the cone); the
    cone at the simulated pose alone beside it.
    """
    n = len(run.t)
    none = np.zeros(n, bool)
    braked = none if run.slip_predicted is None else np.asarray(run.slip_predicted, bool)
    path = none if run.path_slip_predicted is None else np.asarray(run.path_slip_predicted, bool)
    dt = run.t[1] - run.t[0] if n > 1 else loop.control_dt
    window = max(int(round(loop.slip_window / dt)), 1)

    def clear(flags: np.ndarray) -> np.ndarray:
        return ~(np.convolve(flags.astype(float), np.ones(window))[:n] > 0)

    def worst(mask: np.ndarray, error: np.ndarray | None = None) -> float | None:
        error = run.base_error if error is None else error
        return float(error[mask].max()) if mask.any() else None

    both, cone = clear(braked | path), clear(braked)
    origin = run.base_origin_error
    return {
        "slip_predicted_fraction": float(braked.mean()),
        "path_slip_predicted_fraction": float(path.mean()),
        "base_error_max_where_no_slip_predicted_m": worst(both),
        "base_origin_error_max_where_no_slip_predicted_m": None
        if origin is None
        else worst(both, origin),
        "no_slip_predicted_fraction": float(both.mean()),
        "base_error_max_where_cone_holds_m": worst(cone),
    }
