"""``method: exhaustive``: Eq. 6 over every sample of V at a pose, in one batch (the reference).

V's samples are the collision-free grid CoMs that V contains (``Workspace.valid_com_in_V``).
Their best is the ground truth the CMA-ES planner is measured against (tests, ``make
bench-plan``); ``planner.method: exhaustive`` plans with it (:class:`ExhaustiveSearch`).
The same batched scoring of a strided subset seeds CMA-ES (:mod:`mmstab.planner.searches.
coarse`). Along a route the exhaustive reference has no warm-started form of its own: the
poses after the first run the warm CMA-ES (:meth:`ExhaustiveSearch.warm`).
"""

from __future__ import annotations

import time

import numpy as np
from numpy.typing import ArrayLike

from mmstab.model.robot import Robot
from mmstab.planner.fitness import Fitness, linear_fitness, region_samples
from mmstab.planner.searches.base import ExhaustiveResult, PoseChoice, PoseTask, WarmTask
from mmstab.planner.searches.cmaes import CmaesSearch
from mmstab.stability.static import base_polygon


def solve_exhaustive(fitness: Fitness, samples: ArrayLike) -> ExhaustiveResult:
    """Score every sample (N, 3) [m] with Eq. 6 in one vectorised call; keep the best.

    Raises:
        ValueError: no samples.
    """
    t0 = time.perf_counter()
    pts = np.asarray(samples, dtype=float).reshape(-1, 3)
    if len(pts) == 0:
        raise ValueError("no samples to score")
    values = fitness.linear()(pts)
    k = int(np.argmax(values))
    return ExhaustiveResult(
        best_com=pts[k].copy(),
        best_fitness=float(values[k]),
        best_index=k,
        evaluations=len(pts),
        seconds=time.perf_counter() - t0,
    )


def best_mu(
    robot: Robot,
    gravity_body: ArrayLike,
    samples: ArrayLike,
    polygon_body: ArrayLike | None = None,
) -> tuple[float, int]:
    """The largest force-angle measure over arm-CoM samples (N, 3) [m] at a pose.

    Args:
        robot: the robot.
        gravity_body: gravity in B at the pose (3,) [m/s^2].
        samples: arm CoMs, body frame (N, 3) [m].
        polygon_body: the support polygon in B (n, 3) [m] (``None``: the tracks' rectangle).

    Returns:
        (mu [N rad], row of the sample reaching it).
    """
    polygon = base_polygon(robot).vertices if polygon_body is None else polygon_body
    mu = linear_fitness(robot, polygon, gravity_body, np.zeros(3), 1.0, 0.0).mu(samples)
    k = int(np.argmax(mu))
    return float(mu[k]), k


class ExhaustiveSearch:
    """The reference: the best of the region's samples, scored in one batch."""

    def choose(self, task: PoseTask) -> PoseChoice:
        """The best sample of ``task.region`` by ``task.fitness``."""
        ex = solve_exhaustive(task.fitness, region_samples(task.region))
        return PoseChoice(ex.best_com, ex.best_fitness, exhaustive=ex)

    def warm(self, task: WarmTask) -> PoseChoice:
        """A route's later pose: the warm-started CMA-ES (:meth:`CmaesSearch.warm`)."""
        return CmaesSearch().warm(task)
