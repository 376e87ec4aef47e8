"""The coarse pass: Eq. 6 over a strided subset of V's samples, in one batch.

Its best distinct samples, each refined among its nearest samples, are CMA-ES's start
means (``planner.seeding: coarse``) and, along a route, the guard's second start against a
basin the warm start cannot see (:mod:`mmstab.planner.along_route`, the online horizon).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.model.robot import FloatArray
from mmstab.planner.fitness import Fitness
from mmstab.planner.regions import CoMRegion, SampleIndex, as_region

#: Coarse seeds lie at least this share of V's diameter apart (distinct basins).
SEED_SEPARATION = 0.25


def coarse_samples(samples: ArrayLike, count: int) -> FloatArray:
    """Every k-th sample, k chosen so that about ``count`` of them remain (M, 3) [m]."""
    pts = np.asarray(samples, dtype=float).reshape(-1, 3)
    return pts[:: coarse_stride(len(pts), count)]


def coarse_stride(total: int, count: int) -> int:
    """The stride that leaves about ``count`` of ``total`` samples."""
    return max(1, -(-total // max(int(count), 1)))


def sample_index(region: CoMRegion) -> SampleIndex:
    """The region's samples and their k-d tree (:attr:`PlanningRegion.index`, built once)."""
    return as_region(region).index


def coarse_seeds(
    fitness: Fitness,
    index: SampleIndex,
    count: int,
    basins: int,
    neighbours: int,
    seeds: int,
    allowed: NDArray[np.bool_] | None = None,
) -> FloatArray:
    """CMA-ES start means from a coarse evaluation of Eq. 6 over V's samples (S, 3) [m].

    Args:
        fitness: Eq. 6 at the pose.
        index: V's samples and their k-d tree.
        count: how many samples the coarse pass scores (evenly strided).
        basins: how many distinct coarse optima to refine.
        neighbours: each optimum moves to the best of its ``neighbours`` nearest samples
            (0: no refinement).
        seeds: how many of the refined optima to return, best first.
        allowed: which of the samples may be chosen (M,) (``planner.turret_window``);
            default all.

    Greedy: the best coarse sample, then the best one at least ``SEED_SEPARATION`` times
    V's diameter from every one taken so far, and so on; then the local refinement (V's
    optima lie in its thin corners, which a strided subset reaches only nearby).
    """
    pts = coarse_samples(index.samples, count)
    if allowed is not None:  # the same stride, then only the allowed samples
        pts = pts[allowed[:: coarse_stride(len(index.samples), count)]]
    linear = fitness.linear()
    values = linear(pts)
    alive = np.ones(len(pts), dtype=bool)
    min_dist2 = (SEED_SEPARATION * fitness.diameter) ** 2
    chosen: list[FloatArray] = []
    while len(chosen) < basins and alive.any():
        k = int(np.argmax(np.where(alive, values, -np.inf)))
        chosen.append(pts[k])
        alive &= np.sum((pts - pts[k]) ** 2, axis=1) >= min_dist2
    out = np.array(chosen).reshape(-1, 3)
    k = min(int(neighbours), len(index.samples))
    if k > 0 and len(out):
        _, idx = index.tree.query(out, k=k)
        idx = np.asarray(idx).reshape(len(out), k)
        local = linear(index.samples[idx.ravel()]).reshape(idx.shape)
        if allowed is not None:
            local = np.where(allowed[idx], local, -np.inf)
        out = index.samples[idx[np.arange(len(out)), np.argmax(local, axis=1)]]
    _, first = np.unique(out, axis=0, return_index=True)
    out = out[np.sort(first)]
    return out[np.argsort(-linear(out), kind="stable")][:seeds]
