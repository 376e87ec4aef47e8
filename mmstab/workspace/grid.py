"""The joint grid of the workspace build: every posture of the joints' samplings, or a sample.

One sampling per arm joint (any number of joints). A grid over the size bound
(:func:`mmstab.core.sizes.workspace_postures`: a 6-DoF arm's) is not labelled whole: a seeded
random draw of ``workspace.samples`` of its postures is (``JointGrid.picks``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from mmstab.core.sizes import workspace_postures
from mmstab.model.robot import FloatArray, Robot

#: A joint whose range is a full turn within this [rad] does not sample its upper end.
FULL_TURN_TOL = 1e-6


class JointGrid(NamedTuple):
    """The posture grid: per-joint samples and spacing.

    Attributes:
        axes: sample values of each joint, one array per arm joint [rad].
        step: spacing of each joint's samples (n,) [rad].
        picks: None for the whole grid; else the drawn postures' indices into the whole grid
            (sorted, in :func:`grid_postures` order).
    """

    axes: tuple[FloatArray, ...]
    step: FloatArray
    picks: NDArray[np.int64] | None = None

    @property
    def shape(self) -> tuple[int, ...]:
        """Samples per joint."""
        return tuple(len(a) for a in self.axes)

    @property
    def full_size(self) -> int:
        """Number of postures of the whole grid."""
        return int(np.prod(self.shape, dtype=np.int64))

    @property
    def size(self) -> int:
        """Number of postures labelled (the whole grid's, or the drawn ones')."""
        return self.full_size if self.picks is None else len(self.picks)


def joint_grid(
    robot: Robot, counts: Sequence[int], samples: int | None = None, seed: int = 0
) -> JointGrid:
    """Evenly spaced samples of each joint within its limits; drawn postures above the bound.

    A joint spanning a full turn (the turret, [0, 2 pi]) omits its upper end, which is
    the same posture as its lower end. A grid over the size bound
    (:func:`mmstab.core.sizes.workspace_postures`) with ``samples`` set keeps ``samples`` of
    its postures, drawn uniformly without replacement by ``numpy.random.default_rng(seed)``.

    Args:
        robot: the robot (joint limits).
        counts: samples per joint, one integer >= 2 per arm joint.
        samples: postures drawn from a grid over the bound (None: the whole grid).
        seed: seed of that draw.
    """
    axes, step = [], []
    for n, lo, hi in zip(counts, robot.joint_lower, robot.joint_upper, strict=True):
        full_turn = abs((hi - lo) - 2 * np.pi) <= FULL_TURN_TOL
        axes.append(np.linspace(lo, hi, int(n), endpoint=not full_turn))
        step.append((hi - lo) / (n if full_turn else n - 1))
    grid = JointGrid(tuple(axes), np.array(step))
    count, sampled = workspace_postures(counts, samples)
    if not sampled:
        return grid
    rng = np.random.default_rng(seed)
    picks = np.sort(rng.choice(grid.full_size, size=count, replace=False, shuffle=False))
    return grid._replace(picks=picks.astype(np.int64))


def grid_postures(grid: JointGrid, start: int = 0, stop: int | None = None) -> FloatArray:
    """Postures ``start:stop`` of the grid (m, n) [rad] (of the drawn ones, if sampled).

    Order: joint 1 slowest, then joints 2, 3, ..., joint 0 (the turret) fastest. A chunk
    then holds few values of the early joints, each at every turret angle, so the
    collision checker reuses most link-vs-base and link-vs-link answers within it.
    """
    stop = grid.size if stop is None else stop
    flat = np.arange(start, stop) if grid.picks is None else grid.picks[start:stop]
    shape = grid.shape
    idx = np.unravel_index(flat, (*shape[1:], shape[0]))  # joints 1..n-1, then joint 0
    order = (idx[-1], *idx[:-1])
    return np.column_stack([axis[i] for axis, i in zip(grid.axes, order, strict=True)])


# ----------------------------------------------------------------------------------- hulls
