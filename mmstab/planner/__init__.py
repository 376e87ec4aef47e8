"""Stability planner (paper Section II-D, Eq. 6; ``docs/planner.md``).

Modules: ``settings`` (the ``planner`` section), ``fitness`` (Eq. 6 per population and
as a batched affine form), ``exhaustive`` (the reference over all of V's samples, coarse
seeds), ``cmaes`` (pycma ask/tell, IPOP restarts), ``path`` (per pose and along a path).
"""

from mmstab.planner.cmaes import (
    Generation,
    SearchResult,
    ask_generation,
    ranking_values,
    solve_ipop,
    solve_start,
)
from mmstab.planner.exhaustive import (
    ExhaustiveResult,
    SampleIndex,
    best_mu,
    coarse_samples,
    coarse_seeds,
    sample_index,
    solve_exhaustive,
)
from mmstab.planner.fitness import (
    CoMRegion,
    Fitness,
    LinearFitness,
    linear_fitness,
    pose_fitness,
    region_samples,
)
from mmstab.planner.path import (
    Plan,
    PoseTarget,
    gravity_body_at,
    plan_path,
    solve_path,
    solve_pose,
    start_coms,
)
from mmstab.planner.regions import SampleRegion, planning_region, sample_region
from mmstab.planner.settings import PlannerSettings

__all__ = [
    "CoMRegion",
    "ExhaustiveResult",
    "Fitness",
    "Generation",
    "LinearFitness",
    "Plan",
    "PlannerSettings",
    "PoseTarget",
    "SampleIndex",
    "SampleRegion",
    "SearchResult",
    "ask_generation",
    "best_mu",
    "coarse_samples",
    "coarse_seeds",
    "gravity_body_at",
    "linear_fitness",
    "plan_path",
    "planning_region",
    "pose_fitness",
    "ranking_values",
    "region_samples",
    "sample_index",
    "sample_region",
    "solve_exhaustive",
    "solve_ipop",
    "solve_path",
    "solve_pose",
    "solve_start",
    "start_coms",
]
