"""The references' clock in the closed loop: the reference waits for a base that falls behind.

A run's references are functions of time. A base that cannot follow them (stuck on a step,
high-centred on a ditch's edge) sees them drive on, and the controller chases a reference
metres ahead: the tracks at their limit, the arm at postures planned for ground the robot is
not on. On ``dem.yaml``'s lap, with the arm CoM tracked in the map frame, the arm reached
2.4 m for its target while the chassis sat on the ditch's edge and tipped the robot at 19.0 s.

The clock here is a reference governor (path-progress time scaling): each control period it
advances by s · dt, s = 1 while the base control point is within ``slow`` of its reference,
falling linearly to 0 at ``stop``; the feed-forward rates (ξ̇_ref, q̇_ref) are scaled by s.
Below ``slow`` the clock is the run's own time row for row, so a run whose base never falls
that far behind is unchanged to the bit. A run whose reference has waited ``wait_limit``
seconds in all ends there: **stalled**.

The controller's step is unchanged: the governor only chooses which reference it is given
(on a robot it belongs to the reference generator, beside the step).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mmstab.control.layout import StepReference
from mmstab.model.robot import FloatArray


@dataclass(frozen=True)
class GovernorSettings:
    """The ``physics.governor`` section.

    Attributes:
        slow: base control point error from which the reference slows [m].
        stop: error at which it stops [m] (> ``slow``).
        wait_limit: total time the reference may wait before the run ends, stalled [s].
    """

    slow: float = 0.25
    stop: float = 0.5
    wait_limit: float = 10.0


def clock_rate(error: float, settings: GovernorSettings | None) -> float:
    """The reference clock's rate s in [0, 1] at a base control point error [m]."""
    if settings is None or error <= settings.slow:
        return 1.0
    return max(0.0, (settings.stop - error) / (settings.stop - settings.slow))


class ReferenceClock:
    """The references' rows at the governed time (interpolated between the table's rows).

    Args:
        control: the controller's reference table (T, 15 + 2n), one row per ``dt``.
        errors: the same references with the arm CoM in M (T, 15 + 2n): what errors are
            measured against.
        offset: the base control point's distance ahead of the body origin [m].
        settings: the governor's settings; None: the clock is the run's time.
        dt: control period [s].
    """

    def __init__(
        self,
        control: FloatArray,
        errors: FloatArray,
        offset: float,
        settings: GovernorSettings | None,
        dt: float,
    ):
        self.tables, self.offset, self.settings = (control, errors), offset, settings
        self.last = control.shape[0] - 1
        self.wait = 0 if settings is None else int(round(settings.wait_limit / dt))
        self.max_steps = self.last + self.wait
        self.row = 0.0  # the governed time in rows of the table
        column = StepReference.unpack(np.arange(control.shape[1]))  # each field's columns
        self.rates = np.r_[column.xi_dot_ref, column.q_dot_ref]
        self.x, self.y, self.heading = (int(c) for c in column.xi_des[:3])
        self.rate = 1.0

    @property
    def done(self) -> bool:
        """The reference has reached its table's end."""
        return self.row >= self.last

    def stalled(self, k: int) -> bool:
        """At period ``k`` the reference has waited more than the wait limit in all."""
        return not self.done and k - self.row > self.wait

    def _at(self, table: FloatArray, i: int, f: float) -> FloatArray:
        if f == 0.0:
            return table[i].copy()
        a, b = table[i], table[min(i + 1, self.last)]
        row = a + f * (b - a)
        turn = (b[self.heading] - a[self.heading] + np.pi) % (2 * np.pi) - np.pi
        row[self.heading] = a[self.heading] + f * turn
        return row

    def rows(self, M_T_B: FloatArray) -> tuple[FloatArray, FloatArray]:
        """(control row, error row) for the body at ``M_T_B`` (4, 4) in the map frame M.

        Sets the clock's rate for this period from the distance in M's x-y plane of the body's
        control point (``offset`` ahead along x_B, as the body is tilted) to its reference; the
        rows' feed-forward rates are scaled by it.
        """
        i = int(self.row)  # scalar work: ~10 µs a period would cost the loop 2-6 % of its speed
        f = self.row - i
        control, errors = self._at(self.tables[0], i, f), self._at(self.tables[1], i, f)
        dx = errors[self.x] - M_T_B[0, 3] - self.offset * M_T_B[0, 0]
        dy = errors[self.y] - M_T_B[1, 3] - self.offset * M_T_B[1, 0]
        self.rate = clock_rate(math.hypot(dx, dy), self.settings)
        if self.rate != 1.0:
            control[self.rates] *= self.rate
            errors[self.rates] *= self.rate
        return control, errors

    def advance(self) -> None:
        """One control period at this period's rate."""
        self.row = min(self.row + self.rate, float(self.last))
