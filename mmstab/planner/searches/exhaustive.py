"""``method: exhaustive``: Eq. 6 over every candidate sample (:mod:`mmstab.planner.exhaustive`)."""

from __future__ import annotations

from mmstab.planner.exhaustive import solve_exhaustive
from mmstab.planner.fitness import region_samples
from mmstab.planner.search import PoseChoice, PoseTask


class ExhaustiveSearch:
    """The reference: the best of the region's samples, scored in one batch."""

    def choose(self, task: PoseTask) -> PoseChoice:
        """The best sample of ``task.region`` by ``task.fitness``."""
        ex = solve_exhaustive(task.fitness, region_samples(task.region))
        return PoseChoice(ex.best_com, ex.best_fitness, exhaustive=ex)
