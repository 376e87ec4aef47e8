"""Eq. 6's motion term between roadmap postures, and the moves allowed between poses.

``planner.motion_cost``: ``joints`` (the lattice, L1, distance between postures, squared;
the roadmap distance wherever the staircase between them is free, a lower bound elsewhere)
or ``com`` (Eq. 6's squared arm-CoM distance). Used by the offline ``method: roadmap``
(:mod:`mmstab.planner.searches.roadmap`) and the online horizon on the roadmap.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.distance import cdist

from mmstab.model.robot import FloatArray, Robot
from mmstab.planner.settings import PlannerSettings


class MotionCost(NamedTuple):
    """Eq. 6's motion term between roadmap postures (``planner.motion_cost``).

    Attributes:
        points: each reach row's point in the cost's space (N, d): its posture [rad]
            (``joints``: the lattice, L1, distance) or its arm CoM [m] (``com``: Eq. 6's).
        metric: ``cityblock`` (the distance then squared) or ``sqeuclidean``.
        weight: the term's weight on the squared distance (normalised by the span).
    """

    points: FloatArray
    metric: str
    weight: float

    def point_of(self, robot: Robot, q: FloatArray) -> FloatArray:
        """A posture ``q`` [rad] in the cost's space."""
        return np.asarray(q, dtype=float) if self.metric == "cityblock" else robot.arm_com(q)

    def from_point(self, rows: NDArray[np.intp], point: FloatArray) -> FloatArray:
        """The term from ``point`` (in the cost's space) to the reach rows ``rows``."""
        d = cdist(self.points[rows], np.atleast_2d(point), self.metric)[:, 0]
        return self.weight * (d if self.metric == "sqeuclidean" else d * d)


def motion_cost(
    postures: FloatArray, coms: FloatArray, span: tuple[float, float], settings: PlannerSettings
) -> MotionCost:
    """The motion term of ``settings.motion_cost`` on a roadmap component's nodes.

    Args:
        postures: the nodes' postures (N, n) [rad].
        coms: their arm CoMs, body frame (N, 3) [m].
        span: the normalisers: the CoMs' largest extent along an axis [m] and the
            postures' L1 extent [rad] (``ComponentView.diameter``, ``.joint_span``).
        settings: the planner settings (``motion_cost``, ``w_motion``).
    """
    diameter, joint_span = span
    if settings.motion_cost == "joints":  # the lattice distance between postures [rad]
        return MotionCost(postures, "cityblock", settings.w_motion / joint_span**2)
    return MotionCost(coms, "sqeuclidean", settings.w_motion / diameter**2)


def transitions(
    points: FloatArray,
    turret: FloatArray,
    cand: NDArray[np.intp],
    pairs: list[tuple[int, int]],
    w: float,
    window: float | None,
    metric: str,
) -> tuple[list[FloatArray], list[NDArray[np.bool_]]]:
    """The motion term between consecutive poses' candidates, and the allowed moves.

    The term is ``w`` times the squared distance between the candidates' ``points`` (N, d):
    their CoMs [m] with ``metric`` ``sqeuclidean`` (Eq. 6), their postures [rad] with
    ``cityblock`` (the lattice distance, then squared); a move is allowed when link0
    (``turret`` [rad] per node) changes by at most ``window`` [rad] (None: any).
    """
    M = cand.shape[1]
    motion, allowed = [], []
    for a, b in pairs:
        d = cdist(points[cand[a]], points[cand[b]], metric)
        motion.append(w * (d if metric == "sqeuclidean" else d * d))
        ok = np.ones((M, M), dtype=bool)
        if window is not None:
            ok &= np.abs(turret[cand[a]][:, None] - turret[cand[b]]) <= window + 1e-9
        allowed.append(ok)
    return motion, allowed
