"""``method: cmaes``: CMA-ES from each start mean, the best run kept (:mod:`mmstab.planner.cmaes`).

The start means are the caller's (``PoseTask.starts``, e.g. a warm start), else the FK
CoMs of ``planner.starts`` (the paper) or, with ``seeding: coarse``, the best distinct
samples of a coarse batched evaluation of Eq. 6 over the region's samples.
"""

from __future__ import annotations

import numpy as np

from mmstab.model.robot import FloatArray
from mmstab.planner.cmaes import solve_ipop, start_coms
from mmstab.planner.exhaustive import coarse_seeds
from mmstab.planner.search import PoseChoice, PoseTask


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
