"""``method: cmaes``: CMA-ES from each start mean, the best run kept.

The start means are the caller's (``PoseTask.starts``, e.g. a warm start), else the FK
CoMs of ``planner.starts`` (the paper) or, with ``seeding: coarse``, the best distinct
samples of a coarse batched evaluation of Eq. 6 over the region's samples
(:mod:`mmstab.planner.searches.coarse`). A cold pose runs pycma (ask/tell, IPOP restarts,
:mod:`~mmstab.planner.searches.cmaes.pycma_runs`); a route's later poses, warm-started
from the previous answer, run the compact CMA-ES of the same ask/tell shape
(:mod:`~mmstab.planner.searches.cmaes.warm`).
"""

from __future__ import annotations

import numpy as np

from mmstab.model.robot import FloatArray
from mmstab.planner.searches.base import PoseChoice, PoseTask, WarmTask
from mmstab.planner.searches.cmaes.pycma_runs import (
    IPOP_FACTOR,
    Generation,
    SearchResult,
    ask_generation,
    ranking_values,
    solve_ipop,
    solve_start,
    start_coms,
)
from mmstab.planner.searches.cmaes.warm import WARM_ITERATIONS, WarmCMA, WarmResult, warm_cma
from mmstab.planner.searches.coarse import coarse_seeds

__all__ = [
    "IPOP_FACTOR",
    "WARM_ITERATIONS",
    "CmaesSearch",
    "Generation",
    "SearchResult",
    "WarmCMA",
    "WarmResult",
    "ask_generation",
    "ranking_values",
    "solve_ipop",
    "solve_start",
    "start_coms",
    "warm_cma",
]


class CmaesSearch:
    """CMA-ES (pycma) inside the region from each start; IPOP restarts per ``restarts``."""

    def starts(self, task: PoseTask) -> FloatArray:
        """The start means (S, 3) [m] (module text)."""
        s, region = task.settings, task.region
        if task.starts is not None:
            return task.starts
        if s.seeding == "coarse":
            return coarse_seeds(
                task.fitness,
                region.index,
                s.coarse_samples,
                s.coarse_basins,
                s.coarse_neighbours,
                s.coarse_seeds,
                region.allowed,
            )
        return start_coms(task.robot, region, s.starts)

    def choose(self, task: PoseTask) -> PoseChoice:
        """The best CoM of the runs from every start."""
        s = task.settings
        sigma0 = s.sigma0_metres(task.fitness.diameter)
        coarse = s.seeding == "coarse"
        f, region, rng = task.fitness, task.region, task.rng
        runs = tuple(
            run
            for c in self.starts(task)
            for run in solve_ipop(f, region, c, rng, sigma0, s.restarts, coarse)
        )
        best = int(np.argmax([r.best_fitness for r in runs]))
        return PoseChoice(runs[best].best_com, runs[best].best_fitness, runs, best)

    def warm(self, task: WarmTask) -> PoseChoice:
        """The best of :func:`warm_cma` from each start (``WARM_ITERATIONS`` at most).

        Eq. 6 in its affine form per tip-over axis (cheaper per batch) drives the search;
        the answer's fitness is Eq. 6's own.
        """
        s, fit = task.settings, task.fitness
        linear = fit.linear()  # the same Eq. 6, affine per tip-over axis: cheaper per batch
        runs = [
            warm_cma(
                linear.__call__,
                task.region,
                c,
                task.sigma,
                task.rng,
                s.popsize,
                min(s.max_iterations, WARM_ITERATIONS),
                s.max_resample,
                s.tol_x,
                s.tol_fitness,
            )
            for c in task.starts
        ]
        best = int(np.argmax([r.best_fitness for r in runs]))
        com = runs[best].best_com
        return PoseChoice(com, float(fit(com)[0]), best_start=best)
