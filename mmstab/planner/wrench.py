"""The tool wrench in Eq. 6 (``payload.wrench``, carried as ``Robot.tool_wrench``).

Eq. 6 is searched
over the arm CoM g_a, but a wrench's moment depends on where the tool is, which g_a alone
does not fix. The planner takes the tool point of the collision-free grid posture whose
CoM is nearest to g_a (:class:`ToolMap`, a k-d tree over V's labelled postures): V's
samples are exactly those postures, so for the exhaustive search and the coarse seeds the
tool point is exact, and for CMA-ES's off-grid means it is that of the nearest realisable
posture. The measure is then :func:`mmstab.stability.dynamic.dynamic_force_angle` with
``f_r = m_T g + f`` and ``n_r = (p_tool - g_o) x f + n`` (:class:`WrenchFitness`); a zero
wrench gives the static Eq. 6 to rounding.
"""

from __future__ import annotations

from typing import NamedTuple, cast

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial import cKDTree

from mmstab.core.files import MmstabError
from mmstab.model.robot import FloatArray, Robot
from mmstab.planner.fitness import Fitness
from mmstab.planner.regions import CoMRegion, as_region
from mmstab.planner.settings import PlannerSettings
from mmstab.stability.dynamic import dynamic_force_angle


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
    """Tool points (the wrist frame's origin) in B for postures (N, n) [rad] -> (N, 3) [m]."""
    frames = robot.kinematics.link_frames(np.atleast_2d(np.asarray(q, dtype=float)))
    return np.asarray(frames[:, -1, :3, 3])


def tool_map(robot: Robot, region: CoMRegion) -> ToolMap:
    """The :class:`ToolMap` of the workspace's postures: a view of the region, one per robot.

    Raises:
        MmstabError: the workspace keeps no collision-free postures (``valid_q``).
    """
    r = as_region(region)
    return r.view(("tool_map", robot.source_hash), lambda: _tool_map(robot, r.valid_q))


def _tool_map(robot: Robot, valid_q: FloatArray) -> ToolMap:
    q = np.asarray(valid_q, dtype=float).reshape(-1, robot.arm_joints)
    if len(q) == 0:
        raise MmstabError(
            "planner: a tool wrench needs the workspace's collision-free postures (valid_q)"
        )
    return ToolMap(cKDTree(robot.arm_com(q)), tool_points(robot, q))


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


def with_tool_wrench(fitness: Fitness, region: CoMRegion) -> Fitness:
    """``fitness`` with the robot's tool wrench, or ``fitness`` itself without one.

    A :class:`WrenchFitness` offers everything the searches use of a ``Fitness``
    (``mu``, ``__call__``, ``linear``, ``diameter``, ``settings``), hence the cast.
    """
    wrench = fitness.robot.tool_wrench
    if wrench is None:
        return fitness
    loaded = WrenchFitness(fitness, tool_map(fitness.robot, region), np.asarray(wrench, float))
    return cast(Fitness, loaded)
