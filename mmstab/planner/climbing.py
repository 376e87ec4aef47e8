"""The climb limit in the route planner (``planner.climb``): postures the tracks can climb with.

At a pose whose front wheels run into a step before the next planned pose
(:func:`mmstab.stability.climb.climb_limit`, the look-ahead the distance to that pose), the
arm's posture decides whether the tracks can lift their front over it: the overall CoM
must lie in the limit's half-plane. The arm moves from this pose's posture to the next
one's while the robot drives on, so both poses keep the CoM there (the next one with this
pose's half-plane, in its own body frame: the two frames differ by the pose's pitch onto
the step). A pose whose stable postures all fail it keeps them all and is reported: the
robot needs momentum there (``ClimbPlan.stalls``).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.model.robot import FloatArray, Robot
from mmstab.stability.climb import ClimbLimit, climb_limit
from mmstab.stability.slip import terrain_friction
from mmstab.terrain.base import Terrain


class ClimbPlan(NamedTuple):
    """Which poses keep the CoM where the tracks climb, and the half-plane each keeps.

    Attributes:
        limit: the climb limit at every pose (its look-ahead the distance to the next).
        source: (K,) the pose whose half-plane pose k keeps, -1 where none.
    """

    limit: ClimbLimit
    source: NDArray[np.intp]

    @property
    def constrained(self) -> NDArray[np.bool_]:
        """(K,) whether pose k keeps a half-plane."""
        return np.asarray(self.source >= 0)

    def climbs(self, com_body: ArrayLike) -> NDArray[np.bool_]:
        """Per pose, whether the overall CoM (K, 3) in B [m] keeps its half-plane (or none)."""
        c = np.atleast_2d(np.asarray(com_body, dtype=float))
        ok = np.ones(len(self.source), dtype=bool)
        at = np.flatnonzero(self.constrained)
        ok[at] = self.limit.keeps(self.source[at], c[at])
        return ok

    def eligible(self, k: int, com_body: FloatArray) -> NDArray[np.bool_]:
        """Whether each overall CoM (N, 3) in B [m] keeps pose k's half-plane (all: none)."""
        src = int(self.source[k])
        if src < 0:
            return np.ones(len(com_body), dtype=bool)
        return self.limit.keeps(src, com_body)


def climb_plan(robot: Robot, terrain: Terrain, poses: ArrayLike, closed: bool) -> ClimbPlan:
    """The climb limit along planned poses (x [m], y [m], yaw [rad]) (K, 3) in M (module text).

    Args:
        robot: the robot.
        terrain: the ground.
        poses: the planned base poses, in driving order.
        closed: the path is a loop (the last pose drives on to the first).
    """
    p = np.atleast_2d(np.asarray(poses, dtype=float))
    nxt = np.roll(p[:, :2], -1, axis=0)
    ahead = np.linalg.norm(nxt - p[:, :2], axis=1)
    if not closed:
        ahead[-1] = 0.0  # the last pose drives no further
    limit = climb_limit(robot, terrain, p, terrain_friction(terrain), float(ahead.max()))
    step = limit.step & (limit.ahead <= ahead)  # met before the next pose
    limit = limit._replace(step=step)
    source = np.full(len(p), -1, dtype=np.intp)
    for k in np.flatnonzero(step)[::-1]:  # the nearer step wins where two overlap
        source[(k + 1) % len(p) if closed else min(k + 1, len(p) - 1)] = k
    source[step] = np.flatnonzero(step)
    return ClimbPlan(limit, source)


def climb_exclusions(
    robot: Robot,
    plan: ClimbPlan,
    arm_com_body: FloatArray,
    eligible: NDArray[np.bool_],
    fits: list[Any],
) -> dict[int, NDArray[np.bool_]]:
    """Per constrained pose, the eligible rows whose posture cannot climb its step.

    A pose where no eligible stable row (μ > 0) climbs keeps them all (it is left out):
    the plan may stall there, and the route's report says so.

    Args:
        robot: the robot.
        plan: the climb limit along the route.
        arm_com_body: the rows' arm CoMs, body frame (N, 3) [m].
        eligible: the rows any pose may choose (N,).
        fits: Eq. 6 per pose (their ``mu``).
    """
    com = robot.overall_com(arm_com_body)
    out: dict[int, NDArray[np.bool_]] = {}
    for k in np.flatnonzero(plan.constrained):
        climbs = plan.eligible(int(k), com) & eligible
        rows = np.flatnonzero(climbs)
        if any_stable(fits[k], arm_com_body, rows):
            out[int(k)] = eligible & ~climbs
    return out


#: Rows per block of :func:`any_stable` (the first block mostly holds a stable row).
STABLE_BLOCK = 2048


def any_stable(fit: Any, arm_com_body: FloatArray, rows: NDArray[np.intp]) -> bool:
    """Whether any of ``rows`` has μ > 0 under ``fit``: block by block, the first one ends it."""
    for s in range(0, len(rows), STABLE_BLOCK):
        if (fit.mu(arm_com_body[rows[s : s + STABLE_BLOCK]]) > 0).any():
            return True
    return False
