"""A route's time law slowed in the turns that would slide: a careful driver on a side slope.

The speed profile (:mod:`mmstab.paths.speed`) turns each corner as fast as the tracks allow
(a pivot at 1.0-1.3 rad/s), whatever the slope. The skid-steer model
(:func:`mmstab.stability.skid.turn_slide`) prices a turn's downhill slide per radian ``p``
[m/rad] of heading change, independent of how fast the belts run (the model is homogeneous
in their speed), so a turn at yaw rate ω slides about ``p ω`` per second, and within the slide
verdict's window ``W`` (``physics.slip_window``) at most ``p ω W``. :func:`turn_limits`
caps the yaw rate of each corner (pivot or arc) whose turn would slide more than the budget
``B = slide_budget x slip_distance`` (``physics.slide_budget``, null by default: no caps;
``physics.slip_distance``)
within a window at ``ω = B / (p_max W)``, ``p_max`` the largest slide per radian over the
corner with the plan's arm CoM (the one the verdict prices: the target CoM of the planned
pose before each point); at least :data:`MIN_YAW_RATE`. A corner whose whole turn slides
less than ``B`` (``p_max |turn| <= B``), or that already turns slowly enough, keeps its
rate. Straight-line creep is no turn and is not slowed.

:func:`with_time_law` applies the caps to a route plan: the route's profile is rebuilt
(:meth:`mmstab.paths.route.RoutePath.with_turn_limits`), the planned poses' time fractions
follow it, and the plan carries the slowed route (``RoutePlan.route``), which every
consumer drives (:meth:`mmstab.core.problem.Problem.following`): the plan's verdicts
(which check the slide again on the slowed law, :func:`mmstab.runs.verdict.turn_slip`),
the tracking run and MuJoCo's reference.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from mmstab.paths.route import RoutePath
from mmstab.paths.speed import TurnLimit
from mmstab.runs.along import bracket, sample_spacing
from mmstab.runs.verdict_settings import VerdictSettings
from mmstab.stability.drive import resolve_turn_ratio
from mmstab.stability.skid import track_patch, turn_slide
from mmstab.stability.slip import terrain_friction

if TYPE_CHECKING:
    from mmstab.model.robot import Robot
    from mmstab.planner import RoutePlan
    from mmstab.terrain.base import Terrain

#: Samples of a corner per sample of the verdict's spacing (:func:`runs.along.sample_spacing`).
SUBSAMPLE = 4
#: The slowest a corner is turned [rad/s]: 90 degrees in 31 s. A turn that needs slower
#: keeps this rate and its slide verdict says so.
MIN_YAW_RATE = 0.05


def corner_time(route: RoutePath, start_s: float, end_s: float) -> float:
    """How long the reference takes between two arc lengths [m] [s]."""
    p = route.profile
    return float(np.interp(end_s, p.s, p.t) - np.interp(start_s, p.s, p.t))


def turn_limits(
    robot: Robot,
    terrain: Terrain,
    route: RoutePath,
    s_plan: Any,
    target_com: Any,
    settings: VerdictSettings,
) -> tuple[tuple[TurnLimit, ...], list[dict[str, Any]]]:
    """The corners' yaw-rate caps that keep their slide within the budget (module text).

    Args:
        robot: the robot.
        terrain: the ground.
        route: the route (its profile: the rates before).
        s_plan: the planned poses' arc lengths (K,) [m], increasing.
        target_com: the planned arm CoM at each, body frame (K, 3) [m].
        settings: the slide's limits and ``slide_budget`` (None: no caps).

    Returns:
        The caps, and per corner examined (one whose turn slides beyond the budget): its
        ``waypoint``, ``kind`` (pivot, arc), ``point`` [m], ``turn_deg``, ``start_s`` and
        ``end_s`` [m], ``slide_per_rad_m`` (the model's largest), ``yaw_rate_before``
        [rad/s], ``yaw_rate_limit`` [rad/s] (None: not slowed) and ``slowed``.
    """
    if settings.slide_budget is None or route.limits is None:
        return (), []
    budget = settings.slide_budget * settings.slip_distance
    ratio = resolve_turn_ratio(robot, settings.turn_ratio)
    patch, friction = track_patch(robot), terrain_friction(terrain)
    spacing = sample_spacing(terrain)
    com_plan = np.asarray(target_com, dtype=float)
    caps: list[TurnLimit] = []
    records: list[dict[str, Any]] = []
    for corner, s0, s1 in route.route.turn_spans:
        # a quarter of the verdict's spacing, both ends in (its worst heading may be one)
        n = max(int(np.ceil(SUBSAMPLE * (s1 - s0) / spacing)), 8)
        s = s0 + (s1 - s0) * np.linspace(0.0, 1.0 - 1e-9, n + 1)  # the end still the corner's
        smp = route.route.sample(s)
        com = robot.overall_com(com_plan[bracket(s_plan, s)[0]])
        # the twist per unit ds/dt (the model is homogeneous in the belts' speed)
        slide = turn_slide(patch, terrain.gravity_body(smp.pose), com,
                           np.hypot(smp.rate[:, 0], smp.rate[:, 1]), smp.rate[:, 2], friction,
                           ratio, settings.shear_modulus)  # fmt: skip
        finite = np.isfinite(slide.per_radian)  # beyond the cone: the cone's verdict
        if not finite.any():
            continue
        per_radian = float(np.max(slide.per_radian[finite]))
        if per_radian * abs(corner.turn) <= budget:
            continue
        before = route.yaw_rate_max(s0, s1)
        limit = max(budget / (per_radian * settings.slip_window), MIN_YAW_RATE)
        slowed = limit < before
        if slowed:
            caps.append(TurnLimit(s0, s1, limit))
        records.append({
            "waypoint": int(corner.waypoint),
            "kind": "pivot" if corner.pivot else "arc",
            "point": [float(corner.point[0]), float(corner.point[1])],
            "turn_deg": float(np.degrees(corner.turn)),
            "start_s": s0, "end_s": s1,
            "slide_per_rad_m": per_radian,
            "yaw_rate_before": before,
            "yaw_rate_limit": limit if slowed else None,
            "slowed": slowed,
        })  # fmt: skip
    return tuple(caps), records


def slowed_route(
    robot: Robot,
    terrain: Terrain,
    route: RoutePath,
    s_plan: Any,
    target_com: Any,
    settings: VerdictSettings,
) -> tuple[RoutePath, dict[str, Any]]:
    """The route under :func:`turn_limits`' caps, and the account of it (``time_law``).

    Returns:
        The route (``route`` itself when no corner is slowed) and ``slide_budget``,
        ``budget_m``, ``duration_before_s``, ``duration_s`` and ``corners``
        (:func:`turn_limits`' records with ``yaw_rate_after`` [rad/s], the corner's time
        before and after, ``time_before_s``, ``time_after_s``, and when the slowed route
        reaches its start and end, ``start_t_s``, ``end_t_s`` [s]).
    """
    caps, records = turn_limits(robot, terrain, route, s_plan, target_com, settings)
    slowed = route.with_turn_limits(caps) if caps else route
    for r in records:
        r["yaw_rate_after"] = slowed.yaw_rate_max(r["start_s"], r["end_s"])
        r["time_before_s"] = corner_time(route, r["start_s"], r["end_s"])
        r["time_after_s"] = corner_time(slowed, r["start_s"], r["end_s"])
        r["start_t_s"], r["end_t_s"] = (float(x) for x in np.interp(
            [r["start_s"], r["end_s"]], slowed.profile.s, slowed.profile.t))  # fmt: skip
    budget = settings.slide_budget
    return slowed, {
        "slide_budget": budget,
        "budget_m": None if budget is None else budget * settings.slip_distance,
        "duration_before_s": route.duration,
        "duration_s": slowed.duration,
        "corners": records,
    }


def with_time_law(
    robot: Robot, terrain: Terrain, route: RoutePath, plan: RoutePlan, settings: VerdictSettings
) -> RoutePlan:
    """``plan`` on the slowed route: its fractions on that law, ``route``, ``time_law`` set."""
    slowed, law = slowed_route(robot, terrain, route, plan.s, plan.target_com, settings)
    fractions = np.asarray(slowed.fraction_of_s(plan.s), dtype=float)
    return plan._replace(fractions=fractions, route=slowed, time_law=law)


def describe_time_law(law: dict[str, Any]) -> list[str]:
    """One line per slowed corner: where, its yaw rate before and after, its time."""
    return [
        f"corner {c['waypoint']} at ({c['point'][0]:.2f}, {c['point'][1]:.2f}) m: {c['kind']} of "
        f"{abs(c['turn_deg']):.0f} deg slowed from {c['yaw_rate_before']:.2f} to "
        f"{c['yaw_rate_after']:.2f} rad/s ({c['slide_per_rad_m'] * 100:.1f} cm/rad of slide, "
        f"{c['time_before_s']:.1f} -> {c['time_after_s']:.1f} s)"
        for c in law.get("corners", [])
        if c["slowed"]
    ]
