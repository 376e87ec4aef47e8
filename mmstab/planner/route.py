"""The planner along a route (``docs/routes.md``): Eq. 6 at poses ``planner.spacing`` apart.

The base rests on the terrain at every pose (gravity in the body from
:meth:`Terrain.gravity_body`), so the support and the tipping direction change along the
way. Per pose:

- the first pose: :func:`mmstab.planner.path.solve_pose` with the problem's own search
  (cold start);
- every later pose **warm-started** from the previous pose's answer: CMA-ES starts at the
  previous target CoM, with a step size from how far the answer moved between the two
  poses before (``warm_sigma``), the population as one batch, ``WARM_ITERATIONS``
  iterations at most, the start itself kept as a candidate (never worse than staying);
  by default the compact CMA-ES of :mod:`mmstab.planner.warm` (pycma's set-up and
  per-iteration cost exceed a warm pose's budget), or ``search="solve_pose"``: the same
  starts and step size through :func:`~mmstab.planner.path.solve_pose` (pycma);
- a **guard** against a new basin the warm start cannot see (the best posture switching
  sides): a coarse batched pass of Eq. 6 over V's samples (the planner's ``coarse_*``
  settings, affine form); when its best refined sample beats the previous answer and lies
  away from it, it is a second start.

The motion term of Eq. 6 is taken relative to the previous pose's target (body frames of
consecutive poses), and the realised posture of the previous pose is handed to the IK of
the next (``realise(target, previous_q)``), so the arm moves the short way.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, Literal, NamedTuple, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.core.files import MmstabError
from mmstab.core.masks import true_runs
from mmstab.core.problem import Problem
from mmstab.model.robot import FloatArray, Robot
from mmstab.paths.route import DEFAULT_SPACING, route_samples
from mmstab.planner.exhaustive import SEED_SEPARATION, coarse_seeds, sample_index
from mmstab.planner.fitness import CoMRegion, Fitness, pose_fitness
from mmstab.planner.path import (
    REALISE_TOL,
    PoseTarget,
    fall_back_to_a_sample,
    gravity_body_at,
    solve_path,
    solve_pose,
    start_coms,
)
from mmstab.planner.regions import planning_region
from mmstab.planner.settings import PlannerSettings
from mmstab.planner.warm import warm_cma
from mmstab.stability.static import mu_max as stowed_flat_mu
from mmstab.stability.static import stability_along
from mmstab.terrain import Terrain

#: CMA-ES iterations of a warm-started pose (a cold start uses ``planner.max_iterations``).
WARM_ITERATIONS = 8
#: Smallest warm step size [m]: about the spacing of V's grid samples.
WARM_SIGMA_MIN = 0.01
Realise = Callable[[FloatArray, FloatArray], tuple[FloatArray, bool]]


class RoutePlan(NamedTuple):
    """The plan along a route.

    Attributes:
        s: arc length of each planned pose (K,) [m].
        fractions: the route's time fraction at each pose (K,) (the tracking references').
        poses: base poses (K, 3) of (x, y, yaw) in M.
        target_com: chosen arm CoMs, body frame (K, 3) [m].
        postures: arm postures realising them (K, 4) [rad] (NaN without IK).
        realised_com_error: |g_a(posture) - target| (K,) [m] (NaN without IK).
        collision_free: whether each posture is collision-free (K,).
        mu_planned: μ with the planned CoM (K,) [N rad].
        mu_stowed: μ with the arm stowed (K,) [N rad].
        mu_removed: μ with the arm removed (K,) [N rad].
        targets: the per-pose planner results.
        warm: whether each pose was warm-started (K,).
        guarded: whether the coarse guard added a second start (K,).
        search_seconds: wall time of the search per pose [s]: guard, CMA-ES and an equal
            share of the batched resting poses (not the IK).
        search_cpu_seconds: the same in CPU time of this process [s] (less sensitive to
            other processes on a shared machine).
        settings: the planner settings.
        moves: ``method: roadmap``: the roadmap path into each pose's posture (K arrays
            (n, 4) [rad]), else empty.
    """

    s: FloatArray
    fractions: FloatArray
    poses: FloatArray
    target_com: FloatArray
    postures: FloatArray
    realised_com_error: FloatArray
    collision_free: NDArray[np.bool_]
    mu_planned: FloatArray
    mu_stowed: FloatArray
    mu_removed: FloatArray
    targets: tuple[PoseTarget, ...]
    warm: NDArray[np.bool_]
    guarded: NDArray[np.bool_]
    search_seconds: FloatArray
    search_cpu_seconds: FloatArray
    settings: PlannerSettings
    moves: tuple[FloatArray, ...] = ()


class RiskStretch(NamedTuple):
    """A stretch of planned poses: arc lengths [m] from ``start_s`` to ``end_s``, worst μ."""

    start_s: float
    end_s: float
    worst_mu: float


def warm_settings(settings: PlannerSettings, sigma: float) -> PlannerSettings:
    """The settings of a warm-started pose: one run from the given starts, sigma [m]."""
    return settings._replace(
        method="cmaes",
        seeding="coarse",  # starts given: solve_pose keeps each start as a candidate
        sigma0=float(sigma),
        sigma0_unit="m",
        max_iterations=min(settings.max_iterations, WARM_ITERATIONS),
        restarts=0,
    )


def warm_sigma(settings: PlannerSettings, diameter: float, moved: float) -> float:
    """Warm step size [m]: the last move between answers, within [min, the cold sigma0]."""
    return float(np.clip(moved, WARM_SIGMA_MIN, settings.sigma0_metres(diameter)))


def solve_route(
    robot: Robot,
    terrain: Terrain,
    region: CoMRegion,
    s: ArrayLike,
    poses: ArrayLike,
    settings: PlannerSettings,
    realise: Realise | None = None,
    fractions: ArrayLike | None = None,
    search: Literal["warm", "solve_pose"] = "warm",
) -> RoutePlan:
    """Plan the arm CoM at base poses along a route, each warm-started from the one before.

    Args:
        robot: the robot.
        terrain: the ground (the base rests on it at every pose).
        region: the workspace V.
        s: arc length of each pose (K,) [m].
        poses: base poses (K, 3) in M [m, m, rad], in driving order.
        settings: planner settings (``seed`` seeds the planner's generator; the first pose
            uses them as they are).
        realise: ``(target_com [m], previous_q [rad]) -> (posture, collision_free)``; the
            previous realised posture is passed on; default none (postures NaN).
        fractions: the route's time fraction of each pose (K,); default s / s[-1].
        search: how a warm-started pose is searched: ``warm`` (:func:`mmstab.planner.warm.
            warm_cma`, the population one NumPy batch, no pycma set-up) or ``solve_pose``
            (pycma through :func:`solve_pose`, with the same starts and step size). The
            first pose always goes through :func:`solve_pose` (cold).
    """
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    if settings.method in ("sequence", "roadmap"):  # roadmap: mmstab.planner.roadmap
        return _solve_route_sequence(robot, terrain, region, s, poses, settings, fractions)
    rng = np.random.default_rng(settings.seed)
    mu_max = stowed_flat_mu(robot)
    diameter = float(region.diameter)
    try:
        index = sample_index(region)
    except MmstabError:  # a region without samples: no guard
        index = None
    # every resting pose in one batch (a heightmap's rest solve is far cheaper batched)
    t_gravity, c_gravity = time.perf_counter(), time.process_time()
    gravity_all = gravity_body_at(terrain, poses)
    gravity_share = (time.perf_counter() - t_gravity) / len(poses)  # counted in every pose
    gravity_cpu = (time.process_time() - c_gravity) / len(poses)
    ground = cast(Terrain, _KnownGravity(terrain, poses, gravity_all))
    previous_com, previous_q = robot.arm_com(robot.stowed), robot.stowed
    moved = settings.sigma0_metres(diameter)
    targets, postures, free, warm, guarded, seconds, cpu = [], [], [], [], [], [], []
    for k, pose in enumerate(poses):
        t0, c0 = time.perf_counter(), time.process_time()
        if k == 0:
            starts = None
            if settings.method == "cmaes" and settings.seeding == "starts":
                starts = start_coms(robot, region, settings.starts)
            target = solve_pose(
                robot, ground, region, pose, previous_com, settings, rng, mu_max, starts
            )
            added = False
        else:
            starts_list = [previous_com]
            added = False
            if index is not None:
                fit = pose_fitness(robot, gravity_all[k], previous_com, settings, mu_max, diameter)
                seed = coarse_seeds(
                    fit,
                    index,
                    settings.coarse_samples,
                    settings.coarse_basins,
                    settings.coarse_neighbours,
                    1,
                )
                linear = fit.linear()
                far = np.linalg.norm(seed[0] - previous_com) > SEED_SEPARATION * diameter
                if len(seed) and far and linear(seed)[0] > linear(previous_com)[0]:
                    starts_list.append(seed[0])
                    added = True
            sigma = warm_sigma(settings, diameter, moved)
            if search == "solve_pose":
                target = solve_pose(
                    robot,
                    ground,
                    region,
                    pose,
                    previous_com,
                    warm_settings(settings, sigma),
                    rng,
                    mu_max,
                    np.array(starts_list),
                )
            else:
                fit = pose_fitness(robot, gravity_all[k], previous_com, settings, mu_max, diameter)
                target = _warm_pose(fit, region, pose, starts_list, sigma, settings, rng, t0)
        seconds.append(time.perf_counter() - t0 + gravity_share)
        cpu.append(time.process_time() - c0 + gravity_cpu)
        if realise is not None:
            q, ok = realise(target.target_com, previous_q)
            if not (ok and np.linalg.norm(robot.arm_com(q) - target.target_com) <= REALISE_TOL):
                target, q, ok = fall_back_to_a_sample(
                    robot,
                    ground,
                    region,
                    target,
                    previous_com,
                    settings,
                    mu_max,
                    realise,
                    previous_q,
                )
            previous_q = q
        else:
            q, ok = np.full(4, np.nan), False
        moved = float(np.linalg.norm(target.target_com - previous_com)) if k > 0 else moved
        previous_com = target.target_com
        targets.append(target)
        postures.append(q)
        free.append(ok)
        warm.append(k > 0)
        guarded.append(added)
    target_com = np.array([t.target_com for t in targets])
    q_arr = np.array(postures)
    error = np.where(
        np.isnan(q_arr).any(axis=1),
        np.nan,
        np.linalg.norm(robot.arm_com(np.nan_to_num(q_arr)) - target_com, axis=1),
    )
    cases = stability_along(robot, ground, poses, target_com)
    s_m = np.asarray(s, dtype=float)
    return RoutePlan(
        s=s_m,
        fractions=s_m / max(s_m[-1], 1e-12) if fractions is None else np.asarray(fractions, float),
        poses=poses,
        target_com=target_com,
        postures=q_arr,
        realised_com_error=error,
        collision_free=np.array(free, dtype=bool),
        mu_planned=cases.reconfigured,
        mu_stowed=cases.stowed,
        mu_removed=cases.arm_removed,
        targets=tuple(targets),
        warm=np.array(warm, dtype=bool),
        guarded=np.array(guarded, dtype=bool),
        search_seconds=np.array(seconds),
        search_cpu_seconds=np.array(cpu),
        settings=settings,
    )


def _solve_route_sequence(
    robot: Robot,
    terrain: Terrain,
    region: CoMRegion,
    s: ArrayLike,
    poses: FloatArray,
    settings: PlannerSettings,
    fractions: ArrayLike | None,
) -> RoutePlan:
    """:func:`solve_route` with ``method: sequence``: the whole route at once (open path).

    V's collision-free postures, one per pose, with collision-free joint moves between
    consecutive poses (:mod:`mmstab.planner.sequence`); the first pose moves from the
    stowed arm. The time per pose is the whole search's divided by the poses.
    """
    t0, c0 = time.perf_counter(), time.process_time()
    gravity_all = gravity_body_at(terrain, poses)
    ground = cast(Terrain, _KnownGravity(terrain, poses, gravity_all))
    plan = solve_path(robot, ground, region, poses, settings, closed=False)
    per_pose = (time.perf_counter() - t0) / len(poses)
    per_pose_cpu = (time.process_time() - c0) / len(poses)
    cases = stability_along(robot, ground, poses, plan.target_com)
    s_m = np.asarray(s, dtype=float)
    K = len(poses)
    return RoutePlan(
        s=s_m,
        fractions=s_m / max(s_m[-1], 1e-12) if fractions is None else np.asarray(fractions, float),
        poses=poses,
        target_com=plan.target_com,
        postures=plan.postures,
        realised_com_error=plan.realised_com_error,
        collision_free=plan.collision_free,
        mu_planned=cases.reconfigured,
        mu_stowed=cases.stowed,
        mu_removed=cases.arm_removed,
        targets=plan.targets,
        warm=np.zeros(K, dtype=bool),
        guarded=np.zeros(K, dtype=bool),
        search_seconds=np.full(K, per_pose),
        search_cpu_seconds=np.full(K, per_pose_cpu),
        settings=settings,
        moves=plan.moves,
    )


def _warm_pose(
    fit: Fitness,
    region: CoMRegion,
    pose: FloatArray,
    starts: list[FloatArray],
    sigma: float,
    settings: PlannerSettings,
    rng: np.random.Generator,
    t0: float,
) -> PoseTarget:
    """One warm-started pose: :func:`warm_cma` from each start, the best answer kept."""
    linear = fit.linear()  # the same Eq. 6, affine per tip-over axis: cheaper per batch
    runs = [
        warm_cma(
            linear.__call__,
            region,
            c,
            sigma,
            rng,
            settings.popsize,
            min(settings.max_iterations, WARM_ITERATIONS),
            settings.max_resample,
            settings.tol_x,
            settings.tol_fitness,
        )
        for c in starts
    ]
    best = int(np.argmax([r.best_fitness for r in runs]))
    com = runs[best].best_com
    return PoseTarget(
        pose=np.asarray(pose, dtype=float),
        target_com=com,
        fitness=float(fit(com)[0]),
        mu=float(fit.mu(com)[0]),
        runs=(),
        best_start=best,
        seconds=time.perf_counter() - t0,
    )


class _KnownGravity:
    """A terrain whose gravity at the planned poses is already known (computed in one batch).

    Every other question goes to the terrain itself; a pose not among the planned ones too.
    """

    def __init__(self, terrain: Terrain, poses: FloatArray, gravity_body: FloatArray):
        self._terrain = terrain
        self._known = {tuple(p): g for p, g in zip(map(tuple, poses), gravity_body, strict=True)}

    def __getattr__(self, name: str) -> Any:
        return getattr(self._terrain, name)

    def gravity_body(self, poses: ArrayLike) -> FloatArray:
        """Gravity in the body frame (N, 3) [m/s^2]: the known rows, the rest computed."""
        p = np.atleast_2d(np.asarray(poses, dtype=float))
        rows = [self._known.get(tuple(r)) for r in p]
        if all(r is not None for r in rows):
            return np.array(rows)
        return np.asarray(self._terrain.gravity_body(p))


def stretches(mask: ArrayLike, s: ArrayLike, mu: ArrayLike) -> list[RiskStretch]:
    """Runs of consecutive poses where ``mask`` holds: arc lengths [m] and worst μ [N rad]."""
    s_m, mu_v = np.asarray(s, dtype=float), np.asarray(mu, dtype=float)
    return [
        RiskStretch(float(s_m[k]), float(s_m[j - 1]), float(mu_v[k:j].min()))
        for k, j in true_runs(mask)
    ]


class RouteRisk(NamedTuple):
    """Where a route is at risk (lists of stretches of planned poses).

    Attributes:
        margin: the margin [N rad] (``planner.margin``).
        below_margin: μ planned <= margin: even the best posture is at risk there.
        saved_by_planning: μ stowed <= margin < μ planned: the stowed arm would be at risk.
    """

    margin: float
    below_margin: list[RiskStretch]
    saved_by_planning: list[RiskStretch]


def route_risk(plan: RoutePlan, margin: float) -> RouteRisk:
    """The risk stretches of a route plan against ``margin`` [N rad]."""
    below = plan.mu_planned <= margin
    saved = (plan.mu_stowed <= margin) & ~below
    return RouteRisk(
        margin=float(margin),
        below_margin=stretches(below, plan.s, plan.mu_planned),
        saved_by_planning=stretches(saved, plan.s, plan.mu_stowed),
    )


def plan_route(problem: Problem, workspace: Any = None, progress: bool = False) -> RoutePlan:
    """Plan the problem's route: workspace (cached), poses ``planner.spacing`` apart, IK.

    Poses at 0, ``spacing``, ... and the route's end; their fractions are the route's time
    fractions (the end is reached before the period ends, ``mmstab.paths.route``). Every
    pose after the first is warm-started from the one before (:func:`solve_route`).

    Raises:
        MmstabError: the problem's path is not a route, or the workspace V is empty.
    """
    from mmstab.workspace import load_or_build_workspace
    from mmstab.workspace.ik import PostureSolver

    route = problem.route
    if route is None:
        raise MmstabError(f"{problem.path}: path: not a route (waypoints or file)")
    ws = workspace if workspace is not None else load_or_build_workspace(problem, progress=progress)
    if len(ws.valid_com_in_V) == 0:
        raise MmstabError(f"{problem.path}: the workspace V is empty; no arm CoM can be planned")
    region = planning_region(ws, problem.section("workspace")["method"])
    section = problem.section("planner")
    settings = PlannerSettings.from_section(section)
    s = route_samples(route.length, float(section.get("spacing", DEFAULT_SPACING)))
    poses = route.route.sample(s).pose
    solver = PostureSolver(problem.robot, ws)
    return solve_route(
        problem.robot,
        problem.terrain,
        region,
        s,
        poses,
        settings,
        solver.realise,
        route.fraction_of_s(s),
    )
