"""The planner's flipper lever: the flipper angle as a planning variable.

The other lever, a wrench at the tool, is :mod:`mmstab.planner.wrench`.

**Flippers** (``planner.flipper_angles``, the robot's ``base.flippers.limits``). An outer
search over flipper angles around the inner arm-CoM search: each candidate angle gives the
robot its flippers there (support polygon, :func:`with_flipper_angle`) and asks the
terrain for that robot (``Terrain.with_robot``; an angle the terrain refuses, e.g. flippers
reaching into a ramp, is skipped), then the per-pose pipeline
(:func:`mmstab.planner.pose.solve_pose`, the problem's search) plans the arm;
the best Eq. 6 fitness wins, the previous angle on ties (warm start). Along a path the
candidates are limited to ``rate * dt`` from the previous angle (``dt`` = the time between
poses). The flippers carry no mass of their own in the robot description (the base's mass
and CoM include them), so they change the support polygon, not the CoM.
"""

from __future__ import annotations

import copy
import math
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.core.files import MmstabError
from mmstab.model.robot import (
    FlipperLimits,
    FloatArray,
    Robot,
    flipper_ground_angle,
    with_flipper_angle,
)
from mmstab.planner.pose import PoseTarget, solve_pose
from mmstab.planner.regions import CoMRegion, as_region
from mmstab.planner.searches.cmaes import start_coms
from mmstab.planner.settings import PlannerSettings
from mmstab.stability.static import mu_max as stowed_flat_mu
from mmstab.terrain import Terrain


# --------------------------------------------------------------------------------- flippers
def flipper_limits(robot: Robot) -> FlipperLimits:
    """The robot's flipper limits, which ``planner.flipper_angles`` plans within.

    Raises:
        MmstabError: the robot has no flippers, or no ``base.flippers.limits``.
    """
    if robot.base.flippers is None or robot.base.flippers.limits is None:
        raise MmstabError(f"robot {robot.name}: planner.flipper_angles needs base.flippers.limits")
    return robot.base.flippers.limits


def flipper_candidates(
    robot: Robot, count: int, previous: float, max_step: float = math.inf
) -> FloatArray:
    """Flipper angles to try at a pose [rad], sorted, the previous one included.

    ``count`` evenly spaced angles over the robot's flipper limits, the ground-contact
    angle (:func:`flipper_ground_angle`) and ``previous +- max_step``, all within the
    limits and within ``max_step`` [rad] of ``previous``.

    Raises:
        MmstabError: the robot has no flipper limits.
    """
    lim = flipper_limits(robot)
    lo, hi = max(lim.lower, previous - max_step), min(lim.upper, previous + max_step)
    grid = [*np.linspace(lim.lower, lim.upper, count), flipper_ground_angle(robot), lo, hi]
    out = [previous, *(a for a in grid if lo - 1e-12 <= a <= hi + 1e-12)]
    return np.unique(np.clip(out, lim.lower, lim.upper))


class FlipperTarget(NamedTuple):
    """The outer search's answer at one pose.

    Attributes:
        flipper_angle: chosen flipper angle [rad].
        target: the arm planner's answer with the flippers there (``PoseTarget``).
        tried: the angles tried [rad]; ``fitness`` of each (-inf where refused).
    """

    flipper_angle: float
    target: PoseTarget
    tried: FloatArray
    fitness: FloatArray


def solve_pose_flippers(
    robot: Robot,
    terrain: Terrain,
    region: CoMRegion,
    pose: ArrayLike,
    previous_com: ArrayLike,
    previous_angle: float,
    settings: PlannerSettings,
    rng: np.random.Generator,
    mu_max: float,
    starts: FloatArray | None = None,
    max_step: float = math.inf,
) -> FlipperTarget:
    """Best flipper angle and arm CoM at one pose (outer search over angles).

    Args:
        robot: the robot (its flipper limits bound the angles).
        terrain: the ground.
        region: the workspace V.
        pose: base pose (x, y, yaw) in M [m, m, rad].
        previous_com: arm CoM at the previous pose, body frame (3,) [m].
        previous_angle: flipper angle at the previous pose [rad] (tried first: ties keep it).
        settings: planner settings (``flipper_angles`` evenly spaced candidates).
        rng: the planner's generator.
        mu_max: Eq. 6 normaliser [N rad].
        starts: CMA-ES start means (S, 3) [m] (see ``solve_pose``).
        max_step: largest change from ``previous_angle`` [rad] (rate limit x time step).

    Raises:
        MmstabError: no candidate angle is accepted by the terrain.
    """
    region = as_region(region)  # one region for every angle (its views built once)
    angles = flipper_candidates(robot, settings.flipper_angles, previous_angle, max_step)
    order = sorted(range(len(angles)), key=lambda k: abs(angles[k] - previous_angle))
    fitness = np.full(len(angles), -np.inf)
    best: PoseTarget | None = None
    best_angle = math.nan
    best_rng = rng
    for k in order:
        r = with_flipper_angle(robot, angles[k])
        try:
            t_r = terrain.with_robot(r, flipper_angle=float(angles[k]))
        except MmstabError:
            continue
        # every angle searches from the same generator state, so that angles giving the
        # same polygon give the same answer (the previous angle then wins the tie)
        trial = copy.deepcopy(rng)
        t = solve_pose(r, t_r, region, pose, previous_com, settings, trial, mu_max, starts)
        fitness[k] = t.fitness
        if best is None or t.fitness > best.fitness:
            best, best_angle, best_rng = t, float(angles[k]), trial
    if best is None:
        raise MmstabError(
            f"no flipper angle among {angles.tolist()} fits the terrain at pose "
            f"{np.asarray(pose).tolist()}"
        )
    rng.bit_generator.state = best_rng.bit_generator.state  # continue from the chosen search
    return FlipperTarget(best_angle, best, angles, fitness)


class FlipperPlan(NamedTuple):
    """Arm CoMs and flipper angles along a path (CMA only, no postures).

    Attributes:
        poses: base poses (K, 3) in M.
        target_com: arm CoMs, body frame (K, 3) [m].
        flipper_angles: flipper angles (K,) [rad].
        mu: force-angle measure at each pose (K,) [N rad].
        targets: the per-pose answers.
    """

    poses: FloatArray
    target_com: FloatArray
    flipper_angles: FloatArray
    mu: FloatArray
    targets: tuple[FlipperTarget, ...]


def solve_path_flippers(
    robot: Robot,
    terrain: Terrain,
    region: CoMRegion,
    poses: ArrayLike,
    settings: PlannerSettings,
    dt: float,
) -> FlipperPlan:
    """Arm CoM and flipper angle at each pose in sequence (warm-started, rate-limited).

    Args:
        robot: the robot, flippers starting at its file angle.
        terrain: the ground.
        region: the workspace V.
        poses: base poses (K, 3) in M.
        settings: planner settings (``flipper_angles`` > 0).
        dt: time between consecutive poses [s] (the rate limit's step: rate * dt).

    Raises:
        MmstabError: ``flipper_angles`` is 0, or the robot has no flipper limits.
    """
    if settings.flipper_angles < 1:
        raise MmstabError("planner.flipper_angles is 0: the flippers are not planned")
    lim = flipper_limits(robot)
    pts = np.asarray(poses, dtype=float)
    region = as_region(region)
    rng = np.random.default_rng(settings.seed)
    mu_max = stowed_flat_mu(robot)
    starts = start_coms(robot, region, settings.starts) if settings.seeding == "starts" else None
    previous_com, angle = robot.arm_com(robot.stowed), robot.base.flippers.angle  # type: ignore[union-attr]
    out = []
    for pose in pts:
        ft = solve_pose_flippers(
            robot,
            terrain,
            region,
            pose,
            previous_com,
            angle,
            settings,
            rng,
            mu_max,
            starts,
            lim.rate * dt,
        )
        out.append(ft)
        previous_com, angle = ft.target.target_com, ft.flipper_angle
    return FlipperPlan(
        poses=pts,
        target_com=np.array([t.target.target_com for t in out]).reshape(-1, 3),
        flipper_angles=np.array([t.flipper_angle for t in out]),
        mu=np.array([t.target.mu for t in out]),
        targets=tuple(out),
    )
