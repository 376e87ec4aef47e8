"""A warm-started CMA-ES for one pose along a route, the population as one NumPy batch.

pycma costs about 1.3 ms of Python per iteration and 2.5 ms to set up, more than a whole
warm-started pose may take (10 ms). This is the textbook (mu/mu_w, lambda) CMA-ES (Hansen,
"The CMA Evolution Strategy: A Tutorial", 2016: weights, cumulation, rank-one and rank-mu
updates, cumulative step-size adaptation) for the 3-D arm CoM, with pycma's ask/tell shape
(:class:`WarmCMA`: ``ask()``, ``tell(solutions, values)``, ``stop()``, ``result``) and the
same handling of V as :mod:`~mmstab.planner.searches.cmaes.pycma_runs`: samples outside V
are re-asked up to ``max_resample`` rounds (drawn up front, one membership test per
iteration), those still outside are ranked below every feasible one
(:func:`~mmstab.planner.searches.cmaes.pycma_runs.ranking_values`). Its draws come from the
caller's generator.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from mmstab.model.robot import FloatArray
from mmstab.planner.regions import CoMRegion
from mmstab.planner.searches.cmaes.pycma_runs import ranking_values

#: CMA-ES iterations of a warm-started pose (a cold start uses ``planner.max_iterations``).
WARM_ITERATIONS = 8
#: Iterations whose populations' fitness ranges must all be below ``tol_fitness`` to stop.
FLAT_ITERATIONS = 3


class WarmResult(NamedTuple):
    """One warm CMA-ES run.

    Attributes:
        best_com: best feasible arm CoM (3,) [m] (the start when nothing beat it).
        best_fitness: its fitness.
        iterations: CMA iterations.
        evaluations: samples scored.
        resamples: samples re-asked for lying outside V.
        sigma: the final step size [m].
    """

    best_com: FloatArray
    best_fitness: float
    iterations: int
    evaluations: int
    resamples: int
    sigma: float


class _Strategy(NamedTuple):
    """The textbook constants of a (mu/mu_w, lambda) CMA-ES in n dimensions (Hansen 2016)."""

    lam: int
    mu: int
    weights: FloatArray
    mueff: float
    cc: float
    cs: float
    c1: float
    cmu: float
    damps: float
    chi_n: float


def _strategy(n: int, popsize: int) -> _Strategy:
    lam = int(popsize)
    mu = lam // 2
    w = np.log(mu + 0.5) - np.log(np.arange(1, mu + 1))
    w /= w.sum()
    mueff = 1.0 / np.sum(w**2)
    cc = (4 + mueff / n) / (n + 4 + 2 * mueff / n)
    cs = (mueff + 2) / (n + mueff + 5)
    c1 = 2 / ((n + 1.3) ** 2 + mueff)
    cmu = min(1 - c1, 2 * (mueff - 2 + 1 / mueff) / ((n + 2) ** 2 + mueff))
    damps = 1 + 2 * max(0.0, np.sqrt((mueff - 1) / (n + 1)) - 1) + cs
    chi_n = np.sqrt(n) * (1 - 1 / (4 * n) + 1 / (21 * n**2))
    return _Strategy(lam, mu, w, mueff, cc, cs, c1, cmu, damps, chi_n)


class _State(NamedTuple):
    """The search distribution: mean [m], step size [m], covariance and its eigen-basis."""

    mean: FloatArray
    sigma: float
    C: FloatArray
    B: FloatArray
    D: FloatArray
    pc: FloatArray
    ps: FloatArray


class _Population(NamedTuple):
    """One iteration's population (lambda, 3) [m], its membership, re-asks, share inside."""

    x: FloatArray
    inside: NDArray[np.bool_]
    resamples: int
    share: float


def _draw(
    st: _State,
    cma: _Strategy,
    region: CoMRegion,
    rng: np.random.Generator,
    share: float,
    max_resample: int,
) -> _Population:
    """Draw a population, the re-asks drawn up front with one membership test.

    The first lambda draws inside V (in drawing order) are the population, topped up with
    outside ones if too few; as many draws as the last share inside V asks for, at most
    ``max_resample`` + 1 rounds.
    """
    lam, n = cma.lam, len(st.mean)
    draws = min(
        int(np.ceil(1.2 * lam / max(share, 1.0 / (max_resample + 1)))), (max_resample + 1) * lam
    )
    z_all = rng.standard_normal((draws, n))
    x_all = st.mean + st.sigma * z_all @ (st.B * st.D).T
    inside_all = region.contains(x_all)
    order_in = np.flatnonzero(inside_all)
    take = np.r_[order_in[:lam], np.flatnonzero(~inside_all)[: lam - min(lam, order_in.size)]]
    last = int(take.max()) + 1 if order_in.size >= lam else x_all.shape[0]
    resamples = int(np.sum(~inside_all[:last])) - int(np.sum(~inside_all[take]))
    share = max(float(inside_all.mean()), 1e-3)
    return _Population(x_all[take], inside_all[take], resamples, share)


def _update(st: _State, cma: _Strategy, x: FloatArray, order: NDArray[np.intp], it: int) -> _State:
    """The CMA update from a ranked population (best first): mean, paths, C, sigma."""
    n, w, mueff, cs, cc = len(st.mean), cma.weights, cma.mueff, cma.cs, cma.cc
    y = (x[order[: cma.mu]] - st.mean) / st.sigma
    y_w = w @ y
    mean = st.mean + st.sigma * y_w
    inv_sqrt_C = (st.B / st.D) @ st.B.T
    ps = (1 - cs) * st.ps + np.sqrt(cs * (2 - cs) * mueff) * inv_sqrt_C @ y_w
    h_sig = np.linalg.norm(ps) / np.sqrt(1 - (1 - cs) ** (2 * it)) / cma.chi_n < 1.4 + 2 / (n + 1)
    pc = (1 - cc) * st.pc + h_sig * np.sqrt(cc * (2 - cc) * mueff) * y_w
    C = (
        (1 - cma.c1 - cma.cmu) * st.C
        + cma.c1 * (np.outer(pc, pc) + (1 - h_sig) * cc * (2 - cc) * st.C)
        + cma.cmu * (y.T * w) @ y
    )
    sigma = st.sigma * np.exp((cs / cma.damps) * (np.linalg.norm(ps) / cma.chi_n - 1))
    C = (C + C.T) / 2
    D2, B = np.linalg.eigh(C)
    D = np.sqrt(np.maximum(D2, 1e-20))
    return _State(mean, sigma, C, B, D, pc, ps)


class WarmCMA:
    """The warm CMA-ES as an ask/tell object (pycma's ``CMAEvolutionStrategy`` shape).

    ``ask()`` draws a population inside V (re-asks up front), ``tell(solutions, values)``
    ranks it by Eq. 6 (maximised; the samples outside V below every feasible one) and
    updates the distribution, ``stop()`` says whether a budget or tolerance is reached, and
    ``result`` is the run so far (:class:`WarmResult`). The start is a candidate when it
    lies inside V.

    Args:
        fitness: Eq. 6 of a batch of arm CoMs (N, 3) [m] -> (N,) (scores the start).
        region: the workspace V (``contains``, ``violation``, ``diameter``).
        start_com: the mean to start from, body frame (3,) [m].
        sigma0: initial step size [m].
        rng: the generator the samples are drawn from.
        popsize: lambda, samples per iteration.
        max_iterations: iteration budget.
        max_resample: re-ask rounds for samples outside V per iteration.
        tol_x: stop when sigma times the largest axis is below this [m].
        tol_fitness: stop when the range of a population's fitness stayed below this for
            ``FLAT_ITERATIONS`` iterations.
    """

    def __init__(
        self,
        fitness: Callable[..., FloatArray],
        region: CoMRegion,
        start_com: FloatArray,
        sigma0: float,
        rng: np.random.Generator,
        popsize: int,
        max_iterations: int,
        max_resample: int,
        tol_x: float,
        tol_fitness: float,
    ) -> None:
        n = 3
        self._cma = _strategy(n, popsize)
        self._region, self._rng = region, rng
        self._max_iterations, self._max_resample = max_iterations, max_resample
        self._tol_x, self._tol_fitness = tol_x, tol_fitness
        self._diameter = float(region.diameter)
        mean = np.asarray(start_com, dtype=float).copy()
        self._st = _State(
            mean, float(sigma0), np.eye(n), np.eye(n), np.ones(n), np.zeros(n), np.zeros(n)
        )
        self._best_com, self._best_f = mean.copy(), -np.inf
        if region.contains(mean[None])[0]:
            self._best_f = float(fitness(mean[None])[0])
        self._spread: list[float] = []
        self._evaluations = self._resamples = 0
        self._share = 1.0  # share of the last draws inside V
        self._iterations = 0
        self._stopped = False
        self._inside: NDArray[np.bool_] = np.ones(0, dtype=bool)

    def stop(self) -> bool:
        """Whether the run is over: its iteration budget spent, or a tolerance reached."""
        return self._stopped or self._iterations >= self._max_iterations

    def ask(self) -> FloatArray:
        """The next population (lambda, 3) [m], inside V where the re-asks allowed."""
        self._iterations += 1
        pop = _draw(self._st, self._cma, self._region, self._rng, self._share, self._max_resample)
        self._inside, self._share = pop.inside, pop.share
        self._resamples += pop.resamples
        return pop.x

    def tell(self, solutions: FloatArray, values: FloatArray) -> None:
        """Rank the asked population by its Eq. 6 values (N,) (maximised) and update."""
        x, f, inside, lam = solutions, values, self._inside, self._cma.lam
        self._evaluations += lam
        violation = self._region.violation(x) if not inside.all() else np.zeros(lam)
        order = np.argsort(ranking_values(f, inside, violation, self._diameter), kind="stable")
        feasible = np.where(inside, f, -np.inf)
        k = int(np.argmax(feasible))
        if feasible[k] > self._best_f:
            self._best_f, self._best_com = float(feasible[k]), x[k].copy()
        self._st = st = _update(self._st, self._cma, x, order, self._iterations)
        if st.sigma * st.D.max() < self._tol_x:
            self._stopped = True
            return
        self._spread.append(float(np.ptp(f[inside])) if inside.any() else np.inf)
        flat = self._spread[-FLAT_ITERATIONS:]
        if len(self._spread) >= FLAT_ITERATIONS and max(flat) < self._tol_fitness:
            self._stopped = True  # the populations' values agree (pycma's tolfun)

    @property
    def result(self) -> WarmResult:
        """The run so far: the best feasible CoM (the start when nothing beat it)."""
        return WarmResult(
            self._best_com, self._best_f, self._iterations, self._evaluations,
            self._resamples, self._st.sigma,
        )  # fmt: skip


def warm_cma(
    fitness: Callable[..., FloatArray],
    region: CoMRegion,
    start_com: FloatArray,
    sigma0: float,
    rng: np.random.Generator,
    popsize: int,
    max_iterations: int,
    max_resample: int,
    tol_x: float,
    tol_fitness: float,
) -> WarmResult:
    """Maximise ``fitness`` over V from ``start_com``: :class:`WarmCMA` run to its stop.

    The arguments are :class:`WarmCMA`'s.
    """
    es = WarmCMA(
        fitness, region, start_com, sigma0, rng, popsize, max_iterations, max_resample,
        tol_x, tol_fitness,
    )  # fmt: skip
    while not es.stop():
        x = es.ask()
        es.tell(x, fitness(x))
    return es.result
