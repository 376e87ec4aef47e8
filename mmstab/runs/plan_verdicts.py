"""A plan's verdicts, one per limit: what ``mmstab plan`` reports and exits on.

:func:`route_verdicts` (a route) and :func:`lap_verdicts` (a circle's lap) check the same
way: at the planned poses and every few cm between them (:mod:`mmstab.runs.along`), the
arm in the postures it moves between and on its moves, priced at the path's time law (a
route's speed profile; a lap's one speed, from rest at its start). They give the same
records: ``stability`` (tip), ``slip`` (slide), ``climb`` (step), ``high_centred`` and ``verdicts``
(:func:`mmstab.runs.along.limit_verdicts`: tip, slide, step, high_centred, arm_contact).
:func:`exit_status` is ``mmstab plan``'s exit status for them (``docs/cli.md``): 3 where a
pose tips or falls below the margin, 4 where the tracks slide, 5 where the arm touches the
robot (at a planned posture, or between two on a plan whose moves the search did not check:
:func:`arm_path_check`) or, on its posture reference at a dense sample's rest, the ground
(:func:`mmstab.runs.arm_ground.arm_in_ground_record`), else 0.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from mmstab.core.masks import true_runs
from mmstab.paths.route import ROUTE_DEFAULTS, RoutePath
from mmstab.runs.along import (
    Along,
    ConeTiming,
    LapStage,
    acceleration_margin,
    along_path,
    bracket,
    dense_verdicts,
    lap_stage,
    limit_verdicts,
    path_timing,
    rock_samples,
    sample_spacing,
)
from mmstab.runs.arm_ground import arm_in_ground_record
from mmstab.runs.climb_out import climb_out_verdict, reference_arm_coms
from mmstab.runs.high_centred import path_samples
from mmstab.runs.verdict import (
    climb_verdict,
    plan_verdict,
    robot_turn_check,
    slip_verdict,
    turn_slip,
)
from mmstab.runs.verdict_settings import VerdictSettings
from mmstab.stability.support import loaded_mu

if TYPE_CHECKING:
    from mmstab.model.robot import Robot
    from mmstab.paths.circle import CirclePath
    from mmstab.planner import Plan, RoutePlan
    from mmstab.terrain.base import Terrain

#: ``mmstab plan``'s exit status where a pose tips or is below the margin, where the tracks
#: slide, where the arm touches the robot (:mod:`mmstab.cli.status`' ``EXIT_UNSTABLE``,
#: ``EXIT_SLIDES``, ``EXIT_ARM_COLLISION``).
EXIT_UNSTABLE, EXIT_SLIDES, EXIT_ARM_COLLISION = 3, 4, 5


def arm_path_check(robot: Robot, plan: Any, lap_time: float, dt: float) -> dict[str, Any] | None:
    """Where the arm's path between the planned postures touches the robot, as tracked.

    A search that checks its moves (``roadmap``; ``sequence``, whose straight moves keep the
    roadmap's clearance and are followed where the spline does not) needs no check: None.
    A pose-by-pose search (``cmaes``, ``exhaustive``) checks its postures only: the arm's
    posture reference between them (:func:`mmstab.control.posture.build_posture_reference`,
    repaired with via postures, at every control period, as ``mmstab track`` builds it) is
    checked here, so that ``plan`` and ``track`` give one answer on arm contact.

    Args:
        robot: the robot.
        plan: the plan (``fractions``, ``target_com``, ``postures``, ``settings``).
        lap_time: the path's time [s] (``controller.lap_time``).
        dt: the control period [s] (``controller.dt``).

    Returns:
        The reference's report (:meth:`~mmstab.control.posture.PostureReference.summary`:
        ``reference`` with ``colliding_samples``, ``intervals_fraction`` and ``pairs``,
        the ``via_postures``), or None.
    """
    from mmstab.control.posture import (
        build_posture_reference,
        posture_samples,
        straight_moves_checked,
    )

    if getattr(plan, "moves", ()) or straight_moves_checked(plan):
        return None
    reference = build_posture_reference(robot, plan, posture_samples(lap_time, dt))
    return reference.summary(lap_time)


def lap_acceleration(lap: CirclePath, lap_time: float) -> float:
    """The lap's largest acceleration [m/s^2].

    Its centripetal one at its one speed, at least the route defaults' (the start from
    rest, where the controller sets the rate).
    """
    speed = lap.length / lap_time
    return max(speed**2 / lap.radius, *ROUTE_DEFAULTS.values())


def plan_along(robot: Robot, terrain: Terrain, route: RoutePath, plan: RoutePlan) -> Along:
    """The route rested every few cm with the planned arm (:func:`mmstab.runs.along.along_path`).

    At each sample the arm is in the two planned postures it moves between and where its
    posture reference has it (:func:`mmstab.runs.climb_out.reference_arm_coms`): a move
    that swings the arm's CoM beyond both postures is what ``mmstab track`` drives through.
    """
    from mmstab.planner.along_route import planned_com

    poses, s = path_samples(route, sample_spacing(terrain))
    planned = planned_com(robot, plan.postures, plan.target_com)
    moving = reference_arm_coms(robot, plan, route, s)
    return along_path(robot, terrain, poses, s, plan.s, planned, moving)


def lap_along(robot: Robot, terrain: Terrain, lap: CirclePath, stage: LapStage) -> Along:
    """The lap rested every few cm with the planned arm (:func:`plan_along`'s, closed).

    Past the last planned pose the arm moves into the first pose's posture: the lap closes.
    """
    from mmstab.planner.along_route import planned_com

    poses, s = path_samples(lap, sample_spacing(terrain))
    planned = planned_com(robot, stage.postures, stage.target_com)
    moving = reference_arm_coms(robot, stage, lap, s)
    return along_path(robot, terrain, poses, s, stage.s, planned, moving, closed=True)


def path_along(robot: Robot, terrain: Terrain, path: Any, plan: Any) -> Along:
    """:func:`plan_along` of a route's plan, :func:`lap_along` of a circle's."""
    if path.closed:
        return lap_along(robot, terrain, path, lap_stage(plan, path))
    return plan_along(robot, terrain, path, plan)


def high_centred_along(along: Along) -> dict[str, Any]:
    """``summary.json``'s ``high_centred``: where the dense samples' chassis rests on the ground.

    Returns:
        ``high_centred`` (any sample is), ``samples``, ``spacing_m`` and ``stretches`` (arc
        lengths [m]), with the planned arm (:func:`mmstab.runs.along.along_path`).
    """
    s = along.s
    return {
        "high_centred": bool(along.high_centred.any()),
        "samples": int(len(s)),
        "spacing_m": float(np.median(np.diff(s))) if len(s) > 1 else 0.0,
        "criterion": "the chassis does not rest on the ground along the path (planned arm)",
        "stretches": [{"start_s": float(s[a]), "end_s": float(s[b - 1])}
                      for a, b in true_runs(along.high_centred)],
    }  # fmt: skip


def route_acceleration(route: RoutePath) -> float:
    """The larger of the route's acceleration limits [m/s^2] (the file's, else the defaults)."""
    limits = route.limits
    if limits is None:
        return max(ROUTE_DEFAULTS["acceleration"], ROUTE_DEFAULTS["lateral_acceleration"])
    return max(limits.acceleration, limits.lateral_acceleration)


def route_verdicts(
    robot: Robot,
    terrain: Terrain,
    route: RoutePath,
    plan: RoutePlan,
    settings: VerdictSettings,
    along: Along | None = None,
    arm_path: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The verdicts of a route plan (``summary.json``'s records of ``mmstab plan``).

    Args:
        robot: the robot.
        terrain: the ground.
        route: the route planned.
        plan: its plan.
        settings: the margin and the slide's limits.
        along: :func:`plan_along`'s samples, if already made.
        arm_path: :func:`arm_path_check`'s report (None: the moves were checked).

    Returns:
        ``mu_realised`` (K,) [N rad] (the realised postures' μ, one loaded batch),
        ``stability`` (with ``climb_out``: :func:`mmstab.runs.climb_out.climb_out_verdict`;
        unstable where a climb overturns the robot), ``slip``, ``climb``, ``high_centred``,
        ``along_path`` (the dense samples' verdicts), ``slides`` (where the tracks slide,
        arc lengths [m]) and ``verdicts`` (:func:`mmstab.runs.along.limit_verdicts`).
    """
    realised = np.atleast_2d(robot.arm_com(np.nan_to_num(plan.postures)))
    mu_realised = loaded_mu(robot, terrain, plan.poses, realised)  # one case, one batch
    # the friction cone at the planned poses; the turns' slide along the path's own time law
    # (a pivot's slide falls in the second the pivot takes, :func:`path_timing`)
    dense_poses, dense_s, times = path_timing(route, sample_spacing(terrain))
    dense_com = np.asarray(plan.target_com)[bracket(plan.s, dense_s)[0]]
    slip = passed_poses(slip_verdict(terrain, plan.poses), (0, len(plan.s) - 1))
    turning = turn_slip(terrain, dense_poses, robot_turn_check(robot, settings, dense_com, times))
    turning["sliding_turns"] = [
        x | {"start_s": float(dense_s[x["first"]]), "end_s": float(dense_s[x["last"]])}
        for x in turning["sliding_turns"]
    ]
    slip["turns"] = turning
    slip["slides"] = bool(slip["slides"]) or bool(turning["sliding_turns"])
    # between the planned poses: every few cm, the arm in the postures it moves between and
    # on its way between them
    along = plan_along(robot, terrain, route, plan) if along is None else along
    poses = [
        {"pose": plan.poses[k], "mu_planned": float(plan.mu_planned[k]),
         "mu_realised": float(mu_realised[k]), "collision_free": bool(plan.collision_free[k])}
        for k in range(len(plan.s))
    ]  # fmt: skip
    passes = times if len(times) == len(along.s) else None  # the same samples
    dense, slip, stability = along_records(
        robot, terrain, route, plan, along, route_acceleration(route), passes, settings, slip,
        poses,
    )  # fmt: skip
    out: dict[str, Any] = {
        "mu_realised": mu_realised,
        "stability": stability,
        "slip": slip,
        "climb": climb_verdict(robot, terrain, plan.poses, plan.target_com, False),
        "high_centred": high_centred_along(along),
        "along_path": dense,
        "slides": slide_stretches(slip, plan.s),
    }
    if arm_path is not None:  # the reference's fractions are the route's time fractions
        spans = arm_path["reference"]["intervals_fraction"]
        metres = [route.s_at([a, b]).tolist() for a, b in spans]
        out["arm_path"] = arm_path | {"intervals_m": metres}
    out["verdicts"] = limit_verdicts({**out, "s": plan.s.tolist(), "poses": poses,
                                      "risk": {"slides": out["slides"]}})  # fmt: skip
    return out


def along_records(
    robot: Robot,
    terrain: Terrain,
    path: RoutePath | CirclePath,
    stage: RoutePlan | LapStage,
    along: Along,
    acceleration: float,
    times: Any,
    settings: VerdictSettings,
    slip: dict[str, Any],
    poses: list[dict[str, Any]],
) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
    """A plan's checks every few cm, route or lap: (``along_path``, ``slip``, ``stability``).

    Args:
        robot: the robot.
        terrain: the ground.
        path: the route or lap.
        stage: its plan (postures, moves, ``s``).
        along: the path's samples (:func:`plan_along`, :func:`lap_along`).
        acceleration: the path's largest acceleration [m/s^2] (the tip margin's share, the
            rocks' push).
        times: when the path reaches each sample (N,) [s] (the cone's passes priced at the
            time law); None: every pass beyond the cone slides.
        settings: the margin and the slide's limits.
        slip: the planned poses' slide verdict, given the dense stretches here.
        poses: the planned poses' records (``pose``, ``mu_planned``, ``mu_realised``,
            ``collision_free``): the tip verdict at them, given the stretches here.
    """
    accelerating = acceleration_margin(robot.total_mass, acceleration)
    # where μ is low about an edge inside the footprint, the push rocks it onto the next one
    threshold = settings.margin + accelerating
    rocks = rock_samples(robot, terrain, along, threshold, settings.margin, acceleration)
    timing = None
    if times is not None:
        timing = ConeTiming(np.asarray(times), settings.slip_distance, settings.slip_window)
    dense = dense_verdicts(terrain, along, settings.margin, accelerating, rocks, timing)
    # the arm on its posture reference at the rests (a heightmap's): in the ground is a contact
    in_ground = arm_in_ground_record(robot, terrain, path, stage, along.poses, along.s)
    if in_ground is not None:
        dense["arm_in_ground"] = in_ground
    if settings.arm_over_crests:  # the arm against the ground at the rests and over crests
        from mmstab.runs.arm_ground import arm_ground_record

        dense["arm_ground"] = arm_ground_record(robot, terrain, path, stage, along.poses,
                                                along.s, rocks.checked)  # fmt: skip
    slip = with_stretches(slip, dense, "slide", "slides")
    stability = with_stretches(plan_verdict(poses, settings.margin), dense, "tip", "stable")
    # climbs with the rear down, the arm on its posture reference (runs.climb_out)
    stability["climb_out"] = climb_out_verdict(robot, terrain, path, along.poses, along.s, stage)
    if stability["climb_out"]["overturns"]:
        stability["stable"] = False
    return dense, slip, stability


def lap_verdicts(
    robot: Robot,
    terrain: Terrain,
    lap: CirclePath,
    plan: Plan,
    poses: list[dict[str, Any]],
    settings: VerdictSettings,
    lap_time: float,
    arm_path: dict[str, Any] | None = None,
    along: Along | None = None,
) -> dict[str, Any]:
    """The verdicts of a closed path's plan (``mmstab plan`` on a circle).

    Checked as a route's (:func:`route_verdicts`): at the planned poses and every few cm
    around the lap, the arm in the postures it moves between and on its moves; the lap is
    driven at one speed from rest at its start (where the run waits for the arm).

    Args:
        robot: the robot.
        terrain: the ground.
        lap: the closed path.
        plan: the lap's plan (its postures, moves and fractions).
        poses: per planned pose: ``pose`` (3,) [m, m, rad], ``fraction`` of the lap,
            ``target_com`` (3,) body frame [m], ``mu_planned``, ``mu_realised`` [N rad],
            ``collision_free``.
        settings: the margin and the slide's limits.
        lap_time: one lap [s] (``controller.lap_time``).
        arm_path: :func:`arm_path_check`'s report (None: the moves were checked).
        along: :func:`lap_along`'s samples, if already made.

    Returns:
        ``stability`` (with ``climb_out``), ``slip`` (the friction cone at the lap's start,
        around the lap at its time law, and the lap's turns), ``climb``, ``high_centred``,
        ``along_path`` (the dense samples' verdicts), ``slides``, ``arm_path`` (with
        ``arm_path``: its report and the touching stretches ``intervals_m`` [m]) and
        ``verdicts`` (:func:`mmstab.runs.along.limit_verdicts`; ``where`` in arc lengths
        from the lap's start [m]).
    """
    stage = lap_stage(plan, lap)
    coms = [p["target_com"] for p in poses]
    times = [lap_time * p["fraction"] for p in poses]
    turns = robot_turn_check(robot, settings, coms, times, lap_time)
    pose_xy = np.asarray([p["pose"] for p in poses], dtype=float)
    # the cone at the start, where the robot rests; elsewhere priced along the lap
    slip = passed_poses(slip_verdict(terrain, pose_xy, turns), (0,))
    slip["slides"] = slip["slides"] or bool(slip.get("turns", {}).get("sliding_turns"))
    along = lap_along(robot, terrain, lap, stage) if along is None else along
    passes = lap_time * lap.fraction_of_s(along.s)  # one speed
    dense, slip, stability = along_records(
        robot, terrain, lap, stage, along, lap_acceleration(lap, lap_time), passes, settings,
        slip, poses,
    )  # fmt: skip
    out: dict[str, Any] = {
        "stability": stability,
        "slip": slip,
        "high_centred": high_centred_along(along),
        "climb": climb_verdict(robot, terrain, pose_xy, np.asarray(coms), True),
        "along_path": dense,
    }
    s = stage.s.tolist()
    out["slides"] = slide_stretches(out["slip"], s, lap.length)
    if arm_path is not None:
        spans = arm_path["reference"]["intervals_fraction"]
        out["arm_path"] = {**arm_path, "intervals_m": [[lap.length * a, lap.length * b]
                                                       for a, b in spans]}  # fmt: skip
    out["verdicts"] = limit_verdicts({**out, "s": s, "poses": poses,
                                      "risk": {"slides": out["slides"]}})  # fmt: skip
    return out


def exit_status(verdicts: dict[str, dict[str, Any]]) -> int:
    """``mmstab plan``'s exit status for a plan's verdicts (no ``--allow-...`` option).

    3 where a pose tips or falls below the margin (or a climb overturns the robot: the
    ``tip`` verdict), else 4 where the tracks slide, else 5 where the arm touches the robot,
    else 0.
    """
    if verdicts["tip"]["unsafe"]:
        return EXIT_UNSTABLE
    if verdicts["slide"]["unsafe"]:
        return EXIT_SLIDES
    if verdicts["arm_contact"]["unsafe"]:
        return EXIT_ARM_COLLISION
    return 0


def passed_poses(slip: dict[str, Any], rests: Any) -> dict[str, Any]:
    """A path's cone check at its planned poses where the robot rests (a route's ends).

    The path passes its other planned poses at its time law; the dense samples price the
    supports beyond the cone there (:func:`mmstab.stability.slip.cone_slide`). Those poses
    move to ``passed_poses`` (index, pose, tilt [rad]).

    Args:
        slip: the cone's verdict at the planned poses (``sliding_poses``).
        rests: the indices of the planned poses the robot rests at.
    """
    out = dict(slip)
    bad = out.get("sliding_poses", [])
    ends = set(rests)
    out["sliding_poses"] = [b for b in bad if b["index"] in ends]
    out["passed_poses"] = [b for b in bad if b["index"] not in ends]
    out["slides"] = bool(out["sliding_poses"])
    return out


def with_stretches(
    verdict: dict[str, Any], dense: dict[str, Any], limit: str, key: str
) -> dict[str, Any]:
    """A per-pose verdict with the path's stretches between the poses that pass ``limit``.

    Args:
        verdict: the planned poses' verdict (``stability`` or ``slip``).
        dense: :func:`mmstab.runs.along.dense_verdicts`.
        limit: ``tip`` or ``slide``.
        key: the verdict's flag: ``stable`` (False where a stretch tips) or ``slides``.
    """
    out = dict(verdict)
    found = dense[limit]
    out["stretches"] = found["stretches"]
    out["spacing_m"] = dense["spacing_m"]
    if limit == "tip":  # the margin along the path, with the route's accelerations
        out["along_threshold"] = found["threshold"]
        out["acceleration_margin"] = found["acceleration_margin"]
    if limit == "slide":
        out.setdefault("critical_tilt", found["critical_tilt"])
        out.setdefault("friction", found["friction"])
    if found["binds"]:
        out[key] = key != "stable"
    return out


def slide_stretches(
    slip: dict[str, Any], s: Any, length: float | None = None
) -> list[dict[str, float]]:
    """Where the tracks slide, in arc lengths [m]: at the planned poses, between them, in turns.

    Each with the worst tilt [rad] where the support's tilt is the reason (``tilt_max``) or
    the turn's slide within the window [m] (``slide_m``). ``length``: a closed path's [m]; a
    turn across its start is two stretches, to ``length`` and from 0.
    """
    s_m = np.asarray(s, dtype=float)
    mask = np.zeros(s_m.size, dtype=bool)
    tilt = np.zeros(s_m.size)
    for b in slip["sliding_poses"]:
        mask[b["index"]], tilt[b["index"]] = True, b["tilt"]
    out: list[dict[str, Any]] = [
        {"start_s": float(s_m[k]), "end_s": float(s_m[j - 1]), "tilt_max": float(tilt[k:j].max())}
        for k, j in true_runs(mask)
    ]
    out += [
        {"start_s": x["start_s"], "end_s": x["end_s"], "tilt_max": x["worst"]}
        for x in slip.get("stretches", [])
    ]
    out += [
        {"start_s": float(t["start_s"] if "start_s" in t else s_m[t["first"]]),
         "end_s": float(t["end_s"] if "end_s" in t else s_m[t["last"]]),
         "slide_m": t["slide_in_window_m"], "turn_rad": t["turn_rad"]}
        for t in slip.get("turns", {}).get("sliding_turns", [])
    ]  # fmt: skip
    if length is not None:  # a lap's turn across its start: to the lap's end, from 0
        wraps = [x for x in out if x["end_s"] < x["start_s"]]
        out = [x for x in out if x["end_s"] >= x["start_s"]]
        out += [x | {"end_s": float(length)} for x in wraps]
        out += [x | {"start_s": 0.0} for x in wraps if x["end_s"] > 0.0]
    return sorted(out, key=lambda x: x["start_s"])
