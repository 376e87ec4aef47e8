"""Where the planner may put the arm CoM (``workspace.method``; ``docs/planner.md``).

- ``hull_difference`` (the paper, default): V = hull(all CoMs) minus hull(colliding CoMs),
  the :class:`mmstab.workspace.Workspace` itself. Conservative: it drops every
  collision-free CoM inside hull(colliding), e.g. all CoMs near the stowed arm's.
- ``valid_samples``: the collision-free grid CoMs themselves, each thickened to a ball of
  the cloud's typical spacing (:class:`SampleRegion`). Every collision-free grid CoM is in
  it; a point between samples is only as safe as its nearest sample (the realising
  posture is collision-checked after planning, as with V).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from mmstab.model.robot import FloatArray

#: Membership slack [m] (as ``mmstab.workspace.HULL_TOL``).
TOL = 1e-9
#: Sample pairs used to estimate the cloud's spacing.
SPACING_SAMPLES = 4096


@dataclass(frozen=True, eq=False)
class SampleRegion:
    """The collision-free CoM samples of a workspace, each a ball of ``radius`` [m].

    Attributes:
        workspace: the labelled workspace (``valid_com``, ``valid_q``, ``diameter``).
        radius: ball radius [m]; default (:func:`sample_region`): the median distance
            from a sample to its nearest other sample.
    """

    workspace: Any
    radius: float

    @property
    def diameter(self) -> float:
        """d_workspace of Eq. 6: the workspace's (hull of all CoMs) [m], as for V."""
        return float(self.workspace.diameter)

    @property
    def valid_com(self) -> FloatArray:
        """Every collision-free grid CoM (N, 3) [m]."""
        return np.asarray(self.workspace.valid_com)

    @property
    def valid_q(self) -> FloatArray:
        """Their postures (N, 4) [rad]."""
        return np.asarray(self.workspace.valid_q)

    @property
    def valid_com_in_V(self) -> FloatArray:
        """The region's samples: every collision-free grid CoM (N, 3) [m]."""
        return self.valid_com

    @functools.cached_property
    def _tree(self) -> cKDTree:
        return cKDTree(self.valid_com)

    def distance(self, points: ArrayLike) -> FloatArray:
        """Distance of body-frame points (N, 3) to the nearest sample (N,) [m]."""
        d, _ = self._tree.query(np.atleast_2d(np.asarray(points, dtype=float)))
        return np.asarray(d, dtype=float)

    def contains(self, points: ArrayLike) -> NDArray[np.bool_]:
        """Whether points (N, 3) [m] lie within ``radius`` of a collision-free sample."""
        return self.distance(points) <= self.radius + TOL

    def violation(self, points: ArrayLike) -> FloatArray:
        """How far points (N, 3) lie outside the region, 0 inside [m]."""
        d = self.distance(points) - self.radius
        return np.where(d <= TOL, 0.0, np.maximum(d, TOL))

    def nearest_valid_posture(self, point: ArrayLike) -> FloatArray:
        """The collision-free grid posture whose CoM is nearest to a point [rad]."""
        return np.asarray(self.workspace.nearest_valid_posture(point))


def sample_region(workspace: Any, rng: np.random.Generator | None = None) -> SampleRegion:
    """The ``valid_samples`` region of a workspace, its radius the cloud's median spacing.

    Args:
        workspace: the labelled workspace.
        rng: draws the samples whose spacing is measured; default a generator seeded 0.
    """
    com = np.asarray(workspace.valid_com)
    rng = np.random.default_rng(0) if rng is None else rng
    rows = rng.choice(len(com), size=min(SPACING_SAMPLES, len(com)), replace=False)
    d, _ = cKDTree(com).query(com[rows], k=2)
    return SampleRegion(workspace, float(np.median(d[:, 1])))


def planning_region(workspace: Any, method: str) -> Any:
    """The region for ``workspace.method``: V itself or :class:`SampleRegion`."""
    if method == "hull_difference":
        return workspace
    if method == "valid_samples":
        return sample_region(workspace)
    raise ValueError(f"unknown workspace method {method!r}")
