"""Warm-started planning along a route (``docs/routes.md``): poses ``planner.spacing`` apart.

The base rests on the terrain at every pose (gravity in the body from
:meth:`Terrain.gravity_body`), so the support and the tipping direction change along the
way. Per pose:

- the first pose: :func:`mmstab.planner.pose.solve_pose` with the problem's own search
  (cold start);
- every later pose **warm-started** from the previous pose's answer: CMA-ES starts at the
  previous target CoM, with a step size from how far the answer moved between the two
  poses before (``warm_sigma``), the population as one batch, ``WARM_ITERATIONS``
  iterations at most, the start itself kept as a candidate (never worse than staying);
  by default the warm form of the registered search (:func:`warm_pose`: the search's
  ``warm``, :class:`~mmstab.planner.searches.base.WarmSearch`; for ``cmaes`` and
  ``exhaustive`` the compact CMA-ES of :mod:`mmstab.planner.searches.cmaes.warm`: pycma's
  set-up and per-iteration cost exceed a warm pose's budget), or ``search="solve_pose"``:
  the same starts and step size through :func:`~mmstab.planner.pose.solve_pose` (pycma);
- a **guard** against a new basin the warm start cannot see (the best posture switching
  sides): a coarse batched pass of Eq. 6 over V's samples (the planner's ``coarse_*``
  settings, affine form); when its best refined sample beats the previous answer and lies
  away from it, it is a second start.

The motion term of Eq. 6 is taken relative to the previous pose's target (body frames of
consecutive poses), and the realised posture of the previous pose is handed to the IK of
the next (``realise(target, previous_q)``), so the arm moves the short way. A whole-path
search (``method: sequence``) plans the route at once (:func:`mmstab.planner.solve_path`,
open path).
"""

from __future__ import annotations

import time
from typing import Any, Literal, NamedTuple, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.core.files import MmstabError
from mmstab.model.robot import FloatArray, Robot
from mmstab.paths.route import RoutePath
from mmstab.planner.along_path import solve_path
from mmstab.planner.fitness import Fitness, pose_fitness, support_polygons_at
from mmstab.planner.pose import (
    KnownGravity,
    PoseTarget,
    Realise,
    gravity_body_at,
    realise_target,
    solve_pose,
)
from mmstab.planner.regions import CoMRegion, PlanningRegion, SampleIndex, as_region
from mmstab.planner.searches import search_for
from mmstab.planner.searches.base import PathSearch, WarmSearch, WarmTask
from mmstab.planner.searches.cmaes import WARM_ITERATIONS
from mmstab.planner.searches.coarse import SEED_SEPARATION, coarse_seeds
from mmstab.planner.settings import PlannerSettings
from mmstab.stability.static import mu_max as stowed_flat_mu
from mmstab.stability.support import stability_along
from mmstab.terrain import Terrain

#: Smallest warm step size [m]: about the spacing of V's grid samples.
WARM_SIGMA_MIN = 0.01


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
        mu_planned: μ with the planned arm (K,) [N rad]: the posture realising the target
            (its target CoM where none was found), on the contacts that carry that load
            (:func:`mmstab.stability.support.stability_along`): the μ every command reports.
        mu_stowed: μ with the arm stowed (K,) [N rad], likewise.
        mu_removed: μ with the arm removed (K,) [N rad], likewise.
        targets: the per-pose planner results.
        warm: whether each pose was warm-started (K,).
        guarded: whether the coarse guard added a second start (K,).
        search_seconds: wall time of the search per pose [s]: guard, CMA-ES and an equal
            share of the batched resting poses (not the IK).
        search_cpu_seconds: the same in CPU time of this process [s] (less sensitive to
            other processes on a shared machine).
        settings: the planner settings.
        moves: the arm's path into each pose's posture (K arrays (n, 4) [rad]) with
            ``method: roadmap``, else empty.
        mu_search: μ of the target CoM on the basis the search ranks on (K,) [N rad]: the
            support polygon of the stowed arm's rest (one affine form per pose; the
            search's quality is measured on it). Empty when not known.
        fixed_seconds: wall time before the poses' search [s]: the caches loaded (or
            built) and what the search keeps between plans of a process
            (:func:`mmstab.planner.plan.plan_route`); 0 when not measured.
        route: the route whose time law ``fractions`` follow, when it is not the problem's
            own (its turns slowed: :mod:`mmstab.runs.time_law`); None: the problem's.
        time_law: the account of the slowed turns (:func:`mmstab.runs.time_law.slowed_route`),
            None when none was made.
        turns: the turns ``planner.turn_slide`` priced over its limit and the poses it
            constrained (:class:`mmstab.planner.searches.base.PathChoice`); empty: none.
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
    mu_search: FloatArray = np.zeros(0)
    fixed_seconds: float = 0.0
    route: RoutePath | None = None
    time_law: dict[str, Any] | None = None
    turns: tuple[dict[str, Any], ...] = ()


def planned_com(robot: Robot, postures: ArrayLike, target_com: ArrayLike) -> FloatArray:
    """The arm CoM in B (K, 3) [m] of the planned postures (K, n) [rad].

    The target CoM (K, 3) [m] where no posture realises it (a NaN row).
    """
    q = np.asarray(postures, dtype=float)
    target = np.asarray(target_com, dtype=float)
    known = np.isfinite(q).all(axis=1)
    realised = np.atleast_2d(robot.arm_com(np.nan_to_num(q)))
    return np.where(known[:, None], realised, target)


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


class RouteSearch(NamedTuple):
    """What every pose of a route's per-pose search shares.

    Attributes:
        robot: the robot.
        ground: the terrain, its gravity at the planned poses known (one batch).
        region: the planning region.
        settings: the planner settings.
        rng: the planner's generator.
        mu_max: Eq. 6's normaliser [N rad].
        sample_index: the region's samples and k-d tree (the guard), None without samples.
        gravity_body: gravity in B at every pose (K, 3) [m/s^2].
        search: ``warm`` or ``solve_pose`` (:func:`solve_route`).
        polygons: each pose's support polygon in B (:func:`support_polygons_at`), or None
            on a plane.
    """

    robot: Robot
    ground: Terrain
    region: PlanningRegion
    settings: PlannerSettings
    rng: np.random.Generator
    mu_max: float
    sample_index: SampleIndex | None
    gravity_body: FloatArray
    search: str
    polygons: list[FloatArray] | None = None

    def polygon(self, k: int) -> FloatArray | None:
        """Pose ``k``'s support polygon in B (n, 3) [m], None on a plane."""
        return None if self.polygons is None else self.polygons[k]


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
        region: the planning region (a bare workspace: V).
        s: arc length of each pose (K,) [m].
        poses: base poses (K, 3) in M [m, m, rad], in driving order.
        settings: planner settings (``seed`` seeds the planner's generator; the first pose
            uses them as they are).
        realise: ``(target_com [m], previous_q [rad]) -> (posture, collision_free)``; the
            previous realised posture is passed on; default none (postures NaN).
        fractions: the route's time fraction of each pose (K,); default s / s[-1].
        search: how a warm-started pose is searched: ``warm`` (:func:`warm_pose`, the
            population one NumPy batch, no pycma set-up) or ``solve_pose``
            (pycma through :func:`solve_pose`, with the same starts and step size). The
            first pose always goes through :func:`solve_pose` (cold).
    """
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    region = as_region(region)
    if isinstance(search_for(settings.method), PathSearch):
        return _solve_route_whole(robot, terrain, region, s, poses, settings, fractions)
    try:
        index: SampleIndex | None = region.index
    except MmstabError:  # a region without samples: no guard
        index = None
    # every resting pose in one batch (a heightmap's rest solve is far cheaper batched)
    t_gravity, c_gravity = time.perf_counter(), time.process_time()
    gravity_all = gravity_body_at(terrain, poses)
    polygons = support_polygons_at(robot, terrain, poses)
    gravity_share = (time.perf_counter() - t_gravity) / len(poses)  # counted in every pose
    gravity_cpu = (time.process_time() - c_gravity) / len(poses)
    ground = cast(Terrain, KnownGravity(terrain, poses, gravity_all))
    ctx = RouteSearch(
        robot, ground, region, settings, np.random.default_rng(settings.seed),
        stowed_flat_mu(robot), index, gravity_all, search, polygons,
    )  # fmt: skip
    previous_com, previous_q = robot.arm_com(robot.stowed), robot.stowed
    moved = settings.sigma0_metres(region.diameter)
    targets, postures, free, guarded, seconds, cpu = [], [], [], [], [], []
    for k, pose in enumerate(poses):
        t0, c0 = time.perf_counter(), time.process_time()
        target, added = _route_pose(ctx, k, pose, previous_com, moved, t0)
        seconds.append(time.perf_counter() - t0 + gravity_share)
        cpu.append(time.process_time() - c0 + gravity_cpu)
        if realise is not None:
            target, q, ok = realise_target(
                robot, ground, region, target, previous_com, settings, ctx.mu_max, realise,
                previous_q,
            )  # fmt: skip
            previous_q = q
        else:
            q, ok = np.full(robot.arm_joints, np.nan), False
        moved = float(np.linalg.norm(target.target_com - previous_com)) if k > 0 else moved
        previous_com = target.target_com
        targets.append(target)
        postures.append(q)
        free.append(ok)
        guarded.append(added)
    return _route_plan(
        robot, ground, s, poses, targets, np.array(postures), free, fractions, settings,
        guarded, seconds, cpu,
    )  # fmt: skip


def _route_pose(
    ctx: RouteSearch,
    k: int,
    pose: FloatArray,
    previous_com: FloatArray,
    moved: float,
    t0: float,
) -> tuple[PoseTarget, bool]:
    """Pose ``k`` of a route: cold (the first) or warm-started; whether the guard added a start.

    Args:
        ctx: what the poses share.
        k: the pose's index.
        pose: the base pose [m, m, rad].
        previous_com: the previous pose's target, body frame (3,) [m].
        moved: how far the answer moved between the two poses before [m].
        t0: ``time.perf_counter()`` at the pose's start [s].
    """
    robot, settings = ctx.robot, ctx.settings
    if k == 0:  # the search's own starts (cold)
        target = solve_pose(
            robot, ctx.ground, ctx.region, pose, previous_com, settings, ctx.rng, ctx.mu_max
        )
        return target, False
    starts_list = [previous_com]
    guard = _guard_start(ctx, k, previous_com)
    if guard is not None:
        starts_list.append(guard)
    sigma = warm_sigma(settings, ctx.region.diameter, moved)
    if ctx.search == "solve_pose":
        target = solve_pose(
            robot,
            ctx.ground,
            ctx.region,
            pose,
            previous_com,
            warm_settings(settings, sigma),
            ctx.rng,
            ctx.mu_max,
            np.array(starts_list),
        )
    else:
        fit = pose_fitness(
            robot, ctx.gravity_body[k], previous_com, settings, ctx.mu_max, ctx.region.diameter,
            ctx.polygon(k),
        )  # fmt: skip
        target = warm_pose(fit, ctx.region, pose, starts_list, sigma, settings, ctx.rng, t0)
    return target, guard is not None


def warm_pose(
    fit: Fitness,
    region: PlanningRegion,
    pose: FloatArray,
    starts: list[FloatArray],
    sigma: float,
    settings: PlannerSettings,
    rng: np.random.Generator,
    t0: float,
) -> PoseTarget:
    """One warm-started pose: the warm form of the search ``settings.method`` names.

    Args:
        fit: Eq. 6 at the pose.
        region: the planning region.
        pose: the base pose [m, m, rad] (recorded).
        starts: start means, body frame (3,) each [m].
        sigma: the warm step size [m].
        settings: planner settings (population, tolerances; ``WARM_ITERATIONS`` at most).
        rng: the planner's generator.
        t0: ``time.perf_counter()`` at the pose's start [s].

    Raises:
        MmstabError: the search has no warm form (a whole-path search plans a route at once).
    """
    search = search_for(settings.method)
    if not isinstance(search, WarmSearch):
        raise MmstabError(f"planner.method: {settings.method!r} has no warm-started form")
    choice = search.warm(WarmTask(region, fit, settings, rng, starts, sigma))
    com = choice.target_com
    return PoseTarget(
        pose=np.asarray(pose, dtype=float),
        target_com=com,
        fitness=choice.fitness,
        mu=float(fit.mu(com)[0]),
        runs=(),
        best_start=choice.best_start,
        seconds=time.perf_counter() - t0,
    )


def _guard_start(ctx: RouteSearch, k: int, previous_com: FloatArray) -> FloatArray | None:
    """The coarse guard's second start at pose ``k`` (module text), or None.

    The best refined coarse sample, when it beats the previous answer and lies more than
    ``SEED_SEPARATION`` of V's diameter away from it.
    """
    if ctx.sample_index is None:
        return None
    s, diameter = ctx.settings, ctx.region.diameter
    fit = pose_fitness(
        ctx.robot, ctx.gravity_body[k], previous_com, s, ctx.mu_max, diameter, ctx.polygon(k)
    )
    seed = coarse_seeds(
        fit, ctx.sample_index, s.coarse_samples, s.coarse_basins, s.coarse_neighbours, 1
    )
    linear = fit.linear()
    far = np.linalg.norm(seed[0] - previous_com) > SEED_SEPARATION * diameter
    if len(seed) and far and linear(seed)[0] > linear(previous_com)[0]:
        return np.asarray(seed[0])
    return None


def _route_plan(
    robot: Robot,
    ground: Terrain,
    s: ArrayLike,
    poses: FloatArray,
    targets: list[PoseTarget],
    q_arr: FloatArray,
    free: list[bool],
    fractions: ArrayLike | None,
    settings: PlannerSettings,
    guarded: list[bool],
    seconds: list[float],
    cpu: list[float],
) -> RoutePlan:
    """The :class:`RoutePlan` of a per-pose route search (μ along it in the three cases)."""
    target_com = np.array([t.target_com for t in targets])
    error = np.where(
        np.isnan(q_arr).any(axis=1),
        np.nan,
        np.linalg.norm(robot.arm_com(np.nan_to_num(q_arr)) - target_com, axis=1),
    )
    cases = stability_along(robot, ground, poses, planned_com(robot, q_arr, target_com))
    search = np.array([t.mu for t in targets])  # the search's own basis
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
        warm=np.arange(len(targets)) > 0,
        guarded=np.array(guarded, dtype=bool),
        search_seconds=np.array(seconds),
        search_cpu_seconds=np.array(cpu),
        settings=settings,
        mu_search=search,
    )


def _solve_route_whole(
    robot: Robot,
    terrain: Terrain,
    region: PlanningRegion,
    s: ArrayLike,
    poses: FloatArray,
    settings: PlannerSettings,
    fractions: ArrayLike | None,
) -> RoutePlan:
    """:func:`solve_route` with a whole-path search (``method: sequence``): an open path.

    The first pose moves from the stowed arm. The time per pose is the whole search's
    divided by the poses.
    """
    t0, c0 = time.perf_counter(), time.process_time()
    gravity_all = gravity_body_at(terrain, poses)
    ground = cast(Terrain, KnownGravity(terrain, poses, gravity_all))
    plan = solve_path(robot, ground, region, poses, settings, closed=False)
    per_pose = (time.perf_counter() - t0) / len(poses)
    per_pose_cpu = (time.process_time() - c0) / len(poses)
    planned = planned_com(robot, plan.postures, plan.target_com)
    cases = stability_along(robot, ground, poses, planned)
    search = np.array([t.mu for t in plan.targets])  # the search's own basis
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
        mu_search=search,
        turns=plan.turns,
    )
