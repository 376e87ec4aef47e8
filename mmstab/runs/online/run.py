"""A recording followed map by map (:func:`follow_recording`), and what it shows.

The run is the loop's answers (:class:`~mmstab.runs.online.follow.FollowStep` per map) and
the horizon's last plan of every route pose it planned. :func:`summarize` gives the latency
percentiles, how often the horizon re-planned, what the maps did not cover, μ along the way
and the tip-over, slip and arm-in-ground verdicts; :func:`run_frames` the run as a
recording's frames (:mod:`mmstab.runs.recording`).
"""

from __future__ import annotations

import gc
import itertools
import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from mmstab.core.files import ConfigError
from mmstab.core.problem import Problem
from mmstab.planner.plan import unfreeze_long_lived
from mmstab.runs.arm_ground import in_ground_in_time
from mmstab.runs.online.follow import FollowSettings, FollowStep, build_follower
from mmstab.runs.online.horizon import HorizonPose
from mmstab.runs.online.roadmap_horizon import RoadmapHorizon
from mmstab.runs.online.stream import map_updates
from mmstab.runs.recording import RunFrames, joint_names
from mmstab.runs.tip_rule import first_tip
from mmstab.workspace import Workspace


@dataclass
class FollowRun:
    """A followed recording.

    Attributes:
        steps: the loop's answer to every map, in order.
        plans: the horizon's last plan of each route pose it planned, by grid index.
        skipped: maps received before any odometry (not followed).
        s_grid: arc lengths of the route's planned poses (K,) [m].
        friction: the tracks' friction on the ground [-] (the problem's terrain).
        arm_ground: the roadmap horizon's counts of the ground under the arm
            (:class:`~mmstab.runs.online.roadmap_horizon.RoadmapHorizon`); None: not checked.
    """

    steps: list[FollowStep]
    plans: dict[int, HorizonPose]
    skipped: int
    s_grid: np.ndarray
    friction: float
    arm_ground: dict[str, int] | None = None


def follow_recording(
    problem: Problem,
    path: str | os.PathLike[str],
    workspace: Workspace | None = None,
    limit: int | None = None,
) -> FollowRun:
    """Follow a recording's maps with the problem's robot, route and settings.

    Args:
        problem: a route problem (its ``online`` section names the topics).
        path: the recording (``.mcap``, ``.bag``, ROS 2 bag directory).
        workspace: V (default: loaded from its cache or built).
        limit: follow only the first ``limit`` maps.

    Raises:
        ConfigError: an unreadable recording, missing topics, bad maps, no map after any
            odometry (one line each).
    """
    skipped = [0]
    steps = []
    s = FollowSettings.of(problem)
    joints = None if s.joints_topic is None else (s.joints_topic, joint_names(problem.robot))
    updates = map_updates(path, s.map_topic, s.odom_topic, skipped, joints)
    # the first map read before V and the roadmap are built: a garbage recording or a missing
    # topic is refused at once (it took a workspace build, 20 s without a cache, before)
    first = list(itertools.islice(updates, 1))
    if not first:  # before the workspace and the roadmap are built, or anything written
        raise ConfigError(path, "odometry", "no map arrived after any odometry")
    follower = build_follower(problem, workspace)
    # the set-up's objects (V, the roadmap, CasADi's) out of the collector's full passes: one
    # such pass over them took 63 ms on a map of the rough route, now each scans the loop's own
    gc.collect()
    gc.freeze()
    try:
        for u in itertools.chain(first, updates):
            steps.append(follower.update(u))
            follower.spare()  # after the answer, as the node does
            if limit is not None and len(steps) >= limit:
                break
    finally:
        unfreeze_long_lived()
    h = follower.horizon
    if isinstance(h, RoadmapHorizon):  # the re-plans queued at the end land (replan_jobs)
        h.settle()
    counts = getattr(h, "arm_ground", None)
    return FollowRun(
        steps, dict(h.plans), skipped[0], h.s_grid, follower.friction,
        None if counts is None else dict(counts),
    )  # fmt: skip


def _stats(values: np.ndarray, scale: float = 1.0) -> dict[str, float]:
    v = np.asarray(values, dtype=float) * scale
    v = v[np.isfinite(v)]
    if not len(v):
        return {"p50": float("nan"), "p99": float("nan"), "max": float("nan"), "mean": float("nan")}
    return {
        "p50": float(np.percentile(v, 50)),
        "p99": float(np.percentile(v, 99)),
        "max": float(v.max()),
        "mean": float(v.mean()),
    }


def summarize(run: FollowRun) -> dict[str, Any]:
    """The run's numbers (module text); everything but the latencies is deterministic.

    ``latency_ms``: from each map to its answer (the command and the verdicts);
    ``command_latency_ms``: to the command alone.

    ``slides``: the first map on which the robot's support tilts beyond atan(friction) (the
    slip limit, :mod:`mmstab.stability.slip`), or None. ``arm_in_ground``:
    :func:`arm_in_ground`.
    """
    st = run.steps
    if not st:
        return {"updates": 0, "skipped_maps": run.skipped}
    mu = np.array([x.mu for x in st])
    covered = np.array([x.covered for x in st])
    ahead = np.array([x.covered_ahead for x in st])
    status = np.array([x.status for x in st])
    # the runs' tip rule: μ < 0 that no rock catches, for TIP_HOLD on end (or to the end)
    tip = first_tip(
        np.array([x.time for x in st]), [x.covered and x.mu < 0 and not x.rocks for x in st]
    )
    tilt = np.array([x.tilt for x in st])
    critical = float(np.arctan(run.friction))
    sliding = [x for x in st if x.covered and x.tilt > critical]
    return {
        "updates": len(st),
        "skipped_maps": run.skipped,
        "time_s": [st[0].time, st[-1].time],
        "progress_m": [st[0].s, st[-1].s],
        "latency_ms": _stats(np.array([x.latency for x in st]), 1e3),
        "command_latency_ms": _stats(np.array([x.command_latency for x in st]), 1e3),
        "arm_posture": "measured" if any(x.measured for x in st) else "integrated",
        "replanned_poses": int(sum(x.replanned for x in st)),
        "updates_with_replan": int(sum(x.replanned > 0 for x in st)),
        "robot_not_covered_updates": int((~covered).sum()),
        "horizon_uncovered_updates": int(sum(x.uncovered > 0 for x in st)),
        "covered_ahead_m": {"min": float(ahead.min()), "median": float(np.median(ahead))},
        # null (JSON has no NaN) when no map covered the robot
        "mu_min": float(np.nanmin(mu)) if covered.any() else None,
        "mu_min_at": _lowest(run) if covered.any() else None,
        "mu_planned_min": float(min(p.mu for p in run.plans.values())) if run.plans else None,
        "planned_poses": len(run.plans),
        "planned_collision_free": int(sum(p.collision_free for p in run.plans.values())),
        "qp_failures": int((status != 0).sum()),
        "arm_ground": run.arm_ground,
        "tipped": None if tip is None else {"time_s": st[tip].time, "s_m": st[tip].s},
        "tilt_max_rad": float(np.nanmax(tilt)) if covered.any() else None,
        "friction": run.friction,
        "slides": None
        if not sliding
        else {
            "time_s": sliding[0].time,
            "s_m": sliding[0].s,
            "tilt_rad": sliding[0].tilt,
            "critical_tilt_rad": critical,
            "maps": len(sliding),
        },
        "arm_in_ground": arm_in_ground(st),
    }


def arm_in_ground(steps: list[FollowStep]) -> dict[str, Any]:
    """Where the arm, as it was at a map, was in that map's ground at the robot's rest there.

    ``track``'s record (:func:`mmstab.runs.arm_ground.in_ground_in_time`) over the covered
    maps' states (``samples``: those maps).
    """
    st = [x for x in steps if x.covered]
    h = np.array([x.arm_height for x in st], dtype=float)
    return in_ground_in_time(h, np.array([x.time for x in st], dtype=float))


def _lowest(run: FollowRun) -> dict[str, Any]:
    """Where the loop's lowest μ was: the map, its time [s], progress [m], the grid poses about it.

    ``mu_min`` is over every covered map (the state then, on that map): a rigid base on rough
    ground changes its loaded contacts within centimetres, so it lies between the planned
    poses ``mu_planned_min`` is taken over (``planner.spacing`` apart), as a rule.
    """
    mu = np.array([x.mu for x in run.steps])
    i = int(np.nanargmin(mu))
    x = run.steps[i]
    after = int(np.searchsorted(run.s_grid, x.s, side="right"))
    return {
        "map": i,
        "time_s": x.time,
        "s_m": x.s,
        "between_poses": [after - 1, after] if 0 < after < len(run.s_grid) else [after - 1],
        "mu_planned": x.mu_planned,
    }


def run_frames(run: FollowRun) -> RunFrames:
    """The covered updates as a recording's frames (the resting pose, posture, μ, polygon)."""
    st = [x for x in run.steps if x.covered]
    return RunFrames(
        np.array([x.time for x in st]),
        np.array([x.G_T_B for x in st]).reshape(-1, 4, 4),
        np.array([x.q for x in st]),
        np.array([x.mu for x in st]),
        [x.polygon for x in st],
    )
