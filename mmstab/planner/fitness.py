"""Eq. 6 at one base pose: per population (``Fitness``) and over all of V (``LinearFitness``).

    fitness = w_stability mu(g_a) / mu_max - w_motion |g_a - g_a_prev|^2 / d_workspace^2

``Fitness`` evaluates the force-angle measure as :func:`mmstab.stability.static.force_angle_batch`
does (the first release's numbers, bit for bit). ``LinearFitness`` is the same function
written for many CoMs at once: at a fixed pose every force-angle axis's sine and cosine
parts are affine in the arm CoM (below), so scoring every sample of V is two small matrix
products and one ``arctan2``.

For axis j (unit direction a_j, end vertex p_j) and net force f = m_T g_B, with
l_j = Phi_j (p_j - g_o) and f_j = Phi_j f (``mmstab.stability.static``)::

    (l_j x f_j) . a_j = det[p_j - g_o, f, a_j] = (p_j - g_o) . (f x a_j)
    l_j . f_j         = (p_j - g_o) . f_j

(removing the a_j components of two columns leaves the determinant unchanged), and
g_o = (m_a g_a + m_b c_b) / m_T is affine in g_a.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.core.files import MmstabError
from mmstab.model.robot import FloatArray, Robot
from mmstab.planner.regions import CoMRegion, as_region
from mmstab.planner.settings import PlannerSettings
from mmstab.stability.static import base_polygon, force_angle_batch
from mmstab.terrain import Terrain
from mmstab.terrain.base import GRAVITY_G
from mmstab.terrain.polygon import support_vertices

#: Rows per block of the batched evaluation (keeps temporaries in cache).
BLOCK = 32768


def region_samples(region: CoMRegion) -> FloatArray:
    """The region's samples: the collision-free grid CoMs it holds (M, 3) [m].

    Raises:
        MmstabError: the region holds none.
    """
    samples = as_region(region).samples
    if samples.size == 0:
        raise MmstabError(
            "planner: the workspace V holds no collision-free grid CoM (exhaustive and "
            "coarse-seeded planning score V's samples); V may be empty"
        )
    return samples.reshape(-1, 3)


class Fitness(NamedTuple):
    """Eq. 6 for one base pose, evaluated for a whole population at once."""

    robot: Robot
    polygon: FloatArray  # ordered support polygon in B (n, 3) [m]
    gravity_body: FloatArray  # (3,) [m/s^2]
    previous_com: FloatArray  # (3,) body frame [m]
    mu_max: float  # [N rad]
    diameter: float  # [m]
    settings: PlannerSettings

    def mu(self, com_body: ArrayLike) -> FloatArray:
        """Force-angle measure for arm CoMs (N, 3) [m] -> (N,) [N rad] (as robot_force_angle)."""
        overall = self.robot.overall_com(np.atleast_2d(com_body))
        return force_angle_batch(
            self.polygon, overall, self.robot.total_mass * self.gravity_body
        ).mu

    def __call__(self, com_body: ArrayLike) -> FloatArray:
        """Fitness (to maximise) of arm CoMs (N, 3) [m] -> (N,)."""
        coms = np.atleast_2d(com_body)
        motion = np.sum((coms - self.previous_com) ** 2, axis=1) / self.diameter**2
        s = self.settings
        return s.w_stability * self.mu(coms) / self.mu_max - s.w_motion * motion

    def linear(self) -> LinearFitness:
        """The same Eq. 6 as affine maps, for scoring many CoMs (see the module text)."""
        s = self.settings
        return linear_fitness(
            self.robot,
            self.polygon,
            self.gravity_body,
            self.previous_com,
            s.w_stability / self.mu_max,
            s.w_motion / self.diameter**2,
        )


def linear_fitness(
    robot: Robot,
    polygon: ArrayLike,
    gravity_body: ArrayLike,
    previous_com: ArrayLike,
    w_stability: float,
    w_motion: float,
) -> LinearFitness:
    """Eq. 6 at one pose in affine form (see the module text).

    Args:
        robot: the robot (masses, base CoM).
        polygon: ordered support polygon in B (n, 3) [m].
        gravity_body: gravity in B (3,) [m/s^2].
        previous_com: previous arm CoM, body frame (3,) [m].
        w_stability: omega_1 / mu_max [1/(N rad)].
        w_motion: omega_2 / d_workspace^2 [1/m^2].
    """
    r = robot
    p = np.asarray(polygon, dtype=float)
    p_end = np.roll(p, -1, axis=0)  # axis j runs from vertex j to vertex j + 1
    a_hat = (p_end - p) / np.linalg.norm(p_end - p, axis=1, keepdims=True)
    f = r.total_mass * np.asarray(gravity_body, dtype=float).reshape(3)
    w = np.cross(f, a_hat)  # (n, 3): sine part's direction
    f_perp = f - (a_hat @ f)[:, None] * a_hat  # (n, 3): cosine part's direction
    alpha = r.arm_mass / r.total_mass
    base = r.base.mass * np.asarray(r.base.com, dtype=float) / r.total_mass
    return LinearFitness(
        sin_gain=-alpha * w.T,
        sin_offset=np.sum((p_end - base) * w, axis=1),
        cos_gain=-alpha * f_perp.T,
        cos_offset=np.sum((p_end - base) * f_perp, axis=1),
        force=float(np.linalg.norm(f)),
        previous_com=np.asarray(previous_com, dtype=float).reshape(3),
        w_stability=float(w_stability),
        w_motion=float(w_motion),
    )


class LinearFitness(NamedTuple):
    """Eq. 6 at one pose as affine sine/cosine parts per tip-over axis (n axes).

    Attributes:
        sin_gain: d(sine part)/d g_a (3, n) [N].
        sin_offset: sine part at g_a = 0 (n,) [N m].
        cos_gain: d(cosine part)/d g_a (3, n) [N].
        cos_offset: cosine part at g_a = 0 (n,) [N m].
        force: |f_r| = m_T |g| [N].
        previous_com: the previous arm CoM (3,) [m].
        w_stability: omega_1 / mu_max [1/(N rad)].
        w_motion: omega_2 / d_workspace^2 [1/m^2].
    """

    sin_gain: FloatArray
    sin_offset: FloatArray
    cos_gain: FloatArray
    cos_offset: FloatArray
    force: float
    previous_com: FloatArray
    w_stability: float
    w_motion: float

    def mu(self, com_body: ArrayLike) -> FloatArray:
        """Force-angle measure of arm CoMs (N, 3) [m] -> (N,) [N rad]."""
        coms = np.atleast_2d(np.asarray(com_body, dtype=float))
        out = np.empty(len(coms))
        for s in range(0, len(coms), BLOCK):
            c = coms[s : s + BLOCK]
            sin, cos = c @ self.sin_gain, c @ self.cos_gain
            sin += self.sin_offset  # in place: the same sums, fewer arrays
            cos += self.cos_offset
            theta = np.arctan2(sin, cos, out=sin)
            least = out[s : s + BLOCK]  # theta.min(axis=1), a column at a time (faster)
            least[:] = theta[:, 0]
            for j in range(1, theta.shape[1]):
                np.minimum(least, theta[:, j], out=least)
        out *= self.force
        return out

    def __call__(self, com_body: ArrayLike) -> FloatArray:
        """Eq. 6 fitness of arm CoMs (N, 3) [m] -> (N,)."""
        coms = np.atleast_2d(np.asarray(com_body, dtype=float))
        if (
            self.w_motion == 0.0
            and np.isfinite(coms).all()
            and np.isfinite(self.previous_com).all()
        ):
            return self.w_stability * self.mu(coms)  # x - 0 * (a finite motion) is x itself
        motion = np.sum((coms - self.previous_com) ** 2, axis=1)
        return self.w_stability * self.mu(coms) - self.w_motion * motion


def pose_fitness(
    robot: Robot,
    gravity_body: ArrayLike,
    previous_com: ArrayLike,
    settings: PlannerSettings,
    mu_max: float,
    diameter: float,
    polygon_body: ArrayLike | None = None,
) -> Fitness:
    """Eq. 6 at a pose where gravity in the body frame is ``gravity_body`` (3,) [m/s^2].

    Args:
        robot: the robot.
        gravity_body: gravity in B at the pose [m/s^2] (from the terrain).
        previous_com: arm CoM at the previous pose, body frame (3,) [m].
        settings: planner settings (the weights).
        mu_max: normaliser [N rad].
        diameter: d_workspace [m].
        polygon_body: the ordered support polygon in B (n, 3) [m] the pose stands on
            (:func:`mmstab.planner.pose.support_polygons_at`); ``None``: the tracks'
            rectangle (a plane).
    """
    polygon = base_polygon(robot).vertices if polygon_body is None else polygon_body
    return Fitness(
        robot=robot,
        polygon=np.asarray(polygon, dtype=float),
        gravity_body=np.asarray(gravity_body, dtype=float).reshape(3),
        previous_com=np.asarray(previous_com, dtype=float),
        mu_max=float(mu_max),
        diameter=float(diameter),
        settings=settings,
    )


def support_polygons_at(
    robot: Robot, terrain: Terrain, poses: ArrayLike
) -> list[FloatArray] | None:
    """The support polygon in B at each pose's rest with the arm stowed, (n, 3) each [m].

    What the planner ranks arm CoMs on: the hull (seen along gravity, ordered
    counter-clockwise about the body's up) of the contacts that carry the stowed robot's
    load (:mod:`mmstab.stability.support`), so that the stowed arm scores exactly the μ the
    plan reports for it. Fewer than three such contacts (a line): the tracks' rectangle.
    ``None`` on a plane, where the support is the tracks' rectangle whatever the load.

    Args:
        robot: the robot.
        terrain: the ground.
        poses: base poses (N, 3) in M [m, m, rad].
    """
    if terrain.kind != "heightmap":
        return None
    ground = terrain
    if getattr(terrain, "robot", None) is not robot:
        ground = terrain.with_robot(robot, getattr(terrain, "flipper_angle", None))
    P = np.atleast_2d(np.asarray(poses, dtype=float))
    com = robot.overall_com(robot.arm_com(robot.stowed))
    rest = ground.rest(P, strict=False, com_body=com)  # type: ignore[attr-defined]
    points = ground.candidates.points  # type: ignore[attr-defined]
    rectangle = base_polygon(robot).vertices
    out = []
    for i in range(len(P)):
        R = rest.G_T_B[i, :3, :3]
        if not np.isfinite(R).all():
            out.append(rectangle)
            continue
        poly, line = support_vertices(points[rest.bearing[i]], R.T @ GRAVITY_G)
        out.append(rectangle if line or len(poly) < 3 else poly)
    return out


def same_axes(fits: list[LinearFitness]) -> list[LinearFitness]:
    """The fits with as many tip-over axes each, for the batched bounds over poses.

    Poses whose support polygons differ in vertex count get their first axis repeated: a
    repeated axis leaves μ (the minimum over the axes) unchanged.
    """
    n = max(f.sin_offset.shape[0] for f in fits)

    def pad(f: LinearFitness) -> LinearFitness:
        k = n - f.sin_offset.shape[0]
        if k == 0:
            return f
        cols = np.r_[np.arange(f.sin_offset.shape[0]), np.zeros(k, dtype=int)]
        return f._replace(
            sin_gain=f.sin_gain[:, cols], sin_offset=f.sin_offset[cols],
            cos_gain=f.cos_gain[:, cols], cos_offset=f.cos_offset[cols],
        )  # fmt: skip

    return [pad(f) for f in fits]
