"""The planner's one interface for a search: what it is given and what it answers.

Planning is one pipeline whatever the search (``docs/planner.md``, "Adding a search"):

1. **candidates**: where the arm CoM may be at a pose (:class:`PlanningRegion`, restricted
   to the turret window when ``planner.turret_window`` binds);
2. **fitness**: Eq. 6 at the pose (``mmstab.planner.fitness``, with the tool wrench);
3. **choice**: the search (this interface), by ``planner.method``
   (:data:`mmstab.planner.searches.SEARCHES`);
4. **postures**: a collision-free posture realising each choice (IK, or the best nearby
   sample of V when IK fails), or the postures a whole-path search chose with its CoMs.

A search chooses per pose (:class:`PoseSearch`: ``choose`` a CoM among the candidates
with the fitness) or, in addition, along the whole path at once (:class:`PathSearch`:
``choose_path``, e.g. ``sequence``); a whole-path search still answers per pose (``choose``),
for the callers that plan one pose (the atlas, Fig. 7). A per-pose search that a route
plans pose after pose also answers a pose warm-started from the previous one's answer
(:class:`WarmSearch`: ``warm``, :mod:`mmstab.planner.along_route`). The pipeline steps 1, 2
and 4 are :mod:`mmstab.planner.pose` and :mod:`mmstab.planner.along_path`.
"""

from __future__ import annotations

from typing import Any, NamedTuple, Protocol, runtime_checkable

import numpy as np

from mmstab.model.robot import FloatArray, Robot
from mmstab.planner.fitness import Fitness
from mmstab.planner.regions import PlanningRegion
from mmstab.planner.settings import PlannerSettings
from mmstab.terrain import Terrain


class PoseTask(NamedTuple):
    """One pose's search problem.

    Attributes:
        robot: the robot.
        region: the candidates: where the arm CoM may be (windowed when a window binds).
        fitness: Eq. 6 at the pose (to maximise), batched over CoMs (N, 3) [m].
        settings: the planner settings.
        rng: the planner's generator (the only source of randomness).
        starts: start means a caller fixed (S, 3) [m] (e.g. a warm start), else None.
    """

    robot: Robot
    region: PlanningRegion
    fitness: Fitness
    settings: PlannerSettings
    rng: np.random.Generator
    starts: FloatArray | None = None


class SearchResult(NamedTuple):
    """One CMA-ES run from one start.

    Attributes:
        start_com: the start mean [m].
        best_com: best feasible arm CoM found [m].
        best_fitness: its fitness.
        history: best fitness of each iteration (I,).
        first_samples: the first population (popsize, 3) [m], feasible.
        evaluations: samples told to CMA-ES.
        resamples: samples discarded (re-asked) for lying outside V.
        iterations: CMA iterations.
        popsize: the population size of this run.
        sigma0: its initial step size [m].
    """

    start_com: FloatArray
    best_com: FloatArray
    best_fitness: float
    history: FloatArray
    first_samples: FloatArray
    evaluations: int
    resamples: int
    iterations: int
    popsize: int
    sigma0: float


class ExhaustiveResult(NamedTuple):
    """The best sample of V at one pose.

    Attributes:
        best_com: the best sample's arm CoM, body frame (3,) [m].
        best_fitness: its Eq. 6 fitness.
        best_index: its row in the samples.
        evaluations: samples scored.
        seconds: wall time of the scoring [s].
    """

    best_com: FloatArray
    best_fitness: float
    best_index: int
    evaluations: int
    seconds: float


class PoseChoice(NamedTuple):
    """A search's answer at one pose.

    Attributes:
        target_com: the chosen arm CoM, body frame (3,) [m].
        fitness: its Eq. 6 fitness.
        runs: the CMA-ES runs, if any.
        best_start: index of the run kept (-1 without runs).
        exhaustive: the exhaustive result, if the search scored every sample.
    """

    target_com: FloatArray
    fitness: float
    runs: tuple[SearchResult, ...] = ()
    best_start: int = -1
    exhaustive: ExhaustiveResult | None = None


class WarmTask(NamedTuple):
    """A pose along a route warm-started from the previous pose's answer.

    Attributes:
        region: the planning region.
        fitness: Eq. 6 at the pose (to maximise), batched over CoMs (N, 3) [m].
        settings: the planner settings (population, tolerances).
        rng: the planner's generator.
        starts: start means, body frame (3,) each [m]: the previous answer, and the
            guard's second start when it found one.
        sigma: the warm step size [m].
    """

    region: PlanningRegion
    fitness: Fitness
    settings: PlannerSettings
    rng: np.random.Generator
    starts: list[FloatArray]
    sigma: float


class PathTask(NamedTuple):
    """A whole path's search problem.

    Attributes:
        robot: the robot.
        region: where the arm CoM may be (its samples, their postures).
        gravity_body: gravity in the body frame at each pose (K, 3) [m/s^2].
        settings: the planner settings.
        mu_max: Eq. 6's normaliser [N rad].
        closed: the path is a loop (the last pose moves back to the first).
        poses: the base poses (K, 3) [m, m, rad], for messages naming a pose (or None).
        terrain: the ground the poses rest on (or None): a search that checks the arm
            against the ground under it (``roadmap``) reads it through its interface.
    """

    robot: Robot
    region: PlanningRegion
    gravity_body: FloatArray
    settings: PlannerSettings
    mu_max: float
    closed: bool
    poses: FloatArray | None = None
    terrain: Terrain | None = None


class PathChoice(NamedTuple):
    """A whole-path search's answer: a CoM and its posture per pose.

    Attributes:
        target_com: chosen arm CoMs, body frame (K, 3) [m].
        postures: collision-free postures realising them (K, 4) [rad].
        fitness: Eq. 6 per pose, with the previous pose's choice as previous CoM (K,).
        mu: force-angle measure per pose (K,) [N rad].
        moves: the arm's path into each pose's posture (K arrays (n, 4) [rad]) where the
            search knows one (``roadmap``), else empty: straight joint-space moves.
        turns: the turns ``planner.turn_slide`` priced over its limit (``roadmap``): per
            turn its ``first`` and ``last`` pose, ``turn_rad``, the slide ``slide_m`` [m]
            with the first search's postures, the ``poses`` constrained (empty: none could
            be, the first answer kept).
    """

    target_com: FloatArray
    postures: FloatArray
    fitness: FloatArray
    mu: FloatArray
    moves: tuple[FloatArray, ...] = ()
    turns: tuple[dict[str, Any], ...] = ()


@runtime_checkable
class PoseSearch(Protocol):
    """A search that chooses the arm CoM at one pose."""

    def choose(self, task: PoseTask) -> PoseChoice:
        """The best CoM it finds among ``task.region`` by ``task.fitness``."""
        ...


@runtime_checkable
class PathSearch(Protocol):
    """A search that chooses along the whole path at once (and per pose, ``choose``)."""

    def choose(self, task: PoseTask) -> PoseChoice:
        """Its answer at a single pose."""
        ...

    def choose_path(self, task: PathTask) -> PathChoice:
        """A CoM and a posture per pose, chosen together."""
        ...


@runtime_checkable
class WarmSearch(Protocol):
    """A per-pose search that also answers a pose warm-started from the one before."""

    def warm(self, task: WarmTask) -> PoseChoice:
        """The best CoM it finds from ``task.starts`` with step size ``task.sigma``."""
        ...
