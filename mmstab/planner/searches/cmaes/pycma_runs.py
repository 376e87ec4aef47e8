"""CMA-ES over the arm CoM in V by pycma (ask/tell), one population evaluated per batch.

Samples outside V are discarded and re-asked (the paper); after ``max_resample`` rounds
those still outside are told ranked below every feasible sample (``ranking_values``).
``solve_ipop`` adds IPOP restarts (the population doubled at each). Every run draws from
the caller's ``numpy.random.Generator``; the global NumPy state is untouched.
"""

from __future__ import annotations

import warnings
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from mmstab.core.files import PlanningError
from mmstab.model.robot import FloatArray, Robot
from mmstab.planner.fitness import Fitness
from mmstab.planner.regions import CoMRegion, as_region
from mmstab.planner.searches.base import SearchResult

#: IPOP's population factor per restart (pycma's ``incpopsize``).
IPOP_FACTOR = 2


class Generation(NamedTuple):
    """One CMA generation: samples (popsize, 3) [m], their membership of V, re-asked count."""

    samples: FloatArray
    inside: NDArray[np.bool_]
    discarded: int


def ask_generation(es: Any, region: CoMRegion, rounds: int) -> Generation:
    """Ask a population; re-ask (discard) samples outside V for up to ``rounds`` rounds.

    The paper discards samples outside V. When the optimum lies in a thin part of V, pure
    rejection hides the constraint from CMA-ES (its step size never shrinks) and the
    feasible fraction collapses; so after ``rounds`` re-asks the samples still outside
    are kept and told ranked below every feasible one (see :func:`solve_start`).
    """
    X = np.array(es.ask())
    inside = region.contains(X)
    discarded = 0
    for _ in range(rounds):
        if inside.all():
            break
        k = int((~inside).sum())
        discarded += k
        X[~inside] = np.array(es.ask(k))
        inside = region.contains(X)
    return Generation(X, inside, discarded)


def ranking_values(
    fitness: FloatArray, inside: NDArray[np.bool_], violation: FloatArray, diameter: float
) -> FloatArray:
    """Values for pycma, which minimises.

    Inside V: -fitness. Outside: worse than every feasible sample, increasing with the
    distance to V, so CMA-ES learns where V ends without ever choosing such a sample.
    """
    values = -fitness.copy()
    worst = values[inside].max() if inside.any() else 0.0
    values[~inside] = worst + 1.0 + violation[~inside] / diameter
    return values


def solve_start(
    fitness: Fitness,
    region: CoMRegion,
    start_com: FloatArray,
    rng: np.random.Generator,
    sigma0: float | None = None,
    popsize: int | None = None,
    keep_start: bool = False,
) -> SearchResult:
    """Run CMA-ES (ask/tell) from one start CoM, keeping every told sample inside V.

    Args:
        fitness: Eq. 6 at this pose.
        region: the workspace V.
        start_com: initial mean, body frame (3,) [m].
        rng: the generator CMA draws from (its own, never NumPy's global one).
        sigma0: initial step size [m]; default ``settings.sigma0`` (in metres).
        popsize: population size; default ``settings.popsize``.
        keep_start: count the start itself as a candidate when it lies in V (a coarse
            seed, already a sample of V, is then never lost).
    """
    s = fitness.settings
    sigma0 = s.sigma0 if sigma0 is None else float(sigma0)
    popsize = s.popsize if popsize is None else int(popsize)
    opts = {
        "seed": np.nan,  # pycma would otherwise reseed NumPy's global generator
        "randn": lambda *shape: rng.standard_normal(shape),
        "popsize": popsize,
        "maxiter": s.max_iterations,
        "tolfun": s.tol_fitness,
        "tolx": s.tol_x,
        "verbose": -9,
        "verb_log": 0,
        "verb_disp": 0,
    }
    import cma  # here, not at the top: pycma loads SciPy's stats and pyplot (0.7 s a process)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # pycma warns about unused/odd settings
        es = cma.CMAEvolutionStrategy(list(start_com), sigma0, opts)
    best_com, best_f = np.asarray(start_com, float), -np.inf
    start_inside = bool(region.contains(best_com[None])[0])
    if keep_start and start_inside:
        best_f = float(fitness(best_com)[0])
    history, first, evaluations, resamples = [], None, 0, 0
    while not es.stop():
        gen = ask_generation(es, region, s.max_resample)
        if not gen.inside.any() and first is None and not start_inside:
            raise PlanningError(
                f"planner: no CMA-ES sample fell in the workspace V "
                f"({s.max_resample} re-asks from {np.round(start_com, 3)} m, itself outside V); "
                "V may be empty"
            )
        f = fitness(gen.samples)
        violation = region.violation(gen.samples) if not gen.inside.all() else np.zeros(len(f))
        es.tell(list(gen.samples), list(ranking_values(f, gen.inside, violation, fitness.diameter)))
        resamples += gen.discarded
        evaluations += len(f)
        feasible_f = np.where(gen.inside, f, -np.inf)
        if first is None:
            first = gen.samples[gen.inside].copy()
        k = int(np.argmax(feasible_f))
        if feasible_f[k] > best_f:
            best_f, best_com = float(feasible_f[k]), gen.samples[k].copy()
        history.append(best_f)
    return SearchResult(
        start_com=np.asarray(start_com, float),
        best_com=best_com,
        best_fitness=best_f,
        history=np.array(history),
        first_samples=first if first is not None else np.empty((0, 3)),
        evaluations=evaluations,
        resamples=resamples,
        iterations=int(es.countiter),
        popsize=popsize,
        sigma0=sigma0,
    )


def solve_ipop(
    fitness: Fitness,
    region: CoMRegion,
    start_com: FloatArray,
    rng: np.random.Generator,
    sigma0: float,
    restarts: int,
    keep_start: bool = False,
) -> tuple[SearchResult, ...]:
    """CMA-ES from one start, then ``restarts`` IPOP restarts (population x2 each).

    Every restart starts again from ``start_com`` with the same ``sigma0`` [m] (pycma's
    IPOP with a fixed ``x0``); the caller keeps the best run. ``keep_start``: as in
    :func:`solve_start`.
    """
    popsize = fitness.settings.popsize
    return tuple(
        solve_start(fitness, region, start_com, rng, sigma0, popsize * IPOP_FACTOR**k, keep_start)
        for k in range(restarts + 1)
    )


def start_coms(robot: Robot, region: CoMRegion, starts: tuple[float, ...]) -> FloatArray:
    """Start means of CMA-ES, body frame (S, 3) [m].

    The FK arm CoMs of link0 at each angle (``starts`` [rad]) with the other joints at zero
    (paper); a start outside the region (a coarse grid's hull may miss the stretched arm)
    moves to the region's nearest sample.
    """
    region = as_region(region)
    q = np.zeros((len(starts), robot.arm_joints))
    q[:, 0] = starts
    coms = robot.arm_com(q)
    outside = ~region.contains(coms)
    if outside.any():
        inside = region.samples
        if len(inside):
            for k in np.flatnonzero(outside):
                coms[k] = inside[np.argmin(np.sum((inside - coms[k]) ** 2, axis=1))]
    return coms
