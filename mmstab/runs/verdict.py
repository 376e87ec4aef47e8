"""Stability verdicts: numbers turned into "this holds" or "this tips" (application layer).

The force-angle measure μ [N rad] is positive while the robot stands and negative once its
weight acts outside the support polygon: the robot tips over. Two verdicts:

- a **plan** is stable when every pose's μ exceeds the margin (``planner.margin``, 0 when
  the key is absent); μ of a pose is the smaller of the planner's target and the posture
  realising it (``mu_planned``, ``mu_realised``). :func:`plan_verdict` works from the
  per-pose numbers a plan summary already holds, so the planner's loop is untouched;
  :func:`plan_stability` computes them for a plan that has no summary (the tracking run).
- a **tracking run** tips where μ < 0 (the arm as it moved) for
  :data:`mmstab.runs.tip_rule.TIP_HOLD` on end, at samples where the robot
  does not rock onto a support that holds it (:func:`mmstab.stability.rock.rock_over`); the
  simulation stops there (:mod:`mmstab.runs.tracking`) and :func:`describe_tipping` says when
  and where.

The command line reports either on stderr and exits with status 3
(:class:`mmstab.core.files.UnstableError`), unless ``--allow-unstable`` (plans only).

A third verdict, the **slip limit** (:mod:`mmstab.stability.slip`): a plan or a run slides
when the support's tilt at one of its base poses exceeds ``atan(terrain.friction)``;
:func:`slip_verdict` lists those poses and the command line exits with status 4
unless ``--allow-sliding`` (:mod:`mmstab.cli.commands`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from mmstab.core.files import UnstableError
from mmstab.runs.verdict_settings import DEFAULT_MARGIN, VerdictSettings
from mmstab.stability.slip import terrain_friction, terrain_slip
from mmstab.stability.support import posture_mu

if TYPE_CHECKING:
    from mmstab.core.problem import Problem
    from mmstab.model.robot import Robot
    from mmstab.planner import Plan, RoutePlan
    from mmstab.terrain.base import Terrain

#: Smallest clearance [m] between an arm link and the base or another link that a tracked
#: run may reach (FCL distance at each saved sample); below it, or on contact, the run fails.
MIN_CLEARANCE = 0.001

#: Unstable poses listed in one message (the rest are counted).
LISTED_POSES = 5


def planner_margin(planner_section: Mapping[str, Any]) -> float:
    """The stability margin a plan must exceed [N rad] (``planner.margin``, default 0)."""
    return float(planner_section.get("margin", DEFAULT_MARGIN))


def pose_mu(pose: Mapping[str, Any]) -> float:
    """μ of one planned pose [N rad]: the worse of target and realised (when known)."""
    values = [float(pose[k]) for k in ("mu_planned", "mu_realised") if k in pose]
    finite = [v for v in values if math.isfinite(v)]
    return min(finite) if finite else -math.inf


def plan_verdict(poses: Sequence[Mapping[str, Any]], margin: float) -> dict[str, Any]:
    """Whether every planned pose holds with the margin.

    Args:
        poses: per-pose records with ``pose`` (x, y, heading) [m, m, rad] and
            ``mu_planned`` (and ``mu_realised`` when known) [N rad].
        margin: μ must exceed this [N rad].

    Returns:
        ``stable``, ``margin``, ``criterion``, ``mu_min`` and ``unstable_poses`` (index,
        pose, μ), the ``stability`` record of a plan's ``summary.json``.
    """
    bad = []
    mus = [pose_mu(p) for p in poses]
    for k, (p, mu) in enumerate(zip(poses, mus, strict=True)):
        if not mu > margin:
            bad.append({"index": k, "pose": [float(v) for v in p["pose"]], "mu": mu})
    return {
        "stable": not bad,
        "margin": float(margin),
        "criterion": "mu > margin at every pose (mu: min of mu_planned and mu_realised)",
        "mu_min": min(mus) if mus else None,
        "unstable_poses": bad,
    }


def plan_stability(problem: Problem, plan: Plan | RoutePlan) -> dict[str, Any]:
    """:func:`robot_plan_stability` with the problem's ``planner.margin``.

    A route's plan is also checked for climbs that overturn the robot backwards
    (``climb_out``: :func:`mmstab.runs.climb_out.climb_out_verdict`, as ``mmstab plan``
    judges it), along the route as it will be driven (its turns slowed where they slide).
    """
    from mmstab.planner import RoutePlan

    margin = planner_margin(problem.section("planner"))
    verdict = robot_plan_stability(problem.robot, problem.terrain, plan, margin)
    if isinstance(plan, RoutePlan) and problem.route is not None:
        from mmstab.runs.along import sample_spacing
        from mmstab.runs.climb_out import climb_out_verdict
        from mmstab.runs.high_centred import path_samples

        route = problem.following(plan).route
        assert route is not None
        poses, s = path_samples(route, sample_spacing(problem.terrain))
        climb = climb_out_verdict(problem.robot, problem.terrain, route, poses, s, plan)
        verdict = {**verdict, "climb_out": climb}
        verdict["stable"] = verdict["stable"] and not climb["overturns"]
    return verdict


def robot_plan_stability(
    robot: Robot, terrain: Terrain, plan: Plan | RoutePlan, margin: float
) -> dict[str, Any]:
    """The verdict of a plan made by :func:`mmstab.planner.plan_path` (no summary needed).

    Args:
        robot: the robot.
        terrain: the ground.
        plan: the plan: its targets' μ and the postures realising them.
        margin: μ must exceed this (``planner.margin``) [N rad].

    Returns:
        :func:`plan_verdict` of its poses.
    """
    # the one μ of each planned state (its loaded support, the tool wrench when given)
    realised = posture_mu(robot, terrain, plan.poses, np.asarray(plan.postures))
    poses = [
        {"pose": t.pose, "mu_planned": float(t.mu), "mu_realised": float(m)}
        for t, m in zip(plan.targets, realised, strict=True)
    ]
    return plan_verdict(poses, margin)


def describe_plan_verdict(verdict: Mapping[str, Any], total: int) -> str:
    """One line naming the unstable poses and their μ."""
    bad = verdict["unstable_poses"]
    listed = "; ".join(
        f"pose {b['index']} at ({b['pose'][0]:.3f}, {b['pose'][1]:.3f}) m heading "
        f"{b['pose'][2]:.3f} rad: mu {b['mu']:.4g}"
        for b in bad[:LISTED_POSES]
    )
    more = f"; and {len(bad) - LISTED_POSES} more" if len(bad) > LISTED_POSES else ""
    parts: list[str] = []
    if bad:
        parts.append(
            f"{len(bad)} of {total} planned poses have mu <= {verdict['margin']:g} N rad "
            f"even at the best posture found ({listed}{more})"
        )
    between = verdict.get("stretches", [])
    if between:
        named = "; ".join(
            f"s = {x['start_s']:.2f}-{x['end_s']:.2f} m: mu {x['worst']:.4g} N rad"
            for x in between[:LISTED_POSES]
        )
        threshold = verdict.get("along_threshold", verdict["margin"])
        parts.append(
            f"along the path (every {100 * verdict['spacing_m']:.0f} cm, the arm in its planned "
            f"postures and on its moves) mu <= {threshold:.3g} N rad "
            f"(the margin {verdict['margin']:g} plus "
            f"{verdict.get('acceleration_margin', 0.0):.3g} for the route's accelerations) "
            f"at {named}"
        )
    parts += [
        f"climbing a step with the rear down at s = {x['start_s']:.2f} m the robot goes over "
        f"backwards before its CoM passes the edge (pitch {math.degrees(x['pitch_rad']):.0f} "
        "deg; the arm's reference puts the CoM "
        + (f"{-100 * x['com_ahead_of_rear_m']:.1f} cm behind the rear contact)"
           if x["cause"] == "com behind the rear"
           else f"{100 * x['com_behind_edge_m']:.1f} cm behind the edge as the rear wheel "
           "meets the step's face)")
        for x in verdict.get("climb_out", {}).get("stretches", [])[:LISTED_POSES]
    ]  # fmt: skip
    return "; ".join(parts)


def check_plan(verdict: Mapping[str, Any], total: int, allow_unstable: bool) -> None:
    """Raise :class:`UnstableError` for an unstable plan unless allowed."""
    if not verdict["stable"] and not allow_unstable:
        raise UnstableError(describe_plan_verdict(verdict, total) + "; --allow-unstable to go on")


def describe_tipping(tipped: Mapping[str, Any]) -> str:
    """One line: when and where a tracking run tips over."""
    x, y, heading = tipped["pose"]
    return (
        f"the robot would tip over at t = {tipped['time_s']:.4g} s (step {tipped['step']}), "
        f"base at ({x:.3f}, {y:.3f}) m heading {heading:.3f} rad on the slope, "
        f"mu = {tipped['mu']:.4g} N rad; the run stopped there"
    )


def slip_verdict(terrain: Terrain, poses: Any, turns: TurnCheck | None = None) -> dict[str, Any]:
    """Whether the tracks hold at every base pose and in every turn (:mod:`..slip`, ``..skid``).

    Args:
        terrain: the ground (its ``friction``).
        poses: base poses (x [m], y [m], heading [rad]) (N, 3) in the terrain's map frame, in
            driving order.
        turns: what the turns between the poses need (the robot, the arm's CoM, the slide that
            counts); None: the friction cone at the poses only.

    Returns:
        ``slides``, ``friction``, ``critical_tilt`` [rad], ``tilt_max`` [rad],
        ``margin_min`` [rad] and ``sliding_poses`` (index, pose, tilt [rad]); with ``turns``,
        ``turns`` (:func:`turn_slip`) and ``slides`` also where a turn slides.
    """
    P = np.atleast_2d(np.asarray(poses, dtype=float))
    if P.size == 0:
        return {"slides": False, "sliding_poses": [], "friction": None}
    slip = terrain_slip(terrain, P)
    bad = [
        {"index": int(k), "pose": [float(v) for v in P[k]], "tilt": float(slip.tilt[k])}
        for k in np.flatnonzero(slip.slides)
    ]
    out: dict[str, Any] = {
        "slides": bool(bad),
        "friction": slip.friction,
        "critical_tilt": slip.critical_tilt,
        "tilt_max": float(np.max(slip.tilt)),
        "margin_min": float(np.min(slip.margin)),
        "criterion": "tilt of the support <= atan(friction) at every pose",
        "sliding_poses": bad,
    }
    if turns is not None and len(P) > 1:
        turning = turn_slip(terrain, P, turns)
        out["turns"] = turning
        out["slides"] = bool(bad) or bool(turning["sliding_turns"])
    return out


class TurnCheck(NamedTuple):
    """What :func:`turn_slip` needs besides the poses.

    Attributes:
        robot: the robot.
        arm_com_body: the arm's CoM at each pose, body frame (N, 3) or (3,) [m].
        times: when the path reaches each pose (N,) [s].
        distance: a downhill slide beyond this within ``window`` slides [m]
            (``physics.slip_distance``).
        window: [s] (``physics.slip_window``).
        period: the loop's period when the poses close a loop (the last turns into the
            first), else None [s].
        turn_ratio: the drive layer's η [-] (``physics.turn_ratio``; its belts turn the path).
        shear_modulus: the belts' shear modulus K [m] (``physics.shear_modulus``;
            :func:`mmstab.stability.skid.skid_twist`).
    """

    robot: Robot
    arm_com_body: Any
    times: Any
    distance: float
    window: float
    period: float | None = None
    turn_ratio: float = 1.0
    shear_modulus: float = 0.0


#: The turn check's samples per slip window at most: a tracking run's are thinned to this
#: (its 8,744 poses of rough.yaml cost 42 s in the skid model; 10 per window, 3 s).
TURN_SAMPLES_PER_WINDOW = 10


def thinned(times: Any, step: float) -> Any:
    """Indices of ``times`` [s]: the first in each ``step`` [s] of time, and the last."""
    t = np.asarray(times, dtype=float)
    if len(t) == 0:
        return np.zeros(0, dtype=int)
    _, first = np.unique(np.floor((t - t[0]) / step), return_index=True)
    return np.union1d(first, [len(t) - 1])


def turn_check(
    problem: Problem, arm_com_body: Any, times: Any, period: float | None = None
) -> TurnCheck:
    """The problem's :class:`TurnCheck` (:func:`robot_turn_check` of its ``physics:``)."""
    settings = VerdictSettings.from_sections(problem.section("planner"), problem.section("physics"))
    return robot_turn_check(problem.robot, settings, arm_com_body, times, period)


def robot_turn_check(
    robot: Robot,
    settings: VerdictSettings,
    arm_com_body: Any,
    times: Any,
    period: float | None = None,
) -> TurnCheck:
    """A robot's :class:`TurnCheck`: the slide and window of ``settings``.

    Args:
        robot: the robot.
        settings: the slide's limits (``slip_distance``, ``slip_window``, ``turn_ratio``,
            ``shear_modulus``).
        arm_com_body: the arm's CoM at each pose, body frame (N, 3) [m].
        times: when the path reaches each pose (N,) [s].
        period: the loop's period [s] (closed paths), else None.
    """
    from mmstab.stability.drive import resolve_turn_ratio

    ratio = resolve_turn_ratio(robot, settings.turn_ratio)
    return TurnCheck(robot, arm_com_body, times, settings.slip_distance, settings.slip_window,
                     period, ratio, settings.shear_modulus)  # fmt: skip


#: The slide of a turn the closed loop takes longer over than the path (:func:`turn_time`) times
#: this: at the tracks' rate MuJoCo's fast pivots slide up to 1.045 times the model's per
#: second (``make skid-rates``: ``fast.per_second_ratio_max``), so the verdict's error on
#: them goes the safe way on that grid.
TRACKS_TIME_MARGIN = 1.05


def turn_time(turn: Any, dt: Any, turn_ratio: Any, bounded: Any = True) -> Any:
    """How long the closed loop takes to turn a segment's heading change (N,) [s].

    The path asks for ``turn`` [rad] in ``dt`` [s], a yaw rate ω. Skid-steered, the heading
    turns at the model's share of what the belts command (``turn_ratio``: the model's yaw
    rate over the path's, at least :data:`mmstab.stability.skid.TURN_FLOOR`); the controller
    raises the command to keep up, but on a slope no further than ω plus its yaw margin
    (:mod:`mmstab.control.limits.yaw_rate`). So the heading turns at
    ``min(ω, share (ω + margin))``: a slow turn at the path's rate, a pivot faster than the
    tracks give over longer than the path's time law says (``make skid-rates``: MuJoCo's
    pivots commanded at 1.2 rad/s turn at 0.62 and slide per second as the model does).
    Where the controller is not ``bounded`` (ground below the limit's slope) the path's time.

    Args:
        turn: heading change per segment (N,) [rad].
        dt: the path's time for it (N,) [s].
        turn_ratio: the model's yaw rate over the path's (N,) [-] (NaN: none).
        bounded: the controller's yaw-rate limit applies there (N,) or one [-].
    """
    from mmstab.control.limits.yaw_rate import YAW_MARGIN
    from mmstab.stability.skid import TURN_FLOOR

    ratio = np.abs(np.asarray(turn_ratio, dtype=float))
    share = np.maximum(np.where(np.isfinite(ratio), ratio, 1.0), TURN_FLOOR)
    angle = np.abs(np.asarray(turn, dtype=float))
    rate = angle / np.asarray(dt, dtype=float)
    achieved = np.minimum(rate, share * (rate + YAW_MARGIN))
    took = np.where((angle > 1e-6) & np.asarray(bounded), angle / np.maximum(achieved, 1e-12), dt)
    return np.maximum(dt, took)


def turn_slip(terrain: Terrain, poses: Any, check: TurnCheck) -> dict[str, Any]:
    """The downhill slide the motion between consecutive poses costs (:mod:`..skid`).

    Each segment costs the skid-steer model's downhill motion beyond the commanded one (the
    worse of its two end poses, the belts at the segment's forward speed and turn rate): its
    slide per radian times the heading change, or on a straight segment the belts' creep
    times the segment's time; spread over the time the tracks take for it
    (:func:`turn_time`: a pivot faster than the tracks turn lasts longer than the path's
    time law says; poses denser than :data:`TURN_SAMPLES_PER_WINDOW` per window are thinned
    first). A segment slides when the
    slide within any ``check.window`` ending in it exceeds ``check.distance`` (the closed
    loop's "slid", :func:`mmstab.physics.loop_checks.downhill_drift`: the same quantity and
    threshold); a run of such segments is a sliding turn. Poses beyond the friction cone
    are the cone's verdict, not a turn's. The poses should be the path's own, at its time
    law (:func:`mmstab.runs.along.path_timing`), so that a pivot's slide falls in the second
    it takes.

    Returns:
        ``distance_m``, ``window_s``, ``slide_rate_max_m_s`` and ``sliding_turns`` (first and
        last pose, the turn [rad], the largest slide within a window [m]).
    """
    from mmstab.control.limits.yaw_rate import YAW_MIN_SLOPE
    from mmstab.core.masks import true_runs
    from mmstab.stability.skid import track_patch, turn_slide

    t_all = np.asarray(check.times, dtype=float)
    keep = thinned(t_all, check.window / TURN_SAMPLES_PER_WINDOW)  # a run's dense samples
    P = np.atleast_2d(np.asarray(poses, dtype=float))[keep]
    t = t_all[keep]
    robot, friction = check.robot, terrain_friction(terrain)
    arm_com = np.broadcast_to(np.asarray(check.arm_com_body, float), (len(t_all), 3))[keep]
    com, gravity = robot.overall_com(arm_com), terrain.gravity_body(P)  # once per pose
    closed = check.period is not None
    n = len(P) if closed else len(P) - 1  # segments: the last pose turns into the first
    after = np.roll(np.arange(len(P)), -1)[:n]
    t_end = np.r_[t[1:], t[0] + (check.period or 0.0)][:n]
    turn = np.angle(np.exp(1j * (P[after, 2] - P[:n, 2])))
    heading = np.c_[np.cos(P[:n, 2]), np.sin(P[:n, 2])]
    travel = np.sum((P[after, :2] - P[:n, :2]) * heading, 1)
    dt_seg = np.maximum(t_end - t[:n], 1e-9)
    patch, slide, took = track_patch(robot), np.zeros(n), dt_seg.copy()
    # where the controller's yaw-rate limit holds the turn (its ground's slope, at the pose)
    bounded = -gravity[:, 2] / np.linalg.norm(gravity, axis=1) <= np.cos(YAW_MIN_SLOPE)
    for end in (np.arange(n), after):  # the worse of each segment's two end poses
        ts = turn_slide(patch, gravity[end], com[end], travel / dt_seg, turn / dt_seg, friction,
                        check.turn_ratio, check.shear_modulus)  # fmt: skip
        rate = np.where(np.isfinite(ts.per_radian) | (np.abs(turn) < 1e-6), ts.rate, 0.0)
        slide = np.maximum(slide, np.nan_to_num(rate, nan=0.0, posinf=0.0) * dt_seg)
        took = np.maximum(took, turn_time(turn, dt_seg, ts.turn_ratio, bounded[end]))
    slide = np.where(took > dt_seg * (1 + 1e-9), TRACKS_TIME_MARGIN * slide, slide)
    # cumulative slide against the time the tracks take (piecewise linear); the slide within
    # the window ending at each segment's end
    T = np.r_[0.0, np.cumsum(took)]
    S = np.r_[0.0, np.cumsum(slide)]
    if closed:  # a window may reach back over the loop's start (the loop as the tracks take it)
        period = T[-1] + max(float(check.period or 0.0) - float(np.sum(dt_seg)), 0.0)
        T, S = np.r_[T[:-1] - period, T], np.r_[S[:-1] - S[-1], S]
    windowed = S[-len(slide) :] - np.interp(T[-len(slide) :] - check.window, T, S)
    turns = [
        {"first": int(keep[a]), "last": int(keep[b % len(P)]), "turn_rad": float(np.sum(turn[a:b])),
         "slide_in_window_m": float(windowed[a:b].max())}
        for a, b in true_runs(windowed > check.distance)
    ]  # fmt: skip
    return {
        "distance_m": check.distance,
        "window_s": check.window,
        "shear_modulus_m": check.shear_modulus,
        "slide_rate_max_m_s": float(np.max(slide / took, initial=0.0)),
        "criterion": "downhill motion beyond the command (skid-steer model) within the window "
        "<= distance",
        "sliding_turns": turns,
    }


def climb_verdict(
    robot: Robot, terrain: Terrain, poses: Any, arm_com_body: Any, closed: bool
) -> dict[str, Any]:
    """Whether the tracks climb every step the planned poses run into (the climb limit).

    With the plan's arm and with the arm stowed (:mod:`mmstab.stability.climb`).

    Args:
        robot: the robot.
        terrain: the ground.
        poses: planned base poses (x [m], y [m], heading [rad]) (K, 3) in M, in driving order.
        arm_com_body: the plan's arm CoM at each pose, body frame (K, 3) [m].
        closed: the path is a loop.

    Returns:
        ``steps`` (each pose that keeps a step's climb limit: ``index``; ``met_from``, the
        pose whose look-ahead meets the step (itself, or the pose before it, which drives
        into it), and ``met_after_m``, how far from that pose the front wheel meets the
        edge [m]; the step's ``height`` [m] and edge ``angle`` [rad]; whether the planned
        and the stowed arm climb it), ``stalls`` (the planned arm cannot climb one),
        ``stowed_stalls``.
    """
    from mmstab.planner.climbing import climb_plan

    P = np.atleast_2d(np.asarray(poses, dtype=float))
    plan = climb_plan(robot, terrain, P, closed)
    planned = plan.climbs(robot.overall_com(np.asarray(arm_com_body, dtype=float)))
    stowed = plan.climbs(np.tile(robot.overall_com(robot.arm_com(robot.stowed)), (len(P), 1)))
    lim = plan.limit
    steps = [
        {
            "index": int(k),
            "met_from": int(plan.source[k]),
            "met_after_m": float(lim.ahead[plan.source[k]]),
            "height": float(lim.height[plan.source[k]]),
            "angle": float(lim.angle[plan.source[k]]),
            "planned_climbs": bool(planned[k]),
            "stowed_climbs": bool(stowed[k]),
        }
        for k in np.flatnonzero(plan.constrained)
    ]
    return {
        "stalls": bool(not planned.all()),
        "stowed_stalls": bool(not stowed.all()),
        "criterion": "the overall CoM in the climb limit's half-plane at every step (quasi-static)",
        "steps": steps,
    }


def _cone_slide_words(stretch: Mapping[str, Any]) -> str:
    """What a stretch beyond the friction cone slides within the window (when priced)."""
    if "slide_m" not in stretch:
        return ""
    if stretch["slide_m"] is None:
        return ", at rest on it (it slides indefinitely)"
    return f", {100 * stretch['slide_m']:.1f} cm in {stretch['duration_s']:.2f} s there"


def describe_sliding(verdict: Mapping[str, Any], total: int) -> str:
    """One line naming the poses where the tracks slide, and the turns that slide."""
    bad = verdict["sliding_poses"]
    listed = "; ".join(
        f"pose {b['index']} at ({b['pose'][0]:.3f}, {b['pose'][1]:.3f}) m heading "
        f"{b['pose'][2]:.3f} rad: tilt {math.degrees(b['tilt']):.2f} deg"
        for b in bad[:LISTED_POSES]
    )
    more = f"; and {len(bad) - LISTED_POSES} more" if len(bad) > LISTED_POSES else ""
    parts: list[str] = []
    if bad:
        parts.append(
            f"the tracks would slide at {len(bad)} of {total} poses: tilt beyond "
            f"{math.degrees(verdict['critical_tilt']):.2f} deg = atan(friction "
            f"{verdict['friction']:g}) ({listed}{more})"
        )
    between = verdict.get("stretches", [])
    if between:
        named = "; ".join(
            f"s = {x['start_s']:.2f}-{x['end_s']:.2f} m: tilt {math.degrees(x['worst']):.1f} deg"
            + _cone_slide_words(x)
            for x in between[:LISTED_POSES]
        )
        parts.append(
            f"along the path (every {100 * verdict['spacing_m']:.0f} cm) the support tilts "
            f"beyond {math.degrees(verdict['critical_tilt']):.2f} deg at {named}"
        )
    turns = verdict.get("turns", {}).get("sliding_turns", [])
    if turns:
        named = "; ".join(
            (
                f"s = {t['start_s']:.2f}-{t['end_s']:.2f} m"
                if "start_s" in t
                else f"poses {t['first']}-{t['last']}"
            )
            + f": turning {math.degrees(t['turn_rad']):.0f} deg there, "
            f"{100 * t['slide_in_window_m']:.1f} cm"
            for t in turns[:LISTED_POSES]
        )
        parts.append(
            f"{len(turns)} turn(s) would slide downhill by more than "
            f"{100 * verdict['turns']['distance_m']:.1f} cm within "
            f"{verdict['turns']['window_s']:g} s ({named})"
        )
    return "; ".join(parts)


def arm_collision_verdict(colliding_samples: int, min_clearance: float) -> dict[str, Any]:
    """Whether the tracked arm kept clear of the robot: no contact, clearance >= MIN_CLEARANCE.

    Args:
        colliding_samples: saved samples at which some arm link intersects [-].
        min_clearance: the smallest link clearance over the run [m].
    """
    return {
        "safe": colliding_samples == 0 and min_clearance >= MIN_CLEARANCE,
        "required_clearance_m": MIN_CLEARANCE,
        "min_clearance_m": float(min_clearance),
        "colliding_samples": int(colliding_samples),
    }


def describe_arm_collision(report: Mapping[str, Any]) -> str:
    """One line: how the tracked arm came too close to (or into) the robot."""
    verdict = report["verdict"]
    pairs = ", ".join(list(report.get("pairs", {}))[:3]) or "none in contact"
    return (
        f"the tracked arm touches the robot in {verdict['colliding_samples']} of "
        f"{report['samples']} samples ({pairs}); minimum clearance "
        f"{verdict['min_clearance_m'] * 1e3:.2f} mm at t = {report['min_clearance_time_s']:.4g} s"
        f" (required {verdict['required_clearance_m'] * 1e3:.1f} mm)"
    )
