"""Stability planner (paper Section II-D, Eq. 6; ``docs/planner.md``).

One pipeline, candidates -> fitness -> choice -> postures, around one search interface:

- ``regions`` (where the arm CoM may be, with its cached views), ``fitness`` (Eq. 6 per
  population and in batched affine form), ``wrench`` (the tool wrench in Eq. 6),
  ``turret`` (the turret window);
- ``searches`` (the registry, one module per search with the algorithm it runs, behind
  the interface a search implements, ``searches.base``): ``exhaustive`` (every sample),
  ``cmaes`` (pycma ask/tell, IPOP; and the compact warm-started CMA-ES of the same
  ask/tell shape), ``sequence`` (the whole path by dynamic programming), ``roadmap``; the
  coarse pass that seeds them (``searches.coarse``);
- ``pose`` (one pose through the pipeline), ``along_path`` (poses in turn, or a
  whole-path search), ``along_route`` (along a route, each pose warm-started), ``risk``
  (where a route is at risk), ``plan`` (a problem's plan), ``levers`` (the flippers);
- ``ground``: the ground under the arm, one check for the planner and the online loop.
"""

from mmstab.planner.along_path import Plan, solve_path
from mmstab.planner.along_route import RoutePlan, solve_route
from mmstab.planner.fitness import (
    CoMRegion,
    Fitness,
    LinearFitness,
    linear_fitness,
    pose_fitness,
    region_samples,
)
from mmstab.planner.plan import plan_path, plan_problem, plan_route
from mmstab.planner.pose import PoseTarget, gravity_body_at, solve_pose
from mmstab.planner.regions import (
    PlanningRegion,
    SampleBalls,
    SampleIndex,
    as_region,
    planning_region,
    sample_region,
)
from mmstab.planner.risk import RiskStretch, RouteRisk, route_risk, stretches
from mmstab.planner.searches import SEARCHES, search_for
from mmstab.planner.searches.base import (
    PathChoice,
    PathSearch,
    PathTask,
    PoseChoice,
    PoseSearch,
    PoseTask,
)
from mmstab.planner.searches.cmaes import (
    Generation,
    SearchResult,
    ask_generation,
    ranking_values,
    solve_ipop,
    solve_start,
    start_coms,
)
from mmstab.planner.searches.coarse import coarse_samples, coarse_seeds, sample_index
from mmstab.planner.searches.exhaustive import best_mu, solve_exhaustive
from mmstab.planner.settings import PlannerSettings

__all__ = [
    "SEARCHES",
    "CoMRegion",
    "ExhaustiveResult",
    "Fitness",
    "Generation",
    "LinearFitness",
    "PathChoice",
    "PathSearch",
    "PathTask",
    "Plan",
    "PlannerSettings",
    "PlanningRegion",
    "PoseChoice",
    "PoseSearch",
    "PoseTarget",
    "PoseTask",
    "RiskStretch",
    "RoutePlan",
    "RouteRisk",
    "SampleIndex",
    "SampleBalls",
    "SearchResult",
    "as_region",
    "ask_generation",
    "best_mu",
    "coarse_samples",
    "coarse_seeds",
    "gravity_body_at",
    "linear_fitness",
    "plan_path",
    "plan_problem",
    "plan_route",
    "planning_region",
    "pose_fitness",
    "ranking_values",
    "region_samples",
    "route_risk",
    "sample_index",
    "sample_region",
    "search_for",
    "solve_exhaustive",
    "solve_ipop",
    "solve_path",
    "solve_pose",
    "solve_route",
    "solve_start",
    "start_coms",
    "stretches",
]
