"""The planner per base pose and along a path (paper Section II-D, Eq. 6).

Per base pose the planner searches the arm CoM g_a (body frame) inside the workspace V
that maximises Eq. 6 (``mmstab.planner.fitness``), by ``planner.method``:

- ``cmaes``: CMA-ES (``mmstab.planner.cmaes``) from each start mean, the best run kept.
  The start means are the FK CoMs of ``starts`` (link0 angles, other joints zero; the
  paper) or, with ``seeding: coarse``, the best distinct samples of a coarse batched
  evaluation of Eq. 6 over V's samples. sigma0 is in metres or in V's diameters.
- ``exhaustive``: Eq. 6 over every valid grid CoM inside V in one batch
  (``mmstab.planner.exhaustive``), the reference.

No IK inside the search (as in the paper); afterwards :mod:`mmstab.workspace.ik` finds a
collision-free posture that realises the target. The previous CoM of the first pose is the
stowed arm's: the robot starts with its arm folded. Every run draws from its own
``numpy.random.Generator``; the global NumPy state is untouched.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.core.files import MmstabError
from mmstab.core.problem import Problem
from mmstab.model.robot import FloatArray, Robot
from mmstab.planner.cmaes import SearchResult, solve_ipop
from mmstab.planner.exhaustive import (
    ExhaustiveResult,
    coarse_seeds,
    sample_index,
    solve_exhaustive,
)
from mmstab.planner.fitness import CoMRegion, pose_fitness, region_samples
from mmstab.planner.regions import planning_region
from mmstab.planner.sequence import solve_sequence
from mmstab.planner.settings import PlannerSettings
from mmstab.planner.turret import (
    Window,
    WindowedRegion,
    sample_postures,
    sample_turret,
    turret_window,
    windowed_region,
)
from mmstab.planner.wrench import with_tool_wrench
from mmstab.stability.static import mu_max as stowed_flat_mu
from mmstab.terrain import Terrain

#: Largest CoM error of a realised target [m] before the fallback to a sample.
REALISE_TOL = 1e-4
#: Samples of V near an unrealisable target among which the fallback chooses.
FALLBACK_NEIGHBOURS = 64


class PoseTarget(NamedTuple):
    """The planner's answer at one base pose.

    Attributes:
        pose: base pose (x, y, heading) in S [m, m, rad].
        target_com: chosen arm CoM, body frame (3,) [m].
        fitness: its Eq. 6 fitness.
        mu: force-angle measure at the target [N rad].
        runs: the CMA-ES runs (per start, then its IPOP restarts); empty when exhaustive.
        best_start: index of the run kept (-1 when exhaustive).
        seconds: wall time of the search at this pose [s].
        exhaustive: the exhaustive result (``method: exhaustive``), else None.
        fallback: no collision-free posture realised the search's answer, so the best of
            V's samples near it replaced it (:func:`solve_path`).
        window: the turret angles the pose could choose from [rad]
            (``planner.turret_window``), else None.
    """

    pose: FloatArray
    target_com: FloatArray
    fitness: float
    mu: float
    runs: tuple[SearchResult, ...]
    best_start: int
    seconds: float
    exhaustive: ExhaustiveResult | None = None
    fallback: bool = False
    window: Window | None = None


def gravity_body_at(terrain: Terrain, poses: ArrayLike) -> FloatArray:
    """Gravity in the body frame at base poses (N, 3) or (3,) -> (N, 3) [m/s^2].

    The planner's one use of the terrain (every other stage of the planner and its
    experiments goes through here).
    """
    return terrain.gravity_body(np.atleast_2d(np.asarray(poses, dtype=float)))


def start_coms(robot: Robot, region: CoMRegion, starts: tuple[float, ...]) -> FloatArray:
    """Start means of CMA-ES, body frame (S, 3) [m].

    The FK arm CoMs of link0 at each angle with the other joints at zero (paper); a start
    outside V (a coarse grid's hull may miss the stretched arm) moves to the nearest valid
    CoM inside V, when the region has that cloud (``valid_com_in_V``).
    """
    q = np.zeros((len(starts), 4))
    q[:, 0] = starts
    coms = robot.arm_com(q)
    outside = ~region.contains(coms)
    if outside.any() and hasattr(region, "valid_com_in_V"):
        inside = region.valid_com_in_V
        if len(inside):
            for k in np.flatnonzero(outside):
                coms[k] = inside[np.argmin(np.sum((inside - coms[k]) ** 2, axis=1))]
    return coms


def solve_pose(
    robot: Robot,
    terrain: Terrain,
    region: CoMRegion,
    pose: ArrayLike,
    previous_com: ArrayLike,
    settings: PlannerSettings,
    rng: np.random.Generator,
    mu_max: float | None = None,
    starts: FloatArray | None = None,
    previous_q: ArrayLike | None = None,
    closing_q: ArrayLike | None = None,
) -> PoseTarget:
    """Best arm CoM at one base pose: CMA-ES from each start mean (best run kept) or exhaustive.

    Args:
        robot: the robot.
        terrain: the ground.
        region: the workspace V (``contains``, ``diameter``).
        pose: base pose (x, y, heading) in S [m, m, rad].
        previous_com: arm CoM at the previous pose, body frame [m] (Eq. 6 penalty).
        settings: planner settings.
        rng: the planner's generator.
        mu_max: normaliser [N rad]; default: flat ground, arm stowed.
        starts: CMA-ES start means (S, 3) [m]; default :func:`start_coms` of
            ``settings.starts``, or the coarse seeds with ``seeding: coarse``.
        previous_q: the previous pose's posture [rad]; with ``settings.turret_window``
            the search keeps link0 within the window of its link0 (``mmstab.planner.turret``).
        closing_q: the first pose's posture [rad] when this is the last pose of a closed
            path (the window then also keeps link0 near its link0).
    """
    t0 = time.perf_counter()
    pose = np.asarray(pose, dtype=float)
    window = None
    if settings.turret_window is not None and previous_q is not None:
        first = None if closing_q is None else float(np.asarray(closing_q, dtype=float)[0])
        window = turret_window(
            float(np.asarray(previous_q, dtype=float)[0]), settings.turret_window, first
        )
        region = windowed_region(region, window)
    fitness = pose_fitness(
        robot,
        gravity_body_at(terrain, pose)[0],
        previous_com,
        settings,
        stowed_flat_mu(robot) if mu_max is None else mu_max,
        float(region.diameter),
    )
    fitness = with_tool_wrench(fitness, region)  # itself unless payload.wrench is set
    if settings.method in ("exhaustive", "sequence"):  # sequence: per pose, the reference
        ex = solve_exhaustive(fitness, region_samples(region))
        return PoseTarget(
            pose=pose,
            target_com=ex.best_com,
            fitness=ex.best_fitness,
            mu=float(fitness.mu(ex.best_com)[0]),
            runs=(),
            best_start=-1,
            seconds=time.perf_counter() - t0,
            exhaustive=ex,
            window=window,
        )
    coarse = settings.seeding == "coarse"
    if starts is None:
        if coarse:
            starts = coarse_seeds(
                fitness,
                region.index if isinstance(region, WindowedRegion) else sample_index(region),
                settings.coarse_samples,
                settings.coarse_basins,
                settings.coarse_neighbours,
                settings.coarse_seeds,
                region.allowed if isinstance(region, WindowedRegion) else None,
            )
        else:
            starts = start_coms(robot, region, settings.starts)
    sigma0 = settings.sigma0_metres(fitness.diameter)
    runs = tuple(
        run
        for c in starts
        for run in solve_ipop(fitness, region, c, rng, sigma0, settings.restarts, coarse)
    )
    best = int(np.argmax([r.best_fitness for r in runs]))
    target = runs[best].best_com
    return PoseTarget(
        pose=pose,
        target_com=target,
        fitness=runs[best].best_fitness,
        mu=float(fitness.mu(target)[0]),
        runs=runs,
        best_start=best,
        seconds=time.perf_counter() - t0,
        window=window,
    )


def fall_back_to_a_sample(
    robot: Robot,
    terrain: Terrain,
    region: CoMRegion,
    target: PoseTarget,
    previous_com: FloatArray,
    settings: PlannerSettings,
    mu_max: float,
    realise: Callable[[FloatArray, FloatArray], tuple[FloatArray, bool]],
    previous_q: FloatArray,
) -> tuple[PoseTarget, FloatArray, bool]:
    """No collision-free posture realises an off-grid target: take the best nearby sample.

    V's samples are CoMs of collision-free grid postures, so each is realisable; the one
    with the best Eq. 6 fitness among the ``FALLBACK_NEIGHBOURS`` samples nearest to the
    target replaces it (``PoseTarget.fallback``). Without samples the target stays. With a
    turret window (``target.window``) only samples in it count, and when IK from the
    previous posture still leaves the window, the sample's own grid posture is taken.
    """
    try:
        index = sample_index(region)
    except MmstabError:
        q, ok = realise(target.target_com, previous_q)
        return target, q, ok
    k = min(FALLBACK_NEIGHBOURS, len(index.samples))
    _, idx = index.tree.query(target.target_com, k=k)
    rows = np.atleast_1d(idx)
    if target.window is not None:
        turret = sample_turret(region)
        rows = rows[target.window.contains(turret[rows])]
        if len(rows) == 0:  # no neighbour in the window: the window's samples
            rows = np.flatnonzero(target.window.contains(turret))
    near = index.samples[rows]
    fitness = pose_fitness(
        robot,
        gravity_body_at(terrain, target.pose)[0],
        previous_com,
        settings,
        mu_max,
        float(region.diameter),
    )
    fitness = with_tool_wrench(fitness, region)
    values = fitness(near)
    best = int(np.argmax(values))
    q, ok = realise(near[best], previous_q)
    if target.window is not None and not (ok and target.window.contains(q[0])):
        q, ok = sample_postures(region)[rows[best]].copy(), True
    replaced = target._replace(
        target_com=near[best].copy(),
        fitness=float(values[best]),
        mu=float(fitness.mu(near[best])[0]),
        fallback=True,
    )
    return replaced, q, ok


class Plan(NamedTuple):
    """A planned sequence of arm CoMs along the base path, with realising postures.

    Attributes:
        poses: base poses (K, 3) in S [m, m, rad].
        fractions: path fraction of each pose (K,) in [0, 1).
        target_com: chosen arm CoMs, body frame (K, 3) [m].
        postures: arm postures realising them (K, 4) [rad].
        realised_com_error: |g_a(posture) - target| (K,) [m].
        collision_free: whether each posture is collision-free (K,).
        targets: the per-pose planner results.
        settings: the settings used.
        moves: ``method: roadmap``: the roadmap path into each pose's posture (K arrays
            (n, 4) [rad], :mod:`mmstab.planner.roadmap`), else empty.
    """

    poses: FloatArray
    fractions: FloatArray
    target_com: FloatArray
    postures: FloatArray
    realised_com_error: FloatArray
    collision_free: NDArray[np.bool_]
    targets: tuple[PoseTarget, ...]
    settings: PlannerSettings
    moves: tuple[FloatArray, ...] = ()


def solve_path(
    robot: Robot,
    terrain: Terrain,
    region: CoMRegion,
    poses: ArrayLike,
    settings: PlannerSettings,
    realise: Callable[[FloatArray, FloatArray], tuple[FloatArray, bool]] | None = None,
    closed: bool = False,
) -> Plan:
    """Plan poses in sequence, each penalised against the previous target (Eq. 6).

    Args:
        robot: the robot.
        terrain: the ground.
        region: the workspace V.
        poses: base poses (K, 3) in S.
        settings: planner settings (its ``seed`` seeds the planner's generator).
        realise: ``(target_com, previous_posture) -> (posture, collision_free)``; default
            none: postures are NaN (CMA only, e.g. for benchmarks).
        closed: the path is a loop (the circle): with ``settings.turret_window`` the last
            pose's turret is also kept near the first pose's.

    With ``settings.turret_window``, every pose after the first keeps link0 within the
    window of the previous pose's (the realised posture's link0; without ``realise``, the
    link0 of the target's nearest sample of V).
    """
    poses = np.asarray(poses, dtype=float)
    if settings.method == "sequence":
        return _solve_sequence_path(robot, terrain, region, poses, settings, closed)
    if settings.method == "roadmap":
        return _solve_roadmap_path(robot, terrain, region, poses, settings, closed)
    rng = np.random.default_rng(settings.seed)
    mu_max = stowed_flat_mu(robot)
    starts = start_coms(robot, region, settings.starts) if settings.seeding == "starts" else None
    previous_com, previous_q = robot.arm_com(robot.stowed), robot.stowed
    windowed = settings.turret_window is not None
    targets, postures, free = [], [], []
    turret_q: FloatArray | None = None  # the previous pose's posture, for the window
    first_q: FloatArray | None = None
    for k, pose in enumerate(poses):
        closing = first_q if closed and k == len(poses) - 1 else None
        t = solve_pose(
            robot, terrain, region, pose, previous_com, settings, rng, mu_max, starts,
            previous_q=turret_q, closing_q=closing,
        )  # fmt: skip
        if realise is not None:
            q, ok = realise(t.target_com, previous_q)
            if not (
                ok
                and np.linalg.norm(robot.arm_com(q) - t.target_com) <= REALISE_TOL
                and (t.window is None or t.window.contains(q[0]))
            ):
                t, q, ok = fall_back_to_a_sample(
                    robot, terrain, region, t, previous_com, settings, mu_max, realise, previous_q
                )
            previous_q = q
            turret_q = q
        else:
            q, ok = np.full(4, np.nan), False
            if windowed:
                _, row = sample_index(region).tree.query(t.target_com)
                turret_q = sample_postures(region)[int(row)]
        if windowed and first_q is None:
            first_q = turret_q
        targets.append(t)
        previous_com = t.target_com
        postures.append(q)
        free.append(ok)
    target_com = np.array([t.target_com for t in targets])
    postures_arr = np.array(postures)
    realised = robot.arm_com(np.nan_to_num(postures_arr))
    error = np.where(
        np.isnan(postures_arr).any(axis=1), np.nan, np.linalg.norm(realised - target_com, axis=1)
    )
    return Plan(
        poses=poses,
        fractions=np.arange(len(poses)) / len(poses),
        target_com=target_com,
        postures=postures_arr,
        realised_com_error=error,
        collision_free=np.array(free, dtype=bool),
        targets=tuple(targets),
        settings=settings,
    )


def _solve_sequence_path(
    robot: Robot,
    terrain: Terrain,
    region: CoMRegion,
    poses: FloatArray,
    settings: PlannerSettings,
    closed: bool,
) -> Plan:
    """:func:`solve_path` with ``method: sequence``: V's postures, chosen along the path."""
    t0 = time.perf_counter()
    mu_max = stowed_flat_mu(robot)
    seq = solve_sequence(robot, gravity_body_at(terrain, poses), region, settings, mu_max, closed)
    samples = sample_index(region).samples
    postures = sample_postures(region)[seq.rows]
    seconds = (time.perf_counter() - t0) / max(len(poses), 1)
    targets = tuple(
        PoseTarget(
            pose=pose,
            target_com=samples[row].copy(),
            fitness=float(seq.fitness[k]),
            mu=float(seq.mu[k]),
            runs=(),
            best_start=-1,
            seconds=seconds,
        )
        for k, (pose, row) in enumerate(zip(poses, seq.rows, strict=True))
    )
    return Plan(
        poses=poses,
        fractions=np.arange(len(poses)) / len(poses),
        target_com=samples[seq.rows].copy(),
        postures=postures,
        realised_com_error=np.linalg.norm(robot.arm_com(postures) - samples[seq.rows], axis=1),
        collision_free=np.ones(len(poses), dtype=bool),
        targets=targets,
        settings=settings,
    )


def _solve_roadmap_path(
    robot: Robot,
    terrain: Terrain,
    region: CoMRegion,
    poses: FloatArray,
    settings: PlannerSettings,
    closed: bool,
) -> Plan:
    """:func:`solve_path` with ``method: roadmap``: nodes of the posture roadmap of V's grid."""
    from mmstab.planner.roadmap import solve_roadmap_sequence
    from mmstab.workspace.roadmap import load_or_build_roadmap

    t0 = time.perf_counter()
    ws: Any = getattr(region, "workspace", region)  # valid_samples wraps V
    roadmap = load_or_build_roadmap(robot, ws)
    seq = solve_roadmap_sequence(
        robot, gravity_body_at(terrain, poses), roadmap, settings, stowed_flat_mu(robot),
        closed, poses,
    )  # fmt: skip
    seconds = (time.perf_counter() - t0) / max(len(poses), 1)
    targets = tuple(
        PoseTarget(
            pose, seq.com[k].copy(), float(seq.fitness[k]), float(seq.mu[k]), (), -1, seconds
        )
        for k, pose in enumerate(poses)
    )
    return Plan(
        poses=poses,
        fractions=np.arange(len(poses)) / len(poses),
        target_com=seq.com,
        postures=seq.postures,
        realised_com_error=np.zeros(len(poses)),
        collision_free=np.ones(len(poses), dtype=bool),
        targets=targets,
        settings=settings,
        moves=seq.moves,
    )


def plan_path(problem: Problem, workspace: Any = None, progress: bool = False) -> Plan:
    """Plan the problem's circle: workspace (cached), the planner per pose, IK per target.

    The region searched is ``workspace.method``'s (:func:`mmstab.planner.regions.planning_region`).

    Args:
        problem: a loaded problem (sections ``planner``, ``workspace``, ``path``).
        workspace: a prebuilt :class:`mmstab.workspace.Workspace`; default: load or build.
        progress: show progress bars.
    """
    from mmstab.workspace import load_or_build_workspace
    from mmstab.workspace.ik import PostureSolver

    ws = workspace if workspace is not None else load_or_build_workspace(problem, progress=progress)
    if len(ws.valid_com_in_V) == 0:
        raise MmstabError(f"{problem.path}: the workspace V is empty; no arm CoM can be planned")
    region = planning_region(ws, problem.section("workspace")["method"])
    settings = PlannerSettings.from_section(problem.section("planner"))
    if settings.flipper_angles:
        raise MmstabError(
            f"{problem.path}: planner.flipper_angles plans the flippers, which the tracking "
            "controller does not move; they are planned by make levers "
            "(mmstab.planner.levers.solve_path_flippers)"
        )
    solver = PostureSolver(problem.robot, ws)
    poses = problem.circle.poses(settings.poses)
    return solve_path(
        problem.robot, problem.terrain, region, poses, settings, solver.realise, closed=True
    )
