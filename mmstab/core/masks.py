"""Runs of True in a boolean sequence: where a check failed, a margin was crossed, ...

One helper for every stage that reports stretches (collisions along a reference, risk along
a route, stability below a baseline along a run).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def true_runs(mask: ArrayLike) -> NDArray[np.intp]:
    """(first, end) indices of each run of True in ``mask`` (M, 2); ``end`` is exclusive."""
    m = np.asarray(mask, dtype=bool).ravel()
    return np.flatnonzero(np.diff(np.r_[0, m.astype(np.int8), 0])).reshape(-1, 2)
