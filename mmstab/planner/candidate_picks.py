"""The rows a pose's candidates are picked from (:mod:`mmstab.planner.candidates`).

The rank bound of the picks within their turret bins, the round robin over the bins, and
the values of a search's rows, each row scored once per search.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from mmstab.model.robot import FloatArray
from mmstab.planner.fitness import LinearFitness


def rank_bound(bin_rows: NDArray[np.intp], count: int) -> int:
    """The smallest R with Σ_b min(R, n_b) ≥ count: chosen rows rank below R in their bin."""
    n = np.sort(np.asarray(bin_rows))
    for r in range(1, int(n.max(initial=0)) + 1):
        if int(np.minimum(n, r).sum()) >= count:
            return r
    return int(n.max(initial=0))


def spread_top(values: FloatArray, bins: NDArray[np.intp], count: int) -> NDArray[np.intp]:
    """``count`` rows: the best of every turret bin in turn (round robin), best first.

    The same answer as :func:`mmstab.planner.sequence._diverse_top` (ties by row order),
    without a Python loop over the bins.
    """
    order = np.argsort(-values, kind="stable")
    b = bins[order]
    by_bin = np.argsort(b, kind="stable")  # value order kept within each bin
    sb = b[by_bin]
    rank = np.empty(len(order), dtype=np.intp)
    rank[by_bin] = np.arange(len(order)) - np.searchsorted(sb, sb, side="left")
    chosen = order[np.lexsort((-values[order], rank))][:count]
    return chosen[np.argsort(-values[chosen], kind="stable")]


def among(rows: NDArray[np.intp], sorted_rows: NDArray[np.intp]) -> NDArray[np.bool_]:
    """Whether each of ``rows`` is one of ``sorted_rows`` (ascending)."""
    at = np.minimum(np.searchsorted(sorted_rows, rows), max(len(sorted_rows) - 1, 0))
    return np.asarray(sorted_rows[at] == rows) if len(sorted_rows) else np.zeros(len(rows), bool)


def scored_values(
    fit: LinearFitness, samples: FloatArray, rows: NDArray[np.intp], before: NDArray[np.intp],
    values: FloatArray,
) -> FloatArray:  # fmt: skip
    """Eq. 6's values [-] of reach rows ``rows`` (ascending), each scored once a search.

    A row's value does not depend on the rows scored with it, so those of ``before``
    (ascending, the last round's) are taken from their ``values``.

    Args:
        fit: Eq. 6 at the pose.
        samples: the reach rows' arm CoMs, body frame (N, 3) [m].
        rows: the rows to value.
        before: rows valued before.
        values: their values [-].
    """
    at = np.minimum(np.searchsorted(before, rows), max(len(before) - 1, 0))
    old = before[at] == rows if len(before) else np.zeros(len(rows), dtype=bool)
    v = np.empty(len(rows))
    v[old] = values[at[old]]
    v[~old] = fit(samples[rows[~old]])
    return v
