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
from mmstab.planner.fitness import Fitness, LinearFitness, linear_fitness, region_samples
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

    Exact, but not every sample is scored on every tip-over axis: a strided subset's best
    is a lower bound, and a sample whose running minimum over the axes falls below it
    cannot be the best (:func:`max_min_mu`).

    Args:
        robot: the robot.
        gravity_body: gravity in B at the pose (3,) [m/s^2].
        samples: arm CoMs, body frame (N, 3) [m].
        polygon_body: the support polygon in B (n, 3) [m] (``None``: the tracks' rectangle).

    Returns:
        (mu [N rad], row of the sample reaching it: the first such row).
    """
    polygon = base_polygon(robot).vertices if polygon_body is None else polygon_body
    fit = linear_fitness(robot, polygon, gravity_body, np.zeros(3), 1.0, 0.0)
    return max_min_mu(fit, samples)


#: Rows of the subset whose best μ bounds the pruning from below.
SUBSET_ROWS = 2048


def max_min_mu(fit: LinearFitness, samples: ArrayLike) -> tuple[float, int]:
    """``(max(fit.mu(samples)), first argmax)``, pruned axis by axis (exact).

    μ of a sample is ``force · min_j θ_j`` over the tip-over axes; the best sample's μ is
    at least the best of a strided subset's (the bound). The axes are taken in the order
    that binds the subset most often, and after each the samples whose running minimum
    is below the bound (less a relative 1e-9 for the per-axis products' rounding) are
    dropped. The survivors are scored with :meth:`LinearFitness.mu` itself, so the value
    and row are those of scoring every sample.
    """
    coms = np.atleast_2d(np.asarray(samples, dtype=float))
    n = len(coms)
    if n <= 4 * SUBSET_ROWS:
        mu = fit.mu(coms)
        k = int(np.argmax(mu))
        return float(mu[k]), k
    subset = np.arange(0, n, max(n // SUBSET_ROWS, 1))
    sub = coms[subset]
    theta = np.arctan2(sub @ fit.sin_gain + fit.sin_offset, sub @ fit.cos_gain + fit.cos_offset)
    bound = float(theta.min(axis=1).max()) * fit.force  # the subset's best μ
    order = np.argsort(-np.bincount(theta.argmin(axis=1), minlength=theta.shape[1]), kind="stable")
    floor = (bound - 1e-9 * abs(bound)) / fit.force
    alive = np.arange(n)
    running = np.full(n, np.inf)
    for j in order:
        c = coms[alive]
        th = np.arctan2(c @ fit.sin_gain[:, j] + fit.sin_offset[j],
                        c @ fit.cos_gain[:, j] + fit.cos_offset[j])  # fmt: skip
        running = np.minimum(running, th)
        keep = running >= floor
        alive, running = alive[keep], running[keep]
    mu = fit.mu(coms[alive])
    k = int(np.argmax(mu))
    return float(mu[k]), int(alive[k])


class ExhaustiveSearch:
    """The reference: the best of the region's samples, scored in one batch."""

    def choose(self, task: PoseTask) -> PoseChoice:
        """The best sample of ``task.region`` by ``task.fitness``."""
        ex = solve_exhaustive(task.fitness, region_samples(task.region))
        return PoseChoice(ex.best_com, ex.best_fitness, exhaustive=ex)

    def warm(self, task: WarmTask) -> PoseChoice:
        """A route's later pose: the warm-started CMA-ES (:meth:`CmaesSearch.warm`)."""
        return CmaesSearch().warm(task)
