"""Where a sequence of postures collides: a reference or a run, checked sample by sample.

The posture reference and the start-up approach of a run (:mod:`mmstab.control.posture`,
:mod:`mmstab.control.approach`) and the tracked run itself (:mod:`mmstab.outputs.tracking`)
are checked at every sample with :class:`~mmstab.model.collision.CollisionChecker`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.core.masks import true_runs
from mmstab.model.collision import CollisionChecker


class SequenceCollisions(NamedTuple):
    """Where a sequence of postures collides.

    Attributes:
        samples: postures checked.
        colliding_samples: how many of them collide.
        colliding_share: their share of ``samples`` [-].
        intervals: colliding runs, each [x of its first colliding sample, x of the first free
            sample after it (or of the last sample)], in the unit of the sample coordinate x.
        pairs: colliding pairs of bodies, with the number of samples each, most frequent first.
    """

    samples: int
    colliding_samples: int
    colliding_share: float
    intervals: list[list[float]]
    pairs: dict[str, int]


def sequence_collisions(
    checker: CollisionChecker, x: ArrayLike, q: ArrayLike
) -> tuple[SequenceCollisions, NDArray[np.bool_]]:
    """Check a sequence of postures and summarise where it collides.

    Args:
        checker: the robot's collision checker.
        x: the samples' coordinate (N,), increasing (time [s] or path fraction [-]).
        q: arm postures (N, 4) [rad].

    Returns:
        The summary, and the per-sample answer (N,) (True = some pair collides).
    """
    xs = np.asarray(x, dtype=float)
    qa = np.atleast_2d(np.asarray(q, dtype=float))
    hit = np.asarray(checker.collides(qa), dtype=bool)
    edges = true_runs(hit)
    intervals = [[float(xs[a]), float(xs[min(b, xs.size - 1)])] for a, b in edges.tolist()]
    counts: dict[str, int] = {}
    unique, repeats = np.unique(qa[hit], axis=0, return_counts=True)  # each posture once
    for q_k, n in zip(unique, repeats, strict=True):
        for name in checker.colliding_pairs(q_k):
            counts[name] = counts.get(name, 0) + int(n)
    pairs = dict(sorted(counts.items(), key=lambda kv: -kv[1]))
    report = SequenceCollisions(
        int(hit.size), int(hit.sum()), float(hit.mean()) if hit.size else 0.0, intervals, pairs
    )
    return report, hit
