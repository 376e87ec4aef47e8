"""``method: sequence``: the whole path at once over V's postures (:mod:`mmstab.planner.sequence`).

Per pose (a caller planning one pose) it is the exhaustive reference.
"""

from __future__ import annotations

from mmstab.planner.search import PathChoice, PathTask, PoseChoice, PoseTask
from mmstab.planner.searches.exhaustive import ExhaustiveSearch
from mmstab.planner.sequence import solve_sequence


class SequenceSearch:
    """One of V's samples per pose, Eq. 6 summed along the path, collision-free moves."""

    def choose(self, task: PoseTask) -> PoseChoice:
        """The exhaustive answer at a single pose."""
        return ExhaustiveSearch().choose(task)

    def choose_path(self, task: PathTask) -> PathChoice:
        """The chosen samples and their grid postures."""
        seq = solve_sequence(
            task.robot, task.gravity_body, task.region, task.settings, task.mu_max, task.closed
        )
        region = task.region
        return PathChoice(
            target_com=region.index.samples[seq.rows],
            postures=region.postures[seq.rows],
            fitness=seq.fitness,
            mu=seq.mu,
        )
