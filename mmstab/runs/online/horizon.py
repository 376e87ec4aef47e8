"""The receding horizon: the route's planned poses ahead of the robot, on the latest map.

The horizon holds the poses of the route's planning grid (``planner.spacing`` apart, as the
offline plan) from the one behind the robot to ``online.horizon`` metres ahead. At every map
update each of them rests on the new map; a pose is **re-planned** when it is new or when
the map changed its ground (gravity in B turned by more than ``online.replan_tol``), and
kept otherwise, so the answer of a pose whose ground the map confirms is the one already
found (a warm start that has converged). A pose whose footprint the map does not cover
(off the window or on unknown cells) is **uncovered**: reported, never guessed, and its
previous answer (if any) is not trusted for μ.

Re-planning a pose is the offline route planner's warm step
(:mod:`mmstab.planner.along_route`): Eq. 6 at the pose, CMA-ES started from the previous
pose's answer and this pose's last answer, plus the coarse guard's seed when it finds a
better basin; the very first pose is searched cold (:func:`mmstab.planner.solve_pose`,
CMA-ES). Its posture comes from the same IK (collision-free, from the previous pose's
posture), with the same fallback to V's samples.
"""

from __future__ import annotations

import time
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from mmstab.core.files import MmstabError
from mmstab.model.robot import FloatArray, Robot
from mmstab.planner.along_route import warm_pose, warm_settings, warm_sigma
from mmstab.planner.fitness import Fitness, pose_fitness, support_polygons_at
from mmstab.planner.pose import Realise, realise_target, solve_pose
from mmstab.planner.regions import PlanningRegion, SampleIndex
from mmstab.planner.searches.coarse import SEED_SEPARATION, coarse_seeds
from mmstab.planner.settings import PlannerSettings
from mmstab.stability.dynamic import robot_mu
from mmstab.stability.static import mu_max as stowed_flat_mu
from mmstab.terrain import Terrain
from mmstab.terrain.base import GRAVITY_G
from mmstab.terrain.heightmap_terrain import HeightmapTerrain
from mmstab.terrain.rest.types import RestPoses


class HorizonPose(NamedTuple):
    """One planned pose of the horizon.

    Attributes:
        k: its index on the route's planning grid.
        s: its arc length [m].
        pose: (x, y, yaw) in the map frame [m, m, rad].
        gravity_body: gravity in B at rest on the map it was planned on [m/s^2].
        target_com: the planned arm CoM, body frame [m].
        q: the planned posture [rad].
        mu: μ of that posture there [N rad].
        collision_free: the posture is collision-free.
        planned_at: the time of the update that planned it [s].
    """

    k: int
    s: float
    pose: FloatArray
    gravity_body: FloatArray
    target_com: FloatArray
    q: FloatArray
    mu: float
    collision_free: bool
    planned_at: float


class HorizonUpdate(NamedTuple):
    """What one update did to the horizon.

    Attributes:
        replanned: grid indices re-planned.
        kept: grid indices whose answer the new map confirmed.
        uncovered: grid indices the map does not cover.
    """

    replanned: tuple[int, ...]
    kept: tuple[int, ...]
    uncovered: tuple[int, ...]


class Rested(NamedTuple):
    """Poses rested on one map, each where the map covers it.

    Attributes:
        covered: the map covers the pose's contacts (N,).
        gravity_body: gravity in B (N, 3) [m/s^2] (NaN where not covered).
        ground: the local ground (z [m], roll [rad], pitch [rad]) (N, 3) (NaN where not).
        G_T_B: the resting body poses in G (N, 4, 4) [m] (NaN where not covered).
    """

    covered: NDArray[np.bool_]
    gravity_body: FloatArray
    ground: FloatArray
    G_T_B: FloatArray


def rest_where_covered(terrain: HeightmapTerrain, poses: FloatArray) -> Rested:
    """Rest poses (N, 3) on a map, all at once.

    A pose off the window or on unknown cells is not covered (NaN); each pose's rest is its
    own, so the others come out as if rested alone.
    """
    return rested_rows(terrain.rest(poses, strict=False), len(poses))


def rested_rows(r: RestPoses, n: int) -> Rested:
    """The first ``n`` rows of a batched rest (``strict=False``) as :class:`Rested`."""
    covered, gravity, ground = np.zeros(n, bool), np.full((n, 3), np.nan), np.full((n, 3), np.nan)
    G_T_B = np.full((n, 4, 4), np.nan)
    idx = np.flatnonzero(np.isfinite(r.z[:n]))
    covered[idx] = True
    gravity[idx] = np.einsum("nji,j->ni", r.G_T_B[idx, :3, :3], GRAVITY_G)
    ground[idx] = np.stack([r.z[idx], r.roll[idx], r.pitch[idx]], axis=1)
    G_T_B[idx] = r.G_T_B[idx]
    return Rested(covered, gravity, ground, G_T_B)


def horizon_window(s_grid: FloatArray, s_now: float, ahead: float) -> list[int]:
    """Grid indices from the pose at or behind ``s_now`` [m] to ``ahead`` [m] past it."""
    first = max(int(np.searchsorted(s_grid, s_now, side="right")) - 1, 0)
    last = int(np.searchsorted(s_grid, s_now + ahead, side="right"))
    return list(range(first, max(last, first + 1)))


def sort_poses(
    ks: list[int], rested: Rested, known: dict[int, FloatArray], tol: float
) -> HorizonUpdate:
    """Which horizon poses to plan again, which the map confirms, which it does not cover.

    Args:
        ks: the horizon's grid indices, in driving order.
        rested: those poses rested on the map.
        known: gravity in B [m/s^2] on which each pose was last planned, by grid index.
        tol: the gravity change that plans a pose again [rad].
    """
    replanned, kept, uncovered = [], [], []
    for i, k in enumerate(ks):
        if not rested.covered[i]:  # off the window or on unknown cells
            uncovered.append(k)
        elif k in known and angle_between(rested.gravity_body[i], known[k]) <= tol:
            kept.append(k)
        else:
            replanned.append(k)
    return HorizonUpdate(tuple(replanned), tuple(kept), tuple(uncovered))


def angle_between(a: FloatArray, b: FloatArray) -> float:
    """The angle between two vectors [rad]."""
    c = float(np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b)))
    return float(np.arccos(np.clip(c, -1.0, 1.0)))


class HorizonPlanner:
    """The horizon's plans, updated map by map (module text).

    Args:
        robot: the robot.
        region: the planning region (V).
        settings: the planner settings (their warm form re-plans; ``seed`` seeds it).
        s_grid: arc lengths of the route's planned poses (K,) [m].
        poses_grid: those poses (K, 3) in the map frame.
        realise: the IK ``(target_com, previous_q) -> (q, collision_free)``.
        replan_tol: gravity change that re-plans a pose [rad].
    """

    def __init__(
        self,
        robot: Robot,
        region: PlanningRegion,
        settings: PlannerSettings,
        s_grid: FloatArray,
        poses_grid: FloatArray,
        realise: Realise,
        replan_tol: float,
    ) -> None:
        self.robot, self.region, self.realise = robot, region, realise
        self.settings = settings._replace(method="cmaes", seeding="coarse")
        self.s_grid, self.poses_grid, self.replan_tol = s_grid, poses_grid, replan_tol
        self.rng = np.random.default_rng(settings.seed)
        self.mu_max = stowed_flat_mu(robot)
        self.plans: dict[int, HorizonPose] = {}
        self.moved = settings.sigma0_metres(region.diameter)
        self.index: SampleIndex | None
        try:
            self.index = region.index
        except MmstabError:  # a region without samples: no guard
            self.index = None

    def window(self, s_now: float, ahead: float) -> list[int]:
        """Grid indices from the pose at or behind ``s_now`` [m] to ``ahead`` [m] past it."""
        return horizon_window(self.s_grid, s_now, ahead)

    def update(
        self,
        terrain: Terrain,
        ks: list[int],
        rested: Rested,
        now: float,
        arm_com: FloatArray,
        arm_q: FloatArray,
    ) -> HorizonUpdate:
        """Re-plan the horizon's poses whose ground changed on the latest map.

        Args:
            terrain: the latest map (bound to the robot).
            ks: the horizon's grid indices, in driving order.
            rested: those poses rested on the map (:func:`rest_where_covered`).
            now: the update's time [s].
            arm_com: the arm's CoM now, body frame [m] (the first pose's previous answer).
            arm_q: the arm's posture now [rad].
        """
        known = {k: p.gravity_body for k, p in self.plans.items()}
        changes = sort_poses(ks, rested, known, self.replan_tol)
        for k in changes.replanned:  # in driving order: each after its predecessor's answer
            g = rested.gravity_body[ks.index(k)]
            before = self.plans.get(k - 1)
            prev_com, prev_q = (arm_com, arm_q) if before is None else (before.target_com, before.q)
            self.plans[k] = self._plan(terrain, k, g, prev_com, prev_q, self.plans.get(k), now)
        return changes

    def reference(
        self, s: float, spacing: float
    ) -> tuple[FloatArray | None, FloatArray | None, float]:
        """The planned arm CoM [m], posture [rad] and μ [N rad] at ``s`` [m], between plans.

        Interpolated between the planned poses within ``2 spacing`` [m] of ``s``.
        """
        plans = self.plans
        known = sorted(k for k in plans if abs(plans[k].s - s) <= 2 * spacing)
        if not known:
            return None, None, float("nan")
        ss = np.array([plans[k].s for k in known])
        pick = lambda name: np.array([getattr(plans[k], name) for k in known])  # noqa: E731
        coms, qs, mus = pick("target_com"), pick("q"), pick("mu")
        interp = lambda v: np.array([np.interp(s, ss, v[:, i]) for i in range(v.shape[1])])  # noqa: E731
        return interp(coms), interp(qs), float(np.interp(s, ss, mus))

    def _plan(
        self,
        terrain: Terrain,
        k: int,
        g: FloatArray,
        prev_com: FloatArray,
        prev_q: FloatArray,
        old: HorizonPose | None,
        now: float,
    ) -> HorizonPose:
        """Plan pose ``k`` (gravity ``g`` in B) after ``prev_com`` [m] / ``prev_q`` [rad]."""
        t0, pose, s = time.perf_counter(), self.poses_grid[k], self.settings
        if not self.plans:  # the first pose: a cold search
            target = solve_pose(
                self.robot, terrain, self.region, pose, prev_com, s, self.rng, self.mu_max
            )
        else:
            polygons = support_polygons_at(self.robot, terrain, pose)  # the loaded support
            fit = pose_fitness(
                self.robot, g, prev_com, s, self.mu_max, self.region.diameter,
                None if polygons is None else polygons[0],
            )  # fmt: skip
            starts = [prev_com] if old is None else [prev_com, old.target_com]
            guard = self._guard(fit, prev_com)
            if guard is not None:
                starts.append(guard)
            sigma = warm_sigma(s, self.region.diameter, self.moved)
            target = warm_pose(fit, self.region, pose, starts, sigma, warm_settings(s, sigma),
                               self.rng, t0)  # fmt: skip
        target, q, ok = realise_target(
            self.robot, terrain, self.region, target, prev_com, s, self.mu_max, self.realise,
            prev_q,
        )  # fmt: skip
        self.moved = float(np.linalg.norm(target.target_com - prev_com)) or self.moved
        mu = float(robot_mu(self.robot, g, q)[0])
        return HorizonPose(k, float(self.s_grid[k]), pose, g, target.target_com, q, mu, ok, now)

    def _guard(self, fit: Fitness, prev_com: FloatArray) -> FloatArray | None:
        """The coarse guard's seed when it beats staying and lies in another basin."""
        if self.index is None:
            return None
        s = self.settings
        seed = coarse_seeds(
            fit, self.index, s.coarse_samples, s.coarse_basins, s.coarse_neighbours, 1
        )
        if not len(seed):
            return None
        linear = fit.linear()
        far = np.linalg.norm(seed[0] - prev_com) > SEED_SEPARATION * self.region.diameter
        if far and linear(seed)[0] > linear(prev_com)[0]:
            return np.asarray(seed[0])
        return None
