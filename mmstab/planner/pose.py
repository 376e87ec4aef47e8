"""The planner at one base pose: candidates -> fitness -> choice -> posture (Eq. 6).

Per base pose the planner searches the arm CoM g_a (body frame) inside the planning region
that maximises Eq. 6 (``mmstab.planner.fitness``), by the search ``planner.method`` names
(:data:`mmstab.planner.searches.SEARCHES`; the interface is :mod:`mmstab.planner.searches.base`).

No IK inside the search (as in the paper); afterwards :mod:`mmstab.workspace.ik` finds a
collision-free posture that realises the target, or the best of V's samples near it
replaces it (:func:`fall_back_to_a_sample`). Every run draws from its own
``numpy.random.Generator``; the global NumPy state is untouched.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.core.files import MmstabError
from mmstab.model.robot import FloatArray, Robot
from mmstab.planner.fitness import Fitness, pose_fitness, support_polygons_at
from mmstab.planner.regions import CoMRegion, PlanningRegion, as_region
from mmstab.planner.searches import search_for
from mmstab.planner.searches.base import ExhaustiveResult, PoseTask, SearchResult
from mmstab.planner.settings import PlannerSettings
from mmstab.planner.turret import Window, turret_window
from mmstab.planner.wrench import with_tool_wrench
from mmstab.stability.static import mu_max as stowed_flat_mu
from mmstab.stability.support import loaded_mu
from mmstab.terrain import Terrain

#: Largest CoM error of a realised target [m] before the fallback to a sample.
REALISE_TOL = 1e-4
#: Samples of V near an unrealisable target among which the fallback chooses.
FALLBACK_NEIGHBOURS = 64
#: ``(target_com [m], previous posture [rad]) -> (posture [rad], collision_free)``: the IK.
Realise = Callable[[FloatArray, FloatArray], tuple[FloatArray, bool]]


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
            V's samples near it replaced it (:func:`fall_back_to_a_sample`).
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


class WindowedRegion(NamedTuple):
    """A pose's candidates: the region and the turret window that restricts it.

    Attributes:
        region: the planning region, windowed when a window binds.
        window: the turret window, or None (no window binds).
    """

    region: PlanningRegion
    window: Window | None


class Realised(NamedTuple):
    """A pose's target turned into a posture (step 4).

    Attributes:
        target: the target, replaced by a nearby sample when no posture realised it.
        q: the posture (4,) [rad].
        collision_free: whether the posture is collision-free.
    """

    target: PoseTarget
    q: FloatArray
    collision_free: bool


def gravity_body_at(terrain: Terrain, poses: ArrayLike) -> FloatArray:
    """Gravity in the body frame at base poses (N, 3) or (3,) -> (N, 3) [m/s^2].

    The planner's one use of the terrain (every other stage of the planner and its
    experiments goes through here).
    """
    return terrain.gravity_body(np.atleast_2d(np.asarray(poses, dtype=float)))


def pose_candidates(
    region: PlanningRegion,
    settings: PlannerSettings,
    previous_q: ArrayLike | None = None,
    closing_q: ArrayLike | None = None,
) -> WindowedRegion:
    """Step 1, candidates: the region, restricted to the turret window when one binds.

    Args:
        region: the planning region.
        settings: planner settings (``turret_window``).
        previous_q: the previous pose's posture [rad] (the window is around its link0).
        closing_q: the first pose's posture [rad] when this is the last pose of a closed
            path (the window then also keeps link0 near its link0).
    """
    if settings.turret_window is None or previous_q is None:
        return WindowedRegion(region, None)
    first = None if closing_q is None else float(np.asarray(closing_q, dtype=float)[0])
    window = turret_window(
        float(np.asarray(previous_q, dtype=float)[0]), settings.turret_window, first
    )
    return WindowedRegion(region.windowed(window), window)


def candidate_fitness(
    robot: Robot,
    gravity_body: ArrayLike,
    previous_com: ArrayLike,
    settings: PlannerSettings,
    mu_max: float,
    region: PlanningRegion,
    polygon_body: ArrayLike | None = None,
) -> Fitness:
    """Step 2, fitness: Eq. 6 at a pose (gravity in B [m/s^2]), with the tool wrench if set.

    ``polygon_body``: the pose's support polygon in B (n, 3) [m] (None: the rectangle).
    """
    fitness = pose_fitness(
        robot, gravity_body, previous_com, settings, mu_max, float(region.diameter), polygon_body
    )
    return with_tool_wrench(fitness, region)  # itself unless payload.wrench is set


def choose_at_pose(
    task: PoseTask, pose: FloatArray, window: Window | None, t0: float
) -> PoseTarget:
    """Step 3, choice: the search of ``planner.method`` on one pose's task.

    Args:
        task: the candidates, the fitness and what the search may use.
        pose: the base pose [m, m, rad] (recorded).
        window: the turret window the candidates are restricted to (recorded), or None.
        t0: ``time.perf_counter()`` when the pose's planning began [s].
    """
    choice = search_for(task.settings.method).choose(task)
    return PoseTarget(
        pose=pose,
        target_com=choice.target_com,
        fitness=choice.fitness,
        mu=float(task.fitness.mu(choice.target_com)[0]),
        runs=choice.runs,
        best_start=choice.best_start,
        seconds=time.perf_counter() - t0,
        exhaustive=choice.exhaustive,
        window=window,
    )


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
    """Best arm CoM at one base pose: candidates, fitness and the search's choice.

    Args:
        robot: the robot.
        terrain: the ground.
        region: the planning region (a bare workspace: V).
        pose: base pose (x, y, heading) in S [m, m, rad].
        previous_com: arm CoM at the previous pose, body frame [m] (Eq. 6 penalty).
        settings: planner settings.
        rng: the planner's generator.
        mu_max: normaliser [N rad]; default: flat ground, arm stowed.
        starts: CMA-ES start means (S, 3) [m]; default the search's own
            (:class:`mmstab.planner.searches.cmaes.CmaesSearch`).
        previous_q: the previous pose's posture [rad]; with ``settings.turret_window``
            the search keeps link0 within the window of its link0 (``mmstab.planner.turret``).
        closing_q: the first pose's posture [rad] when this is the last pose of a closed
            path (the window then also keeps link0 near its link0).
    """
    t0 = time.perf_counter()
    pose = np.asarray(pose, dtype=float)
    candidates, window = pose_candidates(as_region(region), settings, previous_q, closing_q)
    polygons = support_polygons_at(robot, terrain, pose)
    fitness = candidate_fitness(
        robot,
        gravity_body_at(terrain, pose)[0],
        previous_com,
        settings,
        stowed_flat_mu(robot) if mu_max is None else mu_max,
        candidates,
        None if polygons is None else polygons[0],
    )
    task = PoseTask(robot, candidates, fitness, settings, rng, starts)
    target = choose_at_pose(task, pose, window, t0)
    if polygons is not None and robot.tool_wrench is None:
        target = previous_if_steadier(robot, terrain, task, target, previous_com)
    return target


def previous_if_steadier(
    robot: Robot, terrain: Terrain, task: PoseTask, target: PoseTarget, previous_com: ArrayLike
) -> PoseTarget:
    """The previous arm CoM instead of the search's where mmstab's one μ prefers it.

    On a heightmap the search ranks arm CoMs on the support the robot stands on with the arm
    stowed (one polygon for every candidate: fast); the chosen CoM rests on its own, on
    the contacts its load puts down (:mod:`mmstab.stability.support`), and that μ is the one
    the plan reports. Where the previous CoM has at least the chosen one's μ there, it is the
    better answer to Eq. 6 too (as steady, and no motion), so it is kept.

    Args:
        robot: the robot.
        terrain: the ground (a heightmap).
        task: the pose's task (its fitness scores the answer).
        target: the search's answer.
        previous_com: the arm CoM at the previous pose, body frame (3,) [m].
    """
    previous = np.asarray(previous_com, dtype=float)
    if np.array_equal(previous, target.target_com):
        return target
    poses = np.tile(target.pose, (2, 1))
    mu = loaded_mu(robot, terrain, poses, np.vstack([target.target_com, previous]), strict=False)
    if not mu[1] >= mu[0]:  # NaN (no rest) keeps the search's answer
        return target
    return target._replace(
        target_com=previous,
        fitness=float(task.fitness(previous)[0]),
        mu=float(task.fitness.mu(previous)[0]),
    )


def fall_back_to_a_sample(
    robot: Robot,
    terrain: Terrain,
    region: PlanningRegion,
    target: PoseTarget,
    previous_com: FloatArray,
    settings: PlannerSettings,
    mu_max: float,
    realise: Realise,
    previous_q: FloatArray,
) -> Realised:
    """Step 4's fallback: no posture realises an off-grid target, take the best nearby sample.

    V's samples are CoMs of collision-free grid postures, so each is realisable; the one
    with the best Eq. 6 fitness among the ``FALLBACK_NEIGHBOURS`` samples nearest to the
    target replaces it (``PoseTarget.fallback``). Without samples the target stays. With a
    turret window (``target.window``) only samples in it count, and when IK from the
    previous posture still leaves the window, the sample's own grid posture is taken.
    """
    try:
        index = region.index
    except MmstabError:
        q, ok = realise(target.target_com, previous_q)
        return Realised(target, q, ok)
    k = min(FALLBACK_NEIGHBOURS, len(index.samples))
    _, idx = index.tree.query(target.target_com, k=k)
    rows = np.atleast_1d(idx)
    if target.window is not None:
        turret = region.turret_angles
        rows = rows[target.window.contains(turret[rows])]
        if len(rows) == 0:  # no neighbour in the window: the window's samples
            rows = np.flatnonzero(target.window.contains(turret))
    near = index.samples[rows]
    polygons = support_polygons_at(robot, terrain, target.pose)
    fitness = candidate_fitness(
        robot, gravity_body_at(terrain, target.pose)[0], previous_com, settings, mu_max, region,
        None if polygons is None else polygons[0],
    )  # fmt: skip
    values = fitness(near)
    best = int(np.argmax(values))
    q, ok = realise(near[best], previous_q)
    if target.window is not None and not (ok and target.window.contains(q[0])):
        q, ok = region.postures[rows[best]].copy(), True
    replaced = target._replace(
        target_com=near[best].copy(),
        fitness=float(values[best]),
        mu=float(fitness.mu(near[best])[0]),
        fallback=True,
    )
    return Realised(replaced, q, ok)


def realise_target(
    robot: Robot,
    terrain: Terrain,
    region: PlanningRegion,
    target: PoseTarget,
    previous_com: FloatArray,
    settings: PlannerSettings,
    mu_max: float,
    realise: Realise,
    previous_q: FloatArray,
) -> Realised:
    """Step 4, posture: IK from the previous posture, or :func:`fall_back_to_a_sample`.

    The IK's answer stands when it is collision-free, realises the target within
    ``REALISE_TOL`` and keeps link0 in the target's turret window (if any).

    """
    q, ok = realise(target.target_com, previous_q)
    if (
        ok
        and np.linalg.norm(robot.arm_com(q) - target.target_com) <= REALISE_TOL
        and (target.window is None or target.window.contains(q[0]))
    ):
        return Realised(target, q, ok)
    return fall_back_to_a_sample(
        robot, terrain, region, target, previous_com, settings, mu_max, realise, previous_q
    )


class KnownGravity:
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
