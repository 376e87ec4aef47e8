"""When a run tips over: μ < 0 that no rock catches, for a stated time (one rule for every run).

``mmstab plan`` checks a route for a state with μ < 0 by pushing the robot across its weak
support edge (:func:`mmstab.stability.rock.rock_over`): where it rocks onto a support that
holds it, the state is a rock, not a tip. A run (``mmstab track``'s kinematic run,
``mmstab follow``'s online loop) judges its states the same way:

- a state is **tipping** where its one μ is below 0 and, on a heightmap and without a tool
  wrench (the rock check pushes the weight alone), the robot pushed by the route's
  acceleration does not rock onto a support that holds it (:class:`RockCheck`);
- the run **tips** where tipping states last :data:`TIP_HOLD` on end, or to the run's end,
  and the tip is placed where that stretch began (:func:`first_tip`). Shorter stretches are
  the rest flickering between supports while a contact crosses the edge of a map cell.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.model.robot import FloatArray, Robot
from mmstab.runs.along import acceleration_margin
from mmstab.runs.plan_verdicts import route_acceleration
from mmstab.stability.rock import rock_over
from mmstab.stability.support import is_heightmap
from mmstab.terrain import Terrain
from mmstab.terrain.base import GRAVITY_G

#: How long [s] μ may stay below 0 where the robot does not rock onto a support that holds
#: it before a run calls a tip. Shorter stretches are the rest flickering between supports
#: while a contact crosses an edge of the map's cells (at most 11 ms on the tracking runs of
#: the 48 validation routes); a robot starting to tip stays there.
TIP_HOLD = 0.05


class RockCheck:
    """Whether states with μ < 0 rock onto a support that holds them (module text).

    Args:
        robot: the robot (its mass, and its tool wrench: with one, no state rocks).
        route: the route driven (its acceleration limits, else the route defaults', push
            the robot), or None: no push (the robot's weight alone).
    """

    def __init__(self, robot: Robot, route: Any | None) -> None:
        acceleration = route_acceleration(route) if route is not None else 0.0
        self.robot = robot
        self.push = acceleration / float(np.linalg.norm(GRAVITY_G))  # a / g [-]
        self.threshold = acceleration_margin(robot.total_mass, acceleration)  # [N rad]

    def applies(self, terrain: Terrain) -> bool:
        """The check runs on this ground: a heightmap, and no tool wrench."""
        return is_heightmap(terrain) and self.robot.tool_wrench is None

    def holds(
        self, terrain: Terrain, poses: ArrayLike, arm_com_body: ArrayLike
    ) -> NDArray[np.bool_]:
        """(N,) the states rock onto a support that holds them (False where the check is off).

        Args:
            terrain: the ground.
            poses: base poses (N, 3) of (x, y, yaw) in M [m, m, rad].
            arm_com_body: the arm CoM per state in B (N, 3) [m].
        """
        P = np.atleast_2d(np.asarray(poses, dtype=float))
        if not self.applies(terrain) or not len(P):
            return np.zeros(len(P), dtype=bool)
        arm = np.atleast_2d(np.asarray(arm_com_body, dtype=float))
        rock = rock_over(self.robot, terrain, P, arm, self.push, self.threshold, 0.0)
        return np.asarray(rock.holds, dtype=bool)


def first_tip(times: FloatArray, tipping: ArrayLike, hold: float = TIP_HOLD) -> int | None:
    """The index where the first stretch of tipping states that lasts begins, or None.

    A stretch lasts ``hold`` [s] when the time from its first state to the next state that
    is not tipping is at least ``hold``, or when it runs to the last state (a sample stands
    for the time until the next). For states ``dt`` apart this is ``round(hold / dt)``
    tipping samples on end (:class:`mmstab.runs.tracking.simulation.TipWatch`).

    Args:
        times: the states' times (N,) [s], ascending.
        tipping: (N,) which states are tipping.
        hold: how long a stretch must last [s].
    """
    t = np.asarray(times, dtype=float)
    bad = np.asarray(tipping, dtype=bool)
    start: int | None = None
    for i in range(len(bad)):
        if bad[i]:
            start = i if start is None else start
            continue
        if start is not None and t[i] - t[start] >= hold * (1 - 1e-9):
            return start
        start = None
    return start
