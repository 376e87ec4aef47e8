"""A path's verdicts between its planned poses: every few centimetres, not every half metre.

The planner places poses ``planner.spacing`` apart (0.5 m by default); a ditch's edge or a
kerb lies between two of them. :func:`dense_verdicts` rests the robot along the path every
``spacing`` of arc length (the map's cell, at most :data:`SPACING`, below the tracks'
contact spacing) with the arm in each of the two planned postures it moves between and,
given, where its posture reference has it (the move ``mmstab track`` commands, which may
swing the arm's CoM beyond both postures it joins); the worst counts. It checks there what
the tracking run and the robot meet:

- **tip**: mmstab's one μ (:mod:`mmstab.stability.support`) at or below the plan's margin
  plus what the route's own accelerations take off it (:func:`acceleration_margin`), unless
  the edges it is low about are rocking edges: pushed across them by the route's
  acceleration the robot turns onto a support that holds (:func:`rock_samples`,
  :mod:`mmstab.stability.rock`: a diagonal between two track corners on bumps, a rim);
- **slide**: the support's tilt beyond ``atan(friction)`` (the friction cone,
  :mod:`mmstab.stability.slip`), priced as the slide it costs within the slip window at
  the path's time law (:func:`mmstab.stability.slip.cone_slide`): a stretch slides when
  that exceeds the slip distance (a stop on it, the route's ends included, always does);
- **high-centred**: the chassis among the loaded contacts (a warning: stuck, not unsafe).

Each failing stretch says where (arc lengths [m]), which limit and by how much. A circle's
lap is checked the same way (:class:`LapStage`: its plan as a route's is read); it closes on
its first pose.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.core.masks import true_runs
from mmstab.model.robot import FloatArray, Robot
from mmstab.stability.rock import rock_over
from mmstab.stability.slip import cone_slide, slip_limit, terrain_friction
from mmstab.stability.support import is_heightmap, loaded_support
from mmstab.terrain.base import GRAVITY_G, Terrain

if TYPE_CHECKING:
    from mmstab.paths.circle import CirclePath
    from mmstab.planner import Plan, PlannerSettings

#: Largest arc length between two checked samples [m] (the maps' cells are 2-5 cm; the
#: tracks' road wheels about 10 cm apart).
SPACING = 0.05


class Along(NamedTuple):
    """The samples of a path and what the robot meets there (N samples).

    Attributes:
        s: arc length of each sample (N,) [m].
        poses: (N, 3) of (x, y, yaw) in M [m, m, rad].
        mu: the worst μ of the arm's CoMs (N,) [N rad] (NaN: off the map).
        tilt: the largest support tilt of them (N,) [rad].
        high_centred: (N,) the chassis carries load with any of them.
        arm_com: the arm CoMs checked at each sample, body frame (P, N, 3) [m]: the
            planned postures before and after it, and the posture reference's if given.
    """

    s: FloatArray
    poses: FloatArray
    mu: FloatArray
    tilt: FloatArray
    high_centred: np.ndarray
    arm_com: FloatArray


class LapStage(NamedTuple):
    """A lap's plan as the dense checks read a route's (:func:`lap_stage`).

    Attributes:
        s: arc length of each planned pose from the lap's start (K,) [m].
        fractions: the lap's (time) fraction of each (K,) [-].
        target_com: the planned arm CoMs, body frame (K, 3) [m].
        postures: the postures realising them (K, n) [rad].
        moves: the arm's path into each posture (the roadmap's), else empty.
        settings: the planner's settings.
    """

    s: FloatArray
    fractions: FloatArray
    target_com: FloatArray
    postures: FloatArray
    moves: tuple[FloatArray, ...]
    settings: PlannerSettings


def lap_stage(plan: Plan, lap: CirclePath) -> LapStage:
    """The lap's plan with its poses' arc lengths [m] (a lap is driven at one speed)."""
    fractions = np.asarray(plan.fractions, dtype=float)
    return LapStage(lap.length * fractions, fractions, np.asarray(plan.target_com, dtype=float),
                    np.asarray(plan.postures, dtype=float), plan.moves, plan.settings)  # fmt: skip


def acceleration_margin(mass: float, acceleration: float) -> float:
    """What the route's accelerations can take off a quasi-static μ [N rad].

    An acceleration ``a`` of the base (along or across the path) tilts the net force
    ``m (g - a)`` by ``atan(a / g)`` from gravity, so each axis angle theta_j moves by at
    most that much, and μ = min theta_j |f| by at most ``|f| atan(a / g)``.

    Args:
        mass: the robot's mass [kg].
        acceleration: the largest acceleration of the base along the route [m/s^2]
            (``path.acceleration``, ``path.lateral_acceleration``).
    """
    g = float(np.linalg.norm(GRAVITY_G))
    return float(mass * np.hypot(g, acceleration) * np.arctan2(acceleration, g))


def sample_spacing(terrain: Terrain) -> float:
    """The samples' spacing [m]: the map's cell, at most :data:`SPACING`."""
    hm = getattr(terrain, "heightmap", None)
    return SPACING if hm is None else float(min(SPACING, hm.resolution))


def path_timing(route: Any, spacing: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(poses (N, 3) in M, arc lengths (N,) [m], times (N,) [s]) along a route's time law.

    Samples every ``spacing`` [m] of the route's parameter (a pivot's is the tracks' run,
    :mod:`mmstab.paths.geometry`), each at the time its speed profile reaches it: a pivot's
    heading turns in the seconds the path takes for it, not spread over the planned poses'
    half-metre segments (the turn verdict's window, :func:`mmstab.runs.verdict.turn_slip`).

    Args:
        route: the route (:class:`mmstab.paths.route.RoutePath`).
        spacing: [m].
    """
    n = max(int(np.ceil(route.length / spacing)) + 1, 2)
    s = np.linspace(0.0, route.length, n)
    return route.poses(n), s, np.asarray(route.fraction_of_s(s)) * route.lap_time


def bracket(s_plan: ArrayLike, s: ArrayLike, closed: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the planned poses before and after each arc length ``s`` [m].

    On a ``closed`` path (a lap) the pose after the last is the first: the lap closes.
    """
    sp = np.asarray(s_plan, dtype=float)
    last = len(sp) - 1
    before = np.clip(np.searchsorted(sp, np.asarray(s, float), side="right") - 1, 0, last)
    if closed:
        return before, np.where(before == last, 0, before + 1)
    return before, np.minimum(before + 1, last)


def along_path(
    robot: Robot,
    terrain: Terrain,
    poses: ArrayLike,
    s: ArrayLike,
    s_plan: ArrayLike,
    arm_com_plan: ArrayLike,
    arm_com_reference: ArrayLike | None = None,
    closed: bool = False,
) -> Along:
    """Rest the robot at path samples with the planned arm before and after each.

    Args:
        robot: the robot.
        terrain: the ground.
        poses: the path's samples (N, 3) in M [m, m, rad], in driving order.
        s: their arc lengths (N,) [m].
        s_plan: the planned poses' arc lengths (K,) [m], increasing.
        arm_com_plan: the planned arm CoM at each planned pose, body frame (K, 3) [m].
        arm_com_reference: the arm CoM of the posture reference at each sample, body
            frame (N, 3) [m] (:func:`mmstab.runs.climb_out.reference_arm_coms`), checked
            too; None: the two postures only.
        closed: the path is a lap: past its last planned pose the arm moves into the first's.
    """
    P = np.atleast_2d(np.asarray(poses, dtype=float))
    arm = np.asarray(arm_com_plan, dtype=float)
    before, after = bracket(s_plan, s, closed)
    sets = [arm[before], arm[after]]
    if arm_com_reference is not None:
        sets.append(np.asarray(arm_com_reference, dtype=float).reshape(len(P), 3))
    k, n = len(sets), len(P)
    every = loaded_support(robot, terrain, np.vstack([P] * k), np.vstack(sets), strict=False)
    tilt = slip_limit(np.nan_to_num(every.gravity_body), 1.0).tilt
    tilt = np.where(np.isfinite(every.gravity_body).all(axis=1), tilt, np.nan)
    return Along(
        s=np.asarray(s, dtype=float),
        poses=P,
        mu=np.fmin.reduce(every.mu.reshape(k, n), axis=0),
        tilt=np.fmax.reduce(tilt.reshape(k, n), axis=0),
        high_centred=np.asarray(np.asarray(every.high_centred).reshape(k, n).any(axis=0)),
        arm_com=np.stack(sets),
    )


class Rocks(NamedTuple):
    """The samples whose low μ was checked for a rock (:func:`rock_samples`), N samples.

    Attributes:
        checked: (N,) μ at or below the threshold: pushed across its weak edges.
        holds: (N,) checked, and every arm CoM of the sample rocks onto a support that holds.
        mu: (N,) the lowest μ of the pushed CoM on the caught supports [N rad] (NaN where
            not checked or nothing pushed; -inf where it tips).
        rock: (N,) the largest turn to a catch [rad].
        drop: (N,) the largest work of a rock (the CoM's fall under the tilted net force) [m].
        barrier: (N,) the lowest energy stability margin of a caught support [m].
    """

    checked: np.ndarray
    holds: np.ndarray
    mu: FloatArray
    rock: FloatArray
    drop: FloatArray
    barrier: FloatArray


def rock_samples(
    robot: Robot,
    terrain: Terrain,
    along: Along,
    threshold: float,
    margin: float,
    acceleration: float,
) -> Rocks:
    """Push the samples at or below ``threshold`` across their weak edges (every arm CoM).

    On a heightmap only: on a plane every bottom-run contact bears, the support is the
    tracks' rectangle and a push across its edge is a tip (nothing is checked).

    Args:
        robot: the robot.
        terrain: the ground.
        along: the samples (:func:`along_path`), with the arm CoMs checked at each.
        threshold: μ at or below this [N rad] is checked (the margin plus
            :func:`acceleration_margin`).
        margin: the pushed μ on the caught support must exceed this [N rad].
        acceleration: the route's largest acceleration [m/s^2] (the push, ``a / g``).
    """
    n = len(along.s)
    checked = np.isfinite(along.mu) & ~(along.mu > threshold)
    if not is_heightmap(terrain):
        checked[:] = False
    out = Rocks(checked, np.zeros(n, dtype=bool), *(np.full(n, np.nan) for _ in range(4)))
    idx = np.flatnonzero(checked)
    if idx.size == 0:
        return out
    k, m = len(along.arm_com), idx.size
    push = acceleration / float(np.linalg.norm(GRAVITY_G))
    poses, arms = np.vstack([along.poses[idx]] * k), along.arm_com[:, idx].reshape(k * m, 3)
    r = rock_over(robot, terrain, poses, arms, push, threshold, margin)
    out.holds[idx] = np.asarray(r.holds).reshape(k, m).all(axis=0)
    out.mu[idx] = np.fmin.reduce(np.reshape(r.mu, (k, m)), axis=0)
    out.rock[idx] = np.fmax.reduce(np.reshape(r.rock, (k, m)), axis=0)
    out.drop[idx] = np.fmax.reduce(np.reshape(r.drop, (k, m)), axis=0)
    out.barrier[idx] = np.fmin.reduce(np.reshape(r.barrier, (k, m)), axis=0)
    return out


def _finite(x: Any) -> float | None:
    return float(x) if np.isfinite(x) else None


def _stretches(mask: np.ndarray, s: FloatArray, values: FloatArray, worst: Any, by: Any) -> list:
    return [
        {
            "start_s": float(s[a]),
            "end_s": float(s[b - 1]),
            "worst": float(worst(values[a:b])),
            "by": float(by(worst(values[a:b]))),
        }
        for a, b in true_runs(mask)
    ]


class ConeTiming(NamedTuple):
    """When the path reaches its samples and the slide that counts (:func:`dense_verdicts`).

    Attributes:
        times: (N,) the time law's time at each sample [s] (:func:`path_timing`).
        distance: a slide beyond this within ``window`` slides [m] (``physics.slip_distance``).
        window: [s] (``physics.slip_window``).
    """

    times: FloatArray
    distance: float
    window: float


def _priced(stretches: list, mask: np.ndarray, priced: Any) -> list:
    if priced is None:
        return stretches
    for x, (a, b) in zip(stretches, true_runs(mask), strict=True):
        x["slide_m"] = _finite(np.max(priced.slide[a:b]))  # None: at rest on it
        x["duration_s"] = _finite(np.sum(priced.dwell[a:b]))
    return stretches


def dense_verdicts(
    terrain: Terrain,
    along: Along,
    margin: float,
    accelerating: float = 0.0,
    rocks: Rocks | None = None,
    timing: ConeTiming | None = None,
) -> dict[str, Any]:
    """Tip, slide and high-centred stretches of the samples (``summary.json``'s ``along_path``).

    Args:
        terrain: the ground (its ``friction``).
        along: the samples (:func:`along_path`).
        margin: μ must exceed this [N rad] (``planner.margin``) ...
        accelerating: ... plus this [N rad] (:func:`acceleration_margin`) ...
        rocks: ... unless the robot rocks onto a support that holds there
            (:func:`rock_samples`; ``None``: no sample rocks).
        timing: the samples' times and the slide's limits: a stretch beyond the friction
            cone slides when its slide within the window exceeds the distance
            (:func:`mmstab.stability.slip.cone_slide`); ``None``: every such sample slides.

    Returns:
        ``spacing_m``, ``samples``, ``mu_min`` [N rad], ``tilt_max`` [rad], and per limit
        (``tip``, ``slide``, ``high_centred``) whether it binds and its ``stretches``: arc
        lengths [m], the worst value there (μ [N rad], tilt [rad]) and by how much it
        passes the limit (``by``: margin - μ [N rad], tilt - atan(friction) [rad]);
        ``slide.stretches`` (with ``timing``) those beyond the cone whose ``slide_m`` within
        the window exceeds the distance [m] (``duration_s``: the time on them [s]),
        ``slide.passed`` those beyond it that slide less;
        ``tip.rocks``: the stretches below the threshold where the robot rocks and holds
        (``worst`` μ at rest, the caught support's lowest pushed ``mu_rocked`` [N rad],
        the largest turn ``rock_rad`` [rad] (0: the push leaves the CoM inside), its work
        ``work_m`` against ``barrier_m`` [m] (None: no turn)).
    """
    s, mu, tilt = along.s, along.mu, along.tilt
    friction = terrain_friction(terrain)
    critical = float(np.arctan(friction))
    known = np.isfinite(mu)
    threshold = margin + accelerating
    low = known & ~(mu > threshold)
    rocking = low & (rocks.holds if rocks is not None else False)
    tips = low & ~rocking
    beyond = np.isfinite(tilt) & (tilt > critical)
    slides, priced, passed = beyond, None, []
    if timing is not None:
        priced = cone_slide(tilt, timing.times, friction, timing.window)
        runs = true_runs(beyond)
        slides = np.zeros_like(beyond)
        for a, b in runs:
            if np.max(priced.slide[a:b]) > timing.distance:
                slides[a:b] = True
        passed = [(a, b) for a, b in runs if not slides[a]]
    return {
        "spacing_m": float(np.median(np.diff(s))) if len(s) > 1 else 0.0,
        "samples": int(len(s)),
        "off_map_samples": int((~known).sum()),
        "mu_min": float(np.min(mu[known])) if known.any() else None,
        "tilt_max": float(np.max(tilt[np.isfinite(tilt)])) if np.isfinite(tilt).any() else None,
        "tip": {
            "binds": bool(tips.any()),
            "margin": float(margin),
            "acceleration_margin": float(accelerating),
            "threshold": float(threshold),
            "stretches": _stretches(tips, s, mu, np.min, lambda w: threshold - w),
            "rocks": []
            if rocks is None
            else [
                {
                    "start_s": float(s[a]),
                    "end_s": float(s[b - 1]),
                    "worst": float(np.min(mu[a:b])),
                    "mu_rocked": float(np.fmin.reduce(rocks.mu[a:b])),
                    "rock_rad": float(np.fmax.reduce(rocks.rock[a:b])),
                    "work_m": float(np.fmax.reduce(rocks.drop[a:b])),
                    "barrier_m": _finite(np.fmin.reduce(rocks.barrier[a:b])),
                }
                for a, b in true_runs(rocking)
            ],
        },
        "slide": {
            "binds": bool(slides.any()),
            "critical_tilt": critical,
            "friction": friction,
            "stretches": _priced(
                _stretches(slides, s, tilt, np.max, lambda w: w - critical), slides, priced
            ),
            "passed": [
                {
                    "start_s": float(s[a]),
                    "end_s": float(s[b - 1]),
                    "worst": float(np.max(tilt[a:b])),
                    "by": float(np.max(tilt[a:b]) - critical),
                    "slide_m": float(np.max(priced.slide[a:b])),
                    "duration_s": float(np.sum(priced.dwell[a:b])),
                }
                for a, b in passed
                if priced is not None
            ],  # fmt: skip
        },
        "high_centred": {
            "binds": bool(along.high_centred.any()),
            "stretches": [
                {"start_s": float(s[a]), "end_s": float(s[b - 1])}
                for a, b in true_runs(along.high_centred)
            ],
        },
    }


def merged(spans: list[list[float]]) -> list[list[float]]:
    """Stretches ``[start, end]`` [m] sorted, overlapping ones joined."""
    out: list[list[float]] = []
    for a, b in sorted(spans):
        if out and a <= out[-1][1] + 1e-9:
            out[-1][1] = max(out[-1][1], b)
        else:
            out.append([a, b])
    return out


def limit_verdicts(summary: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """One verdict per limit of a route plan's summary: what text, JSON and figures show.

    Args:
        summary: the route plan's ``summary.json`` (``stability``, ``slip``, ``climb``,
            ``high_centred``, ``poses``, ``risk``; a lap's ``arm_path``, where the arm's path
            between the planned postures touches the robot, ``intervals_m``; ``along_path``'s
            ``arm_in_ground``, where the arm on its reference is in the ground at rest).

    Returns:
        For ``tip``, ``slide``, ``step``, ``high_centred`` and ``arm_contact``: ``verdict``
        (``holds`` or what happens: ``tips`` (μ <= 0), ``below_margin`` (0 < μ <= the
        margin), ``slides``, ``stalls``, ``high_centred``, ``collides``), ``unsafe`` (it
        sets the exit status unless allowed) and ``where`` (arc lengths [m] of the
        stretches, ``[start, end]``, overlapping ones merged).
    """
    s = summary["s"]
    stab, slip = summary["stability"], summary["slip"]
    tip_where = [[s[b["index"]], s[b["index"]]] for b in stab["unstable_poses"]]
    tip_where += [[x["start_s"], x["end_s"]] for x in stab.get("stretches", [])]
    overturns = stab.get("climb_out", {}).get("stretches", [])
    tip_where += [[x["start_s"], x["end_s"]] for x in overturns]
    slide_where = [[x["start_s"], x["end_s"]] for x in summary["risk"]["slides"]]
    climb = summary["climb"]
    stall_where = [
        [s[x["index"]], s[x["index"]]] for x in climb["steps"] if not x["planned_climbs"]
    ]
    hc = summary["high_centred"]
    hc_where = [[x["start_s"], x["end_s"]] for x in hc["stretches"]]
    contact = [[s[k], s[k]] for k, p in enumerate(summary["poses"]) if not p["collision_free"]]
    contact += [list(x) for x in (summary.get("arm_path") or {}).get("intervals_m", [])]
    in_ground = (summary.get("along_path") or {}).get("arm_in_ground") or {}
    contact += [[x["start_s"], x["end_s"]] for x in in_ground.get("stretches", [])]
    worst = [b["mu"] for b in stab["unstable_poses"]]
    worst += [x["worst"] for x in stab.get("stretches", [])]
    tip = (
        "holds"
        if stab["stable"]
        else ("tips" if overturns or min(worst, default=0.0) <= 0 else "below_margin")
    )
    return {
        "tip": {"verdict": tip, "unsafe": not stab["stable"], "where": merged(tip_where),
                "mu_min": min(worst, default=stab.get("mu_min"))},
        "slide": {"verdict": "slides" if slip["slides"] else "holds",
                  "unsafe": bool(slip["slides"]), "where": merged(slide_where)},
        "step": {"verdict": "stalls" if climb["stalls"] else "holds", "unsafe": False,
                 "where": stall_where},
        "high_centred": {"verdict": "high_centred" if hc["high_centred"] else "holds",
                         "unsafe": False, "where": hc_where},
        "arm_contact": {"verdict": "collides" if contact else "holds", "unsafe": bool(contact),
                        "where": merged(contact)},
    }  # fmt: skip
