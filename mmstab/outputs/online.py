"""``mmstab follow`` / ``make online``: a recording followed online, beside the offline plan.

Writes to the output folder: ``summary.json`` (the run's numbers, the settings, the
comparison with the offline plan), ``online.mcap`` (the run as a recording: joint states,
TF, μ, the support polygon coloured by μ; :mod:`mmstab.runs.recording`) and ``online.png``
(μ along the route, online and offline; the latency per map), and the run in the form of a
tracking run (``run.npz`` and ``problem.yaml``, :mod:`mmstab.runs.store`), so that the
browser viewer replays it: ``mmstab view PROBLEM --run OUT``.

The offline plan is the same planner over the same route poses on the problem's own
terrain, all poses at once: ``method: roadmap`` with the ground under the arm (as ``mmstab
plan`` runs it) for ``online.planner: roadmap``, the warm-started CMA-ES
(:func:`mmstab.planner.along_route.solve_route`) for ``warm``.
A pose's online answer is compared with it where the map **agrees** with that terrain
(the resting gravity in B on the map within ``online.replan_tol`` of the offline one).
"""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from mmstab.app.settings import Settings
from mmstab.core.files import ConfigError, MmstabError, write_figure, write_json, write_npz
from mmstab.core.problem import Problem
from mmstab.outputs.common import save_settings
from mmstab.planner.along_route import solve_route
from mmstab.planner.fitness import support_polygons_at
from mmstab.planner.plan import problem_region
from mmstab.runs.arm_ground import arm_heights_at_rest, in_ground_in_time
from mmstab.runs.online.follow import FollowSettings
from mmstab.runs.online.horizon import angle_between
from mmstab.runs.online.run import FollowRun, follow_recording, run_frames, summarize
from mmstab.runs.recording import write_run
from mmstab.stability.static import mu_max as stowed_flat_mu
from mmstab.stability.static import robot_force_angle
from mmstab.stability.support import loaded_mu
from mmstab.workspace import Workspace

#: Relative μ difference the issue allows where the map agrees [-].
MU_AGREEMENT = 0.02


class OfflinePlan(NamedTuple):
    """The offline plan at the run's planning grid, for the comparison.

    Attributes:
        s: arc lengths of the planned poses (K,) [m].
        poses: the poses (K, 3) [m, m, rad].
        mu_planned: μ of the planned posture (K,) [N rad].
        mu_stowed: μ with the arm stowed (K,) [N rad].
        search_seconds: wall time of the search per pose [s] (K,).
        postures: the planned postures (K, 4) [rad] (None: not kept).
    """

    s: np.ndarray
    poses: np.ndarray
    mu_planned: np.ndarray
    mu_stowed: np.ndarray
    search_seconds: np.ndarray
    postures: np.ndarray | None = None


def offline_plan(problem: Problem, run: FollowRun, workspace: Workspace | None) -> OfflinePlan:
    """The offline plan on the problem's terrain at the route poses the run planned.

    With the same planner as the online loop (``online.planner``): all poses at once on
    the posture roadmap (``method: roadmap``), or warm-started CMA-ES pose after pose. Its
    μ is the search's own (each pose's support polygon at the stowed arm's rest), the basis
    the online horizon plans on, so the two plans compare like with like.
    """
    from mmstab.workspace.ik import PostureSolver

    route = problem.route
    assert route is not None
    ws, region = problem_region(problem, workspace, False)
    settings = Settings.from_problem(problem).planner
    s = run.s_grid
    poses = route.route.sample(s).pose
    robot = problem.robot
    if FollowSettings.of(problem).planner == "roadmap":
        from mmstab.planner.ground.under_arm import GroundUnderArm
        from mmstab.planner.searches.roadmap import solve_roadmap_sequence
        from mmstab.workspace.roadmap import load_or_build_roadmap

        gravity = problem.terrain.gravity_body(poses)
        roadmap = load_or_build_roadmap(robot, ws)
        margin = settings.attitude_margin or 0.0
        under = None  # the ground under the arm, as method roadmap checks it on a route
        if settings.ground_clearance is not None:
            under = GroundUnderArm(robot, problem.terrain, poses, margin=margin)
        polygons = support_polygons_at(robot, problem.terrain, poses)
        seq = solve_roadmap_sequence(
            robot, gravity, roadmap, settings, stowed_flat_mu(robot), False, poses, under=under,
            polygons=polygons,
        )  # fmt: skip
        stowed = loaded_mu(robot, problem.terrain, poses, robot.arm_com(robot.stowed))
        per_pose = np.full(len(s), seq.seconds / len(s))
        return OfflinePlan(s, poses, seq.mu, stowed, per_pose, seq.postures)
    settings = settings._replace(method="cmaes", seeding="coarse")
    realise = PostureSolver(robot, ws).realise
    plan = solve_route(robot, problem.terrain, region, s, poses, settings, realise)
    return OfflinePlan(s, poses, plan.mu_search, plan.mu_stowed, plan.search_seconds)


def compare(
    run: FollowRun, offline: OfflinePlan, gravity: np.ndarray, tol: float
) -> dict[str, Any]:
    """Online against offline μ per planned pose, where the map agrees (module text).

    Args:
        run: the online run.
        offline: the offline plan at the run's planning grid.
        gravity: gravity in B at those poses on the problem's terrain (K, 3) [m/s^2].
        tol: the largest angle between the map's and the terrain's gravity that agrees [rad].
    """
    rows = []
    for k, p in sorted(run.plans.items()):
        agrees = angle_between(p.gravity_body, gravity[k]) <= tol
        mu_off = float(offline.mu_planned[k])
        rows.append((k, p.s, p.mu, mu_off, abs(p.mu - mu_off) / abs(mu_off), agrees))
    rel = np.array([r[4] for r in rows if r[5]])
    return {
        "poses": len(rows),
        "agreeing_poses": int(len(rel)),
        "relative_difference": {
            "median": float(np.median(rel)) if len(rel) else None,
            "max": float(rel.max()) if len(rel) else None,
            "within_2_percent": float((rel <= MU_AGREEMENT).mean()) if len(rel) else None,
        },
        "per_pose": [
            {"k": k, "s_m": s, "mu_online": a, "mu_offline": b, "relative": r, "map_agrees": g}
            for k, s, a, b, r, g in rows
        ],
    }


class AlongRoute(NamedTuple):
    """μ at the covered maps' states (n,) [N rad], on their maps and on the true ground.

    Attributes:
        time: the maps' times [s].
        s: the robot's progress [m].
        mu_map: the loop's μ (the state on its map).
        mu_true: the same states on the problem's terrain.
        mu_offline: the offline plan at the same poses on it, the worse of the two planned
            postures about ``s`` (None: its postures not kept).
    """

    time: np.ndarray
    s: np.ndarray
    mu_map: np.ndarray
    mu_true: np.ndarray
    mu_offline: np.ndarray | None


def along_states(
    problem: Problem, run: FollowRun, offline: OfflinePlan | None = None
) -> AlongRoute | None:
    """:class:`AlongRoute` of a run (None: no covered map); :func:`along_route` tells it."""
    st = [x for x in run.steps if x.covered and np.isfinite(x.mu)]
    if not st:
        return None
    robot = problem.robot
    poses = np.array([x.pose for x in st])
    q = np.array([x.q for x in st])
    s = np.array([x.s for x in st])
    mu_true = loaded_mu(robot, problem.terrain, poses, robot.arm_com(q), q, strict=False)
    worse = None
    if offline is not None and offline.postures is not None and len(offline.s) > 1:
        after = np.clip(np.searchsorted(offline.s, s, side="right"), 1, len(offline.s) - 1)
        worse = np.full(len(st), np.inf)
        for k in (after - 1, after):
            qk = offline.postures[k]
            mu_k = loaded_mu(robot, problem.terrain, poses, robot.arm_com(qk), qk, strict=False)
            worse = np.fmin(worse, mu_k)
    return AlongRoute(
        np.array([x.time for x in st]), s, np.array([x.mu for x in st]), mu_true, worse
    )


def along_route(
    problem: Problem, run: FollowRun, offline: OfflinePlan | None = None
) -> dict[str, Any] | None:
    """μ along the way on the true ground: the loop's states, and the offline plan there.

    The loop's μ (``mu_min``) is each covered map's state (the odometry pose, the arm's
    posture then) on that map; ``mu_planned_min`` only the planned poses' (``planner.spacing``
    apart). Here the same states rest on the problem's own terrain (one state, one μ: the
    difference is the map's), and the offline plan is taken at the same poses with the arm in
    the two planned postures it moves between (the worse counts; ``offline_plan``, when its
    postures are kept). None: no covered map.

    Args:
        problem: the followed problem (its terrain: the true ground).
        run: the online run.
        offline: the offline plan on the run's planning grid.
    """
    a = along_states(problem, run, offline)
    return None if a is None else along_summary(a)


def along_summary(a: AlongRoute) -> dict[str, Any]:
    """``summary.json``'s ``along_route`` (:func:`along_route`)."""

    def at(i: int, **more: float) -> dict[str, Any]:
        return {
            "time_s": float(a.time[i]),
            "s_m": float(a.s[i]),
            **{k: float(v) for k, v in more.items()},
        }

    i, j = int(np.argmin(a.mu_map)), int(np.nanargmin(a.mu_true))
    diff = a.mu_map - a.mu_true
    out: dict[str, Any] = {
        "maps": len(a.s),
        "lowest_on_map": at(i, mu_map=a.mu_map[i], mu_true_ground=a.mu_true[i]),
        "lowest_on_true_ground": at(j, mu_true_ground=a.mu_true[j], mu_map=a.mu_map[j]),
        "map_minus_true_ground": {
            "median": float(np.nanmedian(diff)),
            "p5": float(np.nanpercentile(diff, 5)),
            "p95": float(np.nanpercentile(diff, 95)),
        },
    }
    if a.mu_offline is not None:
        m = int(np.nanargmin(a.mu_offline))
        out["offline_plan"] = at(m, mu_true_ground=a.mu_offline[m])
    return out


def arm_heights_covered(problem: Problem, run: FollowRun) -> tuple[np.ndarray, ...]:
    """The covered maps' times [s] and the arm's least heights there [m], on two grounds.

    On the map, as the loop measured them, and with each state rested on the problem's own
    terrain (the true ground). The map's noise and unknown cells move the state's rest (a
    rigid base rocks onto other contacts within centimetres); the true ground's says what the
    ground did.
    """
    st = [x for x in run.steps if x.covered]
    poses, q = np.array([x.pose for x in st]), np.array([x.q for x in st])
    h_true = arm_heights_at_rest(problem.robot, problem.terrain, poses, q)
    return np.array([x.time for x in st]), np.array([x.arm_height for x in st]), h_true


def arm_in_ground_true(problem: Problem, run: FollowRun) -> dict[str, Any]:
    """The run's ``arm_in_ground`` on the true ground (:func:`arm_heights_covered`)."""
    t, _, h_true = arm_heights_covered(problem, run)
    return in_ground_in_time(h_true, t)


def run_follow(
    problem: Problem,
    recording: str | os.PathLike[str],
    out: str | os.PathLike[str],
    limit: int | None = None,
    workspace: Workspace | None = None,
) -> dict[str, Any]:
    """Follow ``recording`` and write the folder's files (module text); return the summary."""
    out = Path(out)
    t0 = time.perf_counter()
    run = follow_recording(problem, recording, workspace, limit)
    wall = time.perf_counter() - t0
    if not run.steps:  # bad input, refused before anything is written
        raise ConfigError(recording, "odometry", "no map arrived after any odometry")
    summary = summarize(run)
    settings = FollowSettings.of(problem)
    summary["wall_seconds"] = wall
    summary["recording"] = str(recording)
    summary["settings"] = {
        "online": problem.section("online"),
        "planner": problem.section("planner"),
    }
    offline = None
    if run.plans:
        t1 = time.perf_counter()
        offline = offline_plan(problem, run, workspace)
        gravity = problem.terrain.gravity_body(offline.poses)
        summary["offline"] = compare(run, offline, gravity, settings.replan_tol)
        summary["offline"]["seconds_per_pose"] = float(np.median(offline.search_seconds))
        summary["offline"]["wall_seconds"] = time.perf_counter() - t1
    along = along_states(problem, run, offline)
    summary["along_route"] = None if along is None else along_summary(along)
    if along is not None:  # the arm as the loop had it, at the same states' true rests
        summary["along_route"]["arm_in_ground"] = arm_in_ground_true(problem, run)
    if offline is not None:
        _figure(out / "online.png", run, offline, along)
        _snapshot(out / "online_map.png", problem, run, recording)
    frames = run_frames(run)
    if len(frames.t):
        write_run(out / "online.mcap", problem.robot, frames, stowed_flat_mu(problem.robot))
        write_replay(out, problem, run)
    write_json(out / "summary.json", summary)
    return summary


def write_replay(out: Path, problem: Problem, run: FollowRun) -> None:
    """The covered updates as a stored run that the viewer replays (module text).

    Per covered map: the odometry pose, the track angles the commands integrate to (the loop
    knows no measured ones), the arm's posture, and μ with the arm as it was (the loop's
    one μ: that state's loaded contacts on that map), stowed and removed (the tracks'
    rectangle at the map's stowed rest; what the loop saw, not the true ground);
    the planned poses' arm CoMs at their share of the route.
    """
    st = [x for x in run.steps if x.covered]
    t = np.array([x.time for x in st])
    gravity = np.array([x.gravity_body for x in st])
    robot = problem.robot
    q = np.array([x.q for x in st])
    dt = np.diff(np.concatenate([[t[0]], t]))
    tracks = np.cumsum(np.array([x.qdot[:2] for x in st]) * dt[:, None], axis=0)
    state = np.column_stack([np.array([x.pose for x in st]), tracks, q])
    ks = sorted(run.plans)
    route = problem.route
    assert route is not None  # follow needs a route
    write_npz(
        out / "run.npz",
        t=t,
        state=state,
        mu_reconfigured=np.array([x.mu for x in st]),
        mu_stowed=robot_force_angle(robot, gravity, robot.arm_com(robot.stowed)).mu,
        mu_arm_removed=robot_force_angle(robot, gravity, None).mu,
        plan_fractions=route.fraction_of_s([run.plans[k].s for k in ks]),
        plan_target_com=np.array([run.plans[k].target_com for k in ks]).reshape(-1, 3),
    )
    save_settings(out, problem, online_replay=True)


def _figure(path: Path, run: FollowRun, offline: OfflinePlan, along: AlongRoute | None) -> None:
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 3.6))
    s = np.array([x.s for x in run.steps])
    a.plot(s, [x.mu for x in run.steps], lw=1, label="online: mu now (posture now, its map)")
    if along is not None:
        a.plot(along.s, along.mu_true, lw=0.8, alpha=0.8, label="the same states, true ground")
        if along.mu_offline is not None:
            a.plot(along.s, along.mu_offline, lw=0.8, alpha=0.8,
                   label="offline plan there (worse posture)")  # fmt: skip
    ks = sorted(run.plans)
    a.plot([run.plans[k].s for k in ks], [run.plans[k].mu for k in ks], "o", ms=3,
           label="online: planned")  # fmt: skip
    a.plot(offline.s, offline.mu_planned, "-", lw=1, label="offline plan (planned poses)")
    a.plot(offline.s, offline.mu_stowed, ":", lw=1, label="arm stowed")
    a.set(xlabel="route progress s [m]", ylabel="mu [N rad]", title="stability along the route")
    a.legend(fontsize=7)
    lat = np.array([x.latency for x in run.steps]) * 1e3
    b.hist(lat, bins=40)
    b.axvline(np.percentile(lat, 50), color="k", lw=1, label=f"p50 {np.percentile(lat, 50):.1f} ms")
    b.axvline(np.percentile(lat, 99), color="r", lw=1, label=f"p99 {np.percentile(lat, 99):.1f} ms")
    b.set(xlabel="map to answer [ms]", ylabel="maps", title="rest, re-plan, step, verdicts")
    b.legend(fontsize=7)
    fig.tight_layout()
    write_figure(path, fig)


def _snapshot(
    path: Path, problem: Problem, run: FollowRun, recording: str | os.PathLike[str]
) -> None:
    """The robot on its map at the middle covered update: what the loop saw and planned.

    The map as the recording held it (unknown cells left out), the robot at its odometry
    pose rested on it with the arm as it was (support polygon drawn), and the horizon's
    planned poses ahead as ghosts with their planned postures.
    """
    import matplotlib.pyplot as plt

    from mmstab.runs.online.follow import FollowSettings
    from mmstab.terrain.heightmap_terrain import HeightmapTerrain
    from mmstab.terrain.recording import load_grid_map
    from mmstab.viz.drawing import draw_robot, set_equal_aspect

    covered = [x for x in run.steps if x.covered]
    if not covered:
        return
    step = covered[len(covered) // 2]
    topic = FollowSettings.of(problem).map_topic
    grid = load_grid_map(recording, topic, step.time)
    hm, robot = grid.heightmap, problem.robot
    terrain = HeightmapTerrain(hm).with_robot(robot)
    fig = plt.figure(figsize=(9, 6), constrained_layout=True)
    ax = fig.add_subplot(1, 1, 1, projection="3d")
    ax.computed_zorder = False
    ny, nx = hm.shape
    x = hm.origin[0] + hm.resolution * np.arange(nx)
    y = hm.origin[1] + hm.resolution * np.arange(ny)
    X, Y = np.meshgrid(x, y)
    Z = np.ma.masked_invalid(hm.elevation)
    ax.plot_surface(X, Y, Z, cmap="terrain", alpha=0.8, linewidth=0, antialiased=False, zorder=0)
    draw_robot(ax, robot, step.q, terrain.with_robot(robot, arm_q=step.q).G_T_B(step.pose),
               support=True)  # fmt: skip
    ahead = [p for p in run.plans.values() if step.s < p.s <= step.s + 2.0]
    for p in ahead:
        try:
            T = terrain.G_T_B(p.pose)
        except MmstabError:  # a pose the map does not cover (OffMapError): not drawn
            continue
        draw_robot(ax, robot, p.q, T, alpha=0.25)
    finite = np.isfinite(hm.elevation)
    set_equal_aspect(ax, np.column_stack([X[finite], Y[finite], hm.elevation[finite]]))
    ax.view_init(elev=40, azim=-60)
    ax.set(xlabel="x [m]", ylabel="y [m]", zlabel="z [m]")
    ax.set_title(
        f"map at {step.time:.1f} s (s = {step.s:.2f} m): the robot now (mu {step.mu:.0f} N rad) "
        f"and the horizon's planned poses ahead",
        fontsize=9,
    )
    write_figure(path, fig)
