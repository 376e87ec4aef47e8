"""The joint grid of the workspace build: every posture of four joint samplings."""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from mmstab.model.robot import FloatArray, Robot

#: A joint whose range is a full turn within this [rad] does not sample its upper end.
FULL_TURN_TOL = 1e-6


class JointGrid(NamedTuple):
    """The posture grid: per-joint samples and spacing.

    Attributes:
        axes: sample values of each joint, four arrays [rad].
        step: spacing of each joint's samples (4,) [rad].
    """

    axes: tuple[FloatArray, ...]
    step: FloatArray

    @property
    def shape(self) -> tuple[int, ...]:
        """Samples per joint."""
        return tuple(len(a) for a in self.axes)

    @property
    def size(self) -> int:
        """Number of postures."""
        return int(np.prod(self.shape))


def joint_grid(robot: Robot, counts: Sequence[int]) -> JointGrid:
    """Evenly spaced samples of each joint within its limits.

    A joint spanning a full turn (the turret, [0, 2 pi]) omits its upper end, which is
    the same posture as its lower end.

    Args:
        robot: the robot (joint limits).
        counts: samples per joint, four integers >= 2.
    """
    axes, step = [], []
    for n, lo, hi in zip(counts, robot.joint_lower, robot.joint_upper, strict=True):
        full_turn = abs((hi - lo) - 2 * np.pi) <= FULL_TURN_TOL
        axes.append(np.linspace(lo, hi, int(n), endpoint=not full_turn))
        step.append((hi - lo) / (n if full_turn else n - 1))
    return JointGrid(tuple(axes), np.array(step))


def grid_postures(grid: JointGrid, start: int = 0, stop: int | None = None) -> FloatArray:
    """Postures ``start:stop`` of the grid (n, 4) [rad].

    Order: joint 1 slowest, then joints 2 and 3, joint 0 (the turret) fastest. A chunk
    then holds few values of the early joints, each at every turret angle, so the
    collision checker reuses most link-vs-base and link-vs-link answers within it.
    """
    stop = grid.size if stop is None else stop
    n0, n1, n2, n3 = grid.shape
    i1, i2, i3, i0 = np.unravel_index(np.arange(start, stop), (n1, n2, n3, n0))
    return np.column_stack([grid.axes[0][i0], grid.axes[1][i1], grid.axes[2][i2], grid.axes[3][i3]])


# ----------------------------------------------------------------------------------- hulls
