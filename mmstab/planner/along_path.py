"""The planner along a list of base poses: each pose in turn, or the whole path at once.

A per-pose search (:class:`mmstab.planner.searches.base.PoseSearch`) plans the poses in driving
order, each penalised against the previous target (Eq. 6) and realised by the IK from the
previous posture (:mod:`mmstab.planner.pose`); a whole-path search
(:class:`~mmstab.planner.searches.base.PathSearch`) chooses every pose's CoM and posture at once.
Both give a :class:`Plan`. The previous CoM of the first pose is the stowed arm's: the
robot starts with its arm folded.
"""

from __future__ import annotations

import time
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.model.robot import FloatArray, Robot
from mmstab.planner.pose import (
    PoseTarget,
    Realise,
    gravity_body_at,
    realise_target,
    solve_pose,
)
from mmstab.planner.regions import CoMRegion, PlanningRegion, as_region
from mmstab.planner.searches import search_for
from mmstab.planner.searches.base import PathSearch, PathTask
from mmstab.planner.searches.cmaes import start_coms
from mmstab.planner.settings import PlannerSettings
from mmstab.stability.static import mu_max as stowed_flat_mu
from mmstab.terrain import Terrain


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
        moves: the arm's path into each pose's posture (K arrays (n, 4) [rad]) where the
            search gives one (``method: roadmap``), else empty.
        turns: the turns the slide limit constrained (:class:`~.searches.base.PathChoice`).
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
    turns: tuple[dict[str, Any], ...] = ()


def solve_path(
    robot: Robot,
    terrain: Terrain,
    region: CoMRegion,
    poses: ArrayLike,
    settings: PlannerSettings,
    realise: Realise | None = None,
    closed: bool = False,
) -> Plan:
    """Plan poses in sequence, each penalised against the previous target (Eq. 6).

    Args:
        robot: the robot.
        terrain: the ground.
        region: the planning region (a bare workspace: V).
        poses: base poses (K, 3) in S.
        settings: planner settings (its ``seed`` seeds the planner's generator).
        realise: the IK, ``(target_com, previous_posture) -> (posture, collision_free)``;
            default none: postures are NaN (the search only, e.g. for benchmarks).
        closed: the path is a loop (the circle): with ``settings.turret_window`` the last
            pose's turret is also kept near the first pose's.

    With ``settings.turret_window``, every pose after the first keeps link0 within the
    window of the previous pose's (the realised posture's link0; without ``realise``, the
    link0 of the target's nearest sample of V).
    """
    poses = np.asarray(poses, dtype=float)
    region = as_region(region)
    search = search_for(settings.method)
    if isinstance(search, PathSearch):
        return solve_whole_path(search, robot, terrain, region, poses, settings, closed)
    return solve_pose_by_pose(robot, terrain, region, poses, settings, realise, closed)


def solve_pose_by_pose(
    robot: Robot,
    terrain: Terrain,
    region: PlanningRegion,
    poses: FloatArray,
    settings: PlannerSettings,
    realise: Realise | None,
    closed: bool,
) -> Plan:
    """:func:`solve_path` with a per-pose search: each pose from the one before."""
    rng = np.random.default_rng(settings.seed)
    mu_max = stowed_flat_mu(robot)
    # the paper's starts, once; with a turret window each pose's search moves them into
    # its window (``CmaesSearch.starts``): a start far outside it left no sample in V
    fixed = settings.seeding == "starts" and settings.turret_window is None
    starts = start_coms(robot, region, settings.starts) if fixed else None
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
            t, q, ok = realise_target(
                robot, terrain, region, t, previous_com, settings, mu_max, realise, previous_q
            )
            previous_q = q
            turret_q = q
        else:
            q, ok = np.full(robot.arm_joints, np.nan), False
            if windowed:
                _, row = region.index.tree.query(t.target_com)
                turret_q = region.postures[int(row)]
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


def solve_whole_path(
    search: PathSearch,
    robot: Robot,
    terrain: Terrain,
    region: PlanningRegion,
    poses: FloatArray,
    settings: PlannerSettings,
    closed: bool,
) -> Plan:
    """:func:`solve_path` with a whole-path search: its CoMs come with their postures."""
    t0 = time.perf_counter()
    mu_max = stowed_flat_mu(robot)
    gravity = gravity_body_at(terrain, poses)
    task = PathTask(robot, region, gravity, settings, mu_max, closed, poses, terrain)
    choice = search.choose_path(task)
    seconds = (time.perf_counter() - t0) / max(len(poses), 1)
    targets = tuple(
        PoseTarget(
            pose=pose,
            target_com=choice.target_com[k].copy(),
            fitness=float(choice.fitness[k]),
            mu=float(choice.mu[k]),
            runs=(),
            best_start=-1,
            seconds=seconds,
        )
        for k, pose in enumerate(poses)
    )
    error = np.linalg.norm(robot.arm_com(choice.postures) - choice.target_com, axis=1)
    return Plan(
        poses=poses,
        fractions=np.arange(len(poses)) / len(poses),
        target_com=choice.target_com.copy(),
        postures=choice.postures,
        realised_com_error=error,
        collision_free=np.ones(len(poses), dtype=bool),
        targets=targets,
        settings=settings,
        moves=choice.moves,
        turns=choice.turns,
    )
