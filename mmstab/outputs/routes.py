"""Routes over rough ground (``docs/routes.md``): the plan along a route and its figures.

``mmstab plan PROBLEM`` on a route problem writes, in its output folder:

- ``summary.json``: ``mu_planned``, ``mu_stowed``, ``mu_removed`` (lists over the planned
  poses [N rad]), ``s`` (their arc lengths [m]), ``risk`` (the stretches below
  ``planner.margin``, and those where only the stowed arm is), ``ms_per_pose`` (median
  wall time of a warm-started pose's search; ``cpu_ms_per_pose`` its CPU time, less
  sensitive to a shared machine), ``route`` (length, which includes the pivot turns' track
  travel, duration, and how it turns at each corner: ``corners``, ``pivots``, the route
  check's lines; ``time_law``: the turns slowed so that they do not slide, each corner's
  yaw rate before and after, ``slowed_turns`` its lines, :mod:`mmstab.runs.time_law`),
  the per-pose details and the stability verdict, and
  ``quality``: per pose the planned μ, the best μ over V's samples and (``method:
  roadmap``) over the roadmap's reachable postures, and the gaps (:func:`route_quality`);
- ``route_mu.png``: μ along the route, planned / stowed / arm removed, the margin and the
  risk stretches shaded;
- ``route_3d.png``: the terrain, the route and the robot at rest with its planned posture
  at snapshots along the way;
- ``plan.mcap``: the plan as a recording for Foxglove/RViz (the resting pose and posture
  at each planned pose at its time on the route; :mod:`mmstab.runs.recording`).

The tracking run of a route is ``mmstab track`` (:mod:`mmstab.outputs.tracking`, the
same figures as the ramp's run).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from mmstab.app import plan as make_plan
from mmstab.app.settings import Settings
from mmstab.core.files import MmstabError, write_figure, write_json
from mmstab.core.problem import Problem
from mmstab.outputs.common import output_dir, route_corners, save_settings
from mmstab.planner import RoutePlan, RouteRisk, route_risk
from mmstab.runs.along import Along
from mmstab.runs.plan_verdicts import arm_path_check, route_verdicts
from mmstab.runs.plan_verdicts import plan_along as robot_plan_along
from mmstab.runs.recording import frames_at, write_run
from mmstab.runs.time_law import describe_time_law
from mmstab.stability.static import mu_max

#: Robot snapshots drawn in the 3-D figure.
SNAPSHOTS = 6


def plan_along(problem: Problem, plan: RoutePlan) -> Along:
    """The route rested every few cm with the planned arm (:func:`mmstab.runs.along.along_path`)."""
    route = problem.following(plan).route
    if route is None:
        raise MmstabError(f"{problem.path}: path: not a route")
    return robot_plan_along(problem.robot, problem.terrain, route, plan)


def route_summary(
    problem: Problem, plan: RoutePlan, risk: RouteRisk, along: Along | None = None
) -> dict[str, Any]:
    """The numbers of a route plan (``summary.json``); ``along``: :func:`plan_along`'s.

    The verdicts are :func:`mmstab.runs.plan_verdicts.route_verdicts`' (what
    :func:`mmstab.plan` returns).
    """
    robot = problem.robot
    problem = problem.following(plan)  # its turns slowed where they would slide
    route = problem.route
    if route is None:
        raise MmstabError(f"{problem.path}: path: not a route")
    settings = Settings.from_problem(problem)
    arm_path = arm_path_check(robot, plan, route.lap_time, settings.controller.dt)
    v = route_verdicts(robot, problem.terrain, route, plan, settings.verdicts, along, arm_path)
    mu_realised = v["mu_realised"]
    poses = [
        {
            "s": float(plan.s[k]),
            "fraction": float(plan.fractions[k]),
            "pose": plan.poses[k],
            "target_com": plan.target_com[k],
            "posture": plan.postures[k],
            "realised_com_error_m": float(plan.realised_com_error[k]),
            "collision_free": bool(plan.collision_free[k]),
            "fallback": bool(plan.targets[k].fallback),
            "mu_planned": float(plan.mu_planned[k]),
            "mu_realised": float(mu_realised[k]),
            "mu_stowed": float(plan.mu_stowed[k]),
            "mu_arm_removed": float(plan.mu_removed[k]),
            "fitness": float(plan.targets[k].fitness),
            "warm": bool(plan.warm[k]),
            "guard_start": bool(plan.guarded[k]),
            "search_ms": float(1e3 * plan.search_seconds[k]),
        }
        for k in range(len(plan.s))
    ]
    warm = plan.search_seconds[plan.warm] if plan.warm.any() else plan.search_seconds
    warm_cpu = plan.search_cpu_seconds[plan.warm] if plan.warm.any() else plan.search_cpu_seconds
    out: dict[str, Any] = {
        "route": {
            "length_m": route.length,
            "duration_s": route.duration,
            "max_curvature_per_m": route.route.max_curvature,
            "speed_max_m_s": float(route.profile.v.max()),
            **route_corners(problem),
            "time_law": plan.time_law or {},
            "slowed_turns": describe_time_law(plan.time_law or {}),
        },
        "mu_max": mu_max(robot),
        "s": plan.s.tolist(),
        "mu_planned": plan.mu_planned.tolist(),
        "mu_stowed": plan.mu_stowed.tolist(),
        "mu_removed": plan.mu_removed.tolist(),
        "planned_minus_stowed_min": float(np.min(plan.mu_planned - plan.mu_stowed)),
        "risk": {
            "margin": risk.margin,
            "below_margin": [r._asdict() for r in risk.below_margin],
            "saved_by_planning": [r._asdict() for r in risk.saved_by_planning],
            "slides": v["slides"],
        },
        "ms_per_pose": float(1e3 * np.median(warm)),
        "ms_per_pose_max": float(1e3 * np.max(warm)),
        "ms_first_pose": float(1e3 * plan.search_seconds[0]),
        "cpu_ms_per_pose": float(1e3 * np.median(warm_cpu)),
        "warm_started": bool(plan.warm.any()),
        "fixed_seconds": float(plan.fixed_seconds),
        "settings": plan.settings._asdict(),
        "poses": poses,
        "stability": v["stability"],
        "slip": v["slip"],
        "climb": v["climb"],
        "high_centred": v["high_centred"],
        "along_path": v["along_path"],
        "verdicts": v["verdicts"],
        **({"arm_path": v["arm_path"]} if "arm_path" in v else {}),
        "turn_slide": {
            "limit_m": plan.settings.turn_slide,
            "turns": [
                t | {"start_s": float(plan.s[t["first"]]), "end_s": float(plan.s[t["last"]])}
                for t in plan.turns
            ],
        },  # fmt: skip
    }
    return out


def route_quality(problem: Problem, plan: RoutePlan) -> dict[str, Any]:
    """Per pose: the searched μ, the best μ over V's samples and the roadmap's reachable ones.

    All on the basis the search ranks arm CoMs on (each pose's support polygon at the
    stowed arm's rest), so the gap is the search's own.

    The optima are exhaustive (every sample scored at the pose, :func:`mmstab.planner.best_mu`);
    the roadmap's (its nodes in the stowed arm's component, :mod:`mmstab.workspace.roadmap`,
    that clear the ground by ``planner.ground_clearance``) only with ``method: roadmap``, and
    then also over V's samples that clear it as well (``mu_optimum_V_clear``: the same
    exhaustive reference among the postures the plan may take; ``mu_optimum_V`` counts
    postures whose arm reaches below the support plane). The gap is
    ``(optimum − planned) / optimum`` [-]: the price of the motion term and of
    the path's constraints (negative where the plan beats V: roadmap nodes need not lie in
    V's hull difference).
    """
    from mmstab.planner import best_mu, gravity_body_at, planning_region, region_samples
    from mmstab.planner.fitness import support_polygons_at
    from mmstab.workspace import load_or_build_workspace

    ws = load_or_build_workspace(problem, progress=False)
    region = planning_region(ws, Settings.from_problem(problem).workspace.method)
    samples = region_samples(region)
    gravity = gravity_body_at(problem.terrain, plan.poses)
    robot = problem.robot
    polygons = support_polygons_at(robot, problem.terrain, plan.poses)
    polys: list[Any] = [None] * len(gravity) if polygons is None else polygons

    def optima(coms: Any) -> Any:
        return np.array(
            [best_mu(robot, g, coms, p)[0] for g, p in zip(gravity, polys, strict=True)]
        )

    opt_v = optima(samples)
    # the planned CoMs on that basis too: where the roadmap ranked a pose on the one μ
    # (mmstab.planner.searches.roadmap.OneMu) its ``mu_search`` is not on it
    searched = np.array([
        best_mu(robot, g, c[None], p)[0]
        for g, c, p in zip(gravity, plan.target_com, polys, strict=True)
    ])  # fmt: skip
    out: dict[str, Any] = {"mu_searched": searched.tolist(), "mu_optimum_V": opt_v.tolist()}
    gaps = {"V": (opt_v - searched) / np.abs(opt_v)}
    if plan.settings.method == "roadmap":
        from mmstab.planner.searches.roadmap import node_coms
        from mmstab.workspace.roadmap import load_or_build_roadmap

        rm = load_or_build_roadmap(robot, ws)
        start = rm.connect(robot.stowed, robot)
        reach = rm.component == rm.component[start]
        if plan.settings.ground_clearance is not None:  # the nodes the planner may choose
            reach &= rm.node_ground >= plan.settings.ground_clearance
        reach = node_coms(robot, rm)[reach]
        opt_r = optima(reach)
        out["mu_optimum_roadmap"] = opt_r.tolist()
        gaps["roadmap"] = (opt_r - searched) / np.abs(opt_r)
        if plan.settings.ground_clearance is not None:
            from mmstab.model.plane_clearance import arm_ground_clearance

            low = arm_ground_clearance(robot, region.postures) < plan.settings.ground_clearance
            clear = samples[~low]
            opt_c = optima(clear)
            out["mu_optimum_V_clear"] = opt_c.tolist()
            gaps["V_clear"] = (opt_c - searched) / np.abs(opt_c)
    for name, gap in gaps.items():
        out[f"gap_to_{name}"] = gap.tolist()
        out[f"gap_to_{name}_median"] = float(np.median(gap))
        out[f"gap_to_{name}_worst"] = float(np.max(gap))
    return out


def run_route_plan(
    problem: Problem, out: str | Path | None = None, verify: bool = False
) -> dict[str, Any]:
    """Plan the problem's route, write the summary and the two figures (module docstring).

    ``verify``: then run the plan in MuJoCo (:func:`mmstab.outputs.verify.verify_plan`,
    into ``verify/``) and put its outcome beside the plan's verdict (``summary["verify"]``).
    """
    plan = make_plan(problem)
    if not isinstance(plan, RoutePlan):
        raise MmstabError(f"{problem.path}: path: not a route")
    problem = problem.following(plan)  # the route timed with its slowed turns
    risk = route_risk(plan, Settings.from_problem(problem).verdicts.margin)
    d = output_dir(out, "plan")
    along = plan_along(problem, plan)
    summary = route_summary(problem, plan, risk, along)
    summary["quality"] = route_quality(problem, plan)
    write_figure(d / "route_mu.png", draw_route_mu(problem, plan, risk, along, summary))
    write_figure(d / "route_3d.png", draw_route_3d(problem, plan))
    t = plan.fractions * problem.route.lap_time if problem.route is not None else plan.s
    frames = frames_at(
        problem.terrain, problem.robot, t, plan.poses, plan.postures, plan.mu_planned
    )
    write_run(d / "plan.mcap", problem.robot, frames, mu_max(problem.robot))
    save_settings(d, problem)
    if verify:
        from mmstab.outputs.verify import verify_plan

        summary["verify"] = verify_plan(problem, plan, summary, d / "verify")
    write_json(d / "summary.json", summary)
    return summary


def shade_stretches(ax: Any, risk: RouteRisk, spacing: float) -> None:
    """Shade the risk stretches on an axis of arc length [m] (half a spacing either side)."""
    half = spacing / 2
    for i, r in enumerate(risk.below_margin):
        label = "planned below the margin" if i == 0 else None
        ax.axvspan(r.start_s - half, r.end_s + half, color="C3", alpha=0.25, lw=0, label=label)
    for i, r in enumerate(risk.saved_by_planning):
        label = "stowed below the margin, planned not" if i == 0 else None
        ax.axvspan(r.start_s - half, r.end_s + half, color="C1", alpha=0.18, lw=0, label=label)


def draw_route_mu(
    problem: Problem,
    plan: RoutePlan,
    risk: RouteRisk,
    along: Along | None = None,
    summary: dict[str, Any] | None = None,
) -> Any:
    """μ along the route: planned, stowed, arm removed, the margin, the risk stretches.

    With ``along`` and ``summary``: μ every few cm between the poses (the worse planned
    posture) and, marked over the plot, where each limit binds (``summary["verdicts"]``).
    """
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 4.2), constrained_layout=True)
    spacing = float(np.median(np.diff(plan.s))) if len(plan.s) > 1 else 0.0
    shade_stretches(ax, risk, spacing)
    if along is not None:
        ax.plot(along.s, along.mu, "-", lw=0.8, color="C0", alpha=0.5,
                label="arm planned, every few cm")  # fmt: skip
    if summary is not None:
        mark_verdicts(ax, summary["verdicts"])
    ax.plot(plan.s, plan.mu_planned, "o-", ms=3, color="C0", label="arm planned")
    ax.plot(plan.s, plan.mu_stowed, "s:", ms=3, color="C2", label="arm stowed")
    ax.plot(plan.s, plan.mu_removed, "--", color="0.4", label="arm removed")
    ax.axhline(risk.margin, color="k", lw=0.9, ls="-.", label=f"margin {risk.margin:g} N rad")
    ax.set(
        xlabel="arc length along the route [m]",
        ylabel="force-angle stability $\\mu$ [N rad]",
        title=f"{problem.name}: stability along the route ({problem.terrain.label})",
    )
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, ncol=2)
    return fig


#: Colour of each limit's marks in the route figures.
LIMIT_COLOURS = {"tip": "red", "slide": "darkorange", "step": "purple",
                 "high_centred": "saddlebrown", "arm_contact": "magenta"}  # fmt: skip


def mark_verdicts(ax: Any, verdicts: dict[str, dict[str, Any]]) -> None:
    """Bars along the top of ``ax`` where each limit binds (arc lengths [m])."""
    lo, hi = ax.get_ylim()
    for row, (name, v) in enumerate(verdicts.items()):
        y = hi - (row + 1) * 0.04 * (hi - lo)
        for a, b in v["where"]:
            ax.plot(
                [a, max(b, a + 0.02)],
                [y, y],
                lw=4,
                color=LIMIT_COLOURS[name],
                solid_capstyle="butt",
            )
        if v["where"]:
            label = f" {name}: {v['verdict']}".replace("_", "-")
            ax.text(v["where"][0][0], y, label, fontsize=7, va="bottom", color=LIMIT_COLOURS[name])
    ax.set_ylim(lo, hi)


def draw_route_3d(problem: Problem, plan: RoutePlan) -> Any:
    """The terrain, the route and the robot at rest in its planned posture at snapshots."""
    import matplotlib.pyplot as plt

    from mmstab.viz.drawing import clip_to_ground, draw_path_on_ground, draw_robot, set_equal_aspect

    route = problem.route
    if route is None:
        raise MmstabError(f"{problem.path}: path: not a route")
    fig = plt.figure(figsize=(12, 5.6), constrained_layout=True)
    ax = fig.add_subplot(1, 1, 1, projection="3d")
    ax.computed_zorder = False  # the ground first, the robots over it
    path = route.route.sample(np.linspace(0, route.length, 400)).pose[:, :2]
    lo, hi = path.min(axis=0) - 0.6, path.max(axis=0) + 0.6  # the arm reaches past the path
    # cut to the map (the route's footprint is on it, so never empty: routes.path)
    e = clip_to_ground(problem.terrain, (lo[0], hi[0], lo[1], hi[1]))
    if e is None:  # pragma: no cover - ruled out when the route was loaded
        raise MmstabError(f"{problem.path}: path: the route is off the map")
    x, y = np.meshgrid(np.arange(e.x_min, e.x_max, 0.05), np.arange(e.y_min, e.y_max, 0.05))
    ground = problem.terrain.surface_G(x, y)
    ax.plot_surface(
        ground[..., 0],
        ground[..., 1],
        ground[..., 2],
        cmap="terrain",
        alpha=0.85,
        linewidth=0,
        antialiased=False,
        rstride=1,
        cstride=1,
        zorder=0,
    )
    draw_path_on_ground(ax, problem.terrain, path, color="k", linewidths=1.2)
    idx = np.unique(np.linspace(0, len(plan.s) - 1, SNAPSHOTS).round().astype(int))
    pts = []
    for k in idx:
        T = problem.terrain.G_T_B(plan.poses[k])
        q = plan.postures[k] if np.all(np.isfinite(plan.postures[k])) else problem.robot.stowed
        draw_robot(ax, problem.robot, q, T)
        pts.append(T[:3, 3])
        ax.text(*(T[:3, 3] + [0, 0, 0.7]), f"{plan.s[k]:.1f} m", fontsize=8, ha="center")
    set_equal_aspect(ax, np.vstack([np.array(pts), ground.reshape(-1, 3)]))
    ax.view_init(elev=35, azim=-70)
    ax.set(xlabel="$x_G$ [m]", ylabel="$y_G$ [m]", zlabel="$z_G$ [m]")
    ax.set_title(
        f"{problem.name}: route {route.length:.1f} m, robot at rest with the planned arm "
        f"({problem.terrain.label})",
        fontsize=9,
    )
    return fig
