"""The planner's other stability levers: a wrench at the tool, and the flipper angle.

**Tool wrench** (``payload.wrench``, carried as ``Robot.tool_wrench``). Eq. 6 is searched
over the arm CoM g_a, but a wrench's moment depends on where the tool is, which g_a alone
does not fix. The planner takes the tool point of the collision-free grid posture whose
CoM is nearest to g_a (:class:`ToolMap`, a k-d tree over V's labelled postures): V's
samples are exactly those postures, so for the exhaustive search and the coarse seeds the
tool point is exact, and for CMA-ES's off-grid means it is that of the nearest realisable
posture. The measure is then :func:`mmstab.dynamics.dynamic_force_angle` with
``f_r = m_T g + f`` and ``n_r = (p_tool - g_o) x f + n`` (:class:`WrenchFitness`); a zero
wrench gives the static Eq. 6 to rounding.

**Flippers** (``planner.flipper_angles``, the robot's ``base.flippers.limits``). An outer
search over flipper angles around the inner arm-CoM search: each candidate angle gives the
robot its flippers there (support polygon, :func:`with_flipper_angle`) and asks the
terrain for that robot (``Terrain.with_robot``; an angle the terrain refuses, e.g. flippers
reaching into a ramp, is skipped), then :func:`mmstab.planner.solve_pose` plans the arm;
the best Eq. 6 fitness wins, the previous angle on ties (warm start). Along a path the
candidates are limited to ``rate * dt`` from the previous angle (``dt`` = the time between
poses). The flippers carry no mass of their own in the robot description (the base's mass
and CoM include them), so they change the support polygon, not the CoM.
"""

from __future__ import annotations

import copy
import math
import weakref
from typing import Any, NamedTuple, cast

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial import cKDTree

from mmstab.config import MmstabError
from mmstab.dynamics import dynamic_force_angle
from mmstab.planner.fitness import Fitness
from mmstab.planner.settings import PlannerSettings
from mmstab.robot import FloatArray, Robot, flipper_ground_angle, with_flipper_angle
from mmstab.terrain import Terrain


# ------------------------------------------------------------------------------ tool wrench
class ToolMap(NamedTuple):
    """Tool points of V's collision-free postures, looked up by arm CoM.

    Attributes:
        tree: k-d tree over the postures' arm CoMs, body frame [m].
        tool_body: their tool points (the wrist frame's origin), body frame (N, 3) [m].
    """

    tree: cKDTree
    tool_body: FloatArray

    def __call__(self, com_body: ArrayLike) -> FloatArray:
        """Tool points (N, 3) [m] for arm CoMs (N, 3) [m]: the nearest posture's."""
        _, idx = self.tree.query(np.atleast_2d(np.asarray(com_body, dtype=float)))
        return self.tool_body[np.asarray(idx).reshape(-1)]


def tool_points(robot: Robot, q: ArrayLike) -> FloatArray:
    """Tool points (the wrist frame's origin) in B for postures (N, 4) [rad] -> (N, 3) [m]."""
    frames = robot.kinematics.link_frames(np.atleast_2d(np.asarray(q, dtype=float)))
    return np.asarray(frames[:, -1, :3, 3])


_TOOL_MAPS: weakref.WeakKeyDictionary[Any, dict[str, ToolMap]] = weakref.WeakKeyDictionary()


def tool_map(robot: Robot, region: Any) -> ToolMap:
    """The :class:`ToolMap` of a region's labelled postures (cached per region and robot).

    Raises:
        MmstabError: the region keeps no collision-free postures (``valid_q``).
    """
    try:
        return _TOOL_MAPS[region][robot.source_hash]
    except (KeyError, TypeError):
        pass
    q = np.asarray(getattr(region, "valid_q", np.empty((0, 4))), dtype=float).reshape(-1, 4)
    if len(q) == 0:
        raise MmstabError(
            "planner: a tool wrench needs the workspace's collision-free postures (valid_q)"
        )
    out = ToolMap(cKDTree(robot.arm_com(q)), tool_points(robot, q))
    try:
        _TOOL_MAPS.setdefault(region, {})[robot.source_hash] = out
    except TypeError:  # not weak-referenceable: no cache
        pass
    return out


class WrenchFitness(NamedTuple):
    """Eq. 6 with a wrench at the tool (the module text); duck-types :class:`Fitness`."""

    fitness: Fitness
    tools: ToolMap
    wrench_body: FloatArray  # (6,) [N, N m]

    @property
    def diameter(self) -> float:
        """d_workspace [m]."""
        return self.fitness.diameter

    @property
    def settings(self) -> PlannerSettings:
        """The planner settings."""
        return self.fitness.settings

    @property
    def previous_com(self) -> FloatArray:
        """The previous arm CoM, body frame (3,) [m]."""
        return self.fitness.previous_com

    def mu(self, com_body: ArrayLike) -> FloatArray:
        """Force-angle measure with the wrench, arm CoMs (N, 3) [m] -> (N,) [N rad]."""
        f = self.fitness
        coms = np.atleast_2d(np.asarray(com_body, dtype=float))
        overall = f.robot.overall_com(coms)
        force_ext, moment_ext = self.wrench_body[:3], self.wrench_body[3:]
        force = np.broadcast_to(f.robot.total_mass * f.gravity_body + force_ext, coms.shape)
        moment = np.cross(self.tools(coms) - overall, force_ext) + moment_ext
        return dynamic_force_angle(f.polygon, overall, force, moment).mu

    def __call__(self, com_body: ArrayLike) -> FloatArray:
        """Eq. 6 fitness (to maximise) of arm CoMs (N, 3) [m] -> (N,)."""
        coms = np.atleast_2d(np.asarray(com_body, dtype=float))
        f = self.fitness
        motion = np.sum((coms - f.previous_com) ** 2, axis=1) / f.diameter**2
        s = f.settings
        return s.w_stability * self.mu(coms) / f.mu_max - s.w_motion * motion

    def linear(self) -> WrenchFitness:
        """Itself: the wrench's moment arm is not affine in g_a (batched evaluation)."""
        return self


def with_tool_wrench(fitness: Fitness, region: Any) -> Fitness:
    """``fitness`` with the robot's tool wrench, or ``fitness`` itself without one.

    A :class:`WrenchFitness` offers everything the searches use of a ``Fitness``
    (``mu``, ``__call__``, ``linear``, ``diameter``, ``settings``), hence the cast.
    """
    wrench = fitness.robot.tool_wrench
    if wrench is None:
        return fitness
    loaded = WrenchFitness(fitness, tool_map(fitness.robot, region), np.asarray(wrench, float))
    return cast(Fitness, loaded)


# --------------------------------------------------------------------------------- flippers
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
    lim = robot.base.flippers.limits
    if lim is None:
        raise MmstabError(f"robot {robot.name}: planner.flipper_angles needs base.flippers.limits")
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
    target: Any
    tried: FloatArray
    fitness: FloatArray


def solve_pose_flippers(
    robot: Robot,
    terrain: Terrain,
    region: Any,
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
    from mmstab.planner.path import solve_pose

    angles = flipper_candidates(robot, settings.flipper_angles, previous_angle, max_step)
    order = sorted(range(len(angles)), key=lambda k: abs(angles[k] - previous_angle))
    fitness = np.full(len(angles), -np.inf)
    best: Any = None
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
    region: Any,
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
    from mmstab.planner.path import start_coms
    from mmstab.stability import mu_max as stowed_flat_mu

    if settings.flipper_angles < 1:
        raise MmstabError("planner.flipper_angles is 0: the flippers are not planned")
    lim = robot.base.flippers.limits
    if lim is None:
        raise MmstabError(f"robot {robot.name}: planner.flipper_angles needs base.flippers.limits")
    pts = np.asarray(poses, dtype=float)
    rng = np.random.default_rng(settings.seed)
    mu_max = stowed_flat_mu(robot)
    starts = start_coms(robot, region, settings.starts) if settings.seeding == "starts" else None
    previous_com, angle = robot.arm_com(robot.stowed), robot.base.flippers.angle
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
