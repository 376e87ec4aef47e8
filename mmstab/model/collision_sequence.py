"""Where a sequence of postures collides: a reference or a run, checked sample by sample.

The posture reference and the start-up approach of a run (:mod:`mmstab.control.posture`,
:mod:`mmstab.control.approach`) and the tracked run itself (:mod:`mmstab.outputs.tracking`)
are checked at every sample with :class:`~mmstab.model.collision.CollisionChecker`.

Such a sequence is dense and mostly far from contact: a reference sampled every control
period moves the arm by fractions of a millimetre between samples. A pair's distance shrinks
by at most twice the most any arm point moves (both bodies may move), and a joint move by
Δq moves no point more than Σ_j reach_j |Δq_j| (:func:`mmstab.model.reach.joint_reach`, over
the sequence's own postures). So the distance at every :data:`ANCHOR_STRIDE`-th sample
(FCL, :meth:`~mmstab.model.collision.CollisionChecker.clearance`) proves the samples near it
free, and only the others are checked (:func:`proven_free`): the same answer in a fraction
of the FCL calls (``tests/model/test_collision_sequence.py``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.core.masks import true_runs
from mmstab.model.collision import CollisionChecker
from mmstab.model.reach import joint_reach
from mmstab.model.robot import FloatArray

#: Samples from one anchor (a sample whose distance is measured) to the next.
ANCHOR_STRIDE = 16
#: Largest distance [m] measured exactly at the anchors (twice the arm's most motion from one
#: anchor to the next): beyond it the sequence is too sparse for the anchors to pay (a run
#: saved every 10 ms: 2.8 m; a reference every control period: 5-60 mm).
MAX_REACH_OUT = 0.1
#: Slack taken off a measured distance [m]: FCL's GJK distances are not exact to round-off.
SLACK = 1e-6


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
    hit = np.zeros(len(qa), dtype=bool)
    todo = np.flatnonzero(~proven_free(checker, qa))
    if todo.size:
        hit[todo] = np.asarray(checker.collides(qa[todo]), dtype=bool)
    edges = true_runs(hit)
    intervals = [[float(xs[a]), float(xs[min(b, xs.size - 1)])] for a, b in edges.tolist()]
    pairs = pair_counts(checker, qa[hit])
    report = SequenceCollisions(
        int(hit.size), int(hit.sum()), float(hit.mean()) if hit.size else 0.0, intervals, pairs
    )
    return report, hit


def pair_counts(checker: CollisionChecker, q: FloatArray) -> dict[str, int]:
    """The pairs that collide at colliding postures q (M, n) [rad], with the samples each.

    Most frequent first; ties in the order in which the postures, sorted, first show them
    (each distinct posture checked once, every pair whose bounding spheres may touch).
    """
    unique, repeats = np.unique(q, axis=0, return_counts=True)
    if not len(unique):
        return {}
    R, p = checker.shape_poses(unique)
    rows = np.arange(len(unique))
    found = []  # (-samples, first posture, pair index, name)
    for index, pair in enumerate(checker.pairs):
        near = rows[checker._may_touch(pair, p, rows)]
        hit = near[checker._fcl(pair, R, p, near)] if near.size else near
        if hit.size:
            found.append((-int(repeats[hit].sum()), int(hit[0]), index, pair.name))
    return {name: -neg for neg, _, _, name in sorted(found)}


def proven_free(checker: CollisionChecker, q: FloatArray) -> NDArray[np.bool_]:
    """The samples of a sequence (N, n) [rad] that its anchors' distances prove free (N,).

    Sample i between anchors a < i < b is free when either anchor's distance exceeds twice
    the arm's motion bound from it to i (module text), less :data:`SLACK`. Distances are
    measured exactly up to twice the largest motion between two anchors (beyond it, a lower
    bound: enough). A sequence too short for anchors, or too sparse
    (:data:`MAX_REACH_OUT`), proves nothing.
    """
    n = len(q)
    if n < 2 * ANCHOR_STRIDE:
        return np.zeros(n, dtype=bool)
    reach = joint_reach(checker.robot, q)
    motion = np.r_[0.0, np.cumsum(np.abs(np.diff(q, axis=0)) @ reach)]  # from sample 0 [m]
    anchors = np.unique(np.r_[np.arange(0, n, ANCHOR_STRIDE), n - 1])
    reach_out = 2.0 * float(np.diff(motion[anchors]).max()) + 2 * SLACK
    if reach_out > MAX_REACH_OUT:  # a sparse sequence: the distances would cost more
        return np.zeros(n, dtype=bool)
    d = checker.clearance(q[anchors], cull_above=reach_out) - SLACK
    i = np.arange(n)
    k = np.searchsorted(anchors, i, side="right") - 1  # the anchor at or before i
    left, right = anchors[k], anchors[np.minimum(k + 1, len(anchors) - 1)]
    dl, dr = d[k], d[np.minimum(k + 1, len(anchors) - 1)]
    return (dl > 2.0 * (motion - motion[left])) | (dr > 2.0 * (motion[right] - motion))
