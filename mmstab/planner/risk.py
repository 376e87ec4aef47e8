"""Where a planned route is at risk: stretches of poses below a stability margin."""

from __future__ import annotations

from typing import NamedTuple, Protocol

import numpy as np
from numpy.typing import ArrayLike

from mmstab.core.masks import true_runs
from mmstab.model.robot import FloatArray


class RoutePlanLike(Protocol):
    """What the risk needs of a route plan (:class:`mmstab.planner.RoutePlan`)."""

    @property
    def s(self) -> FloatArray:
        """Arc length of each pose (K,) [m]."""
        ...

    @property
    def mu_planned(self) -> FloatArray:
        """μ with the planned CoM (K,) [N rad]."""
        ...

    @property
    def mu_stowed(self) -> FloatArray:
        """μ with the arm stowed (K,) [N rad]."""
        ...


class RiskStretch(NamedTuple):
    """A stretch of planned poses: arc lengths [m] from ``start_s`` to ``end_s``, worst μ."""

    start_s: float
    end_s: float
    worst_mu: float


def stretches(mask: ArrayLike, s: ArrayLike, mu: ArrayLike) -> list[RiskStretch]:
    """Runs of consecutive poses where ``mask`` holds: arc lengths [m] and worst μ [N rad]."""
    s_m, mu_v = np.asarray(s, dtype=float), np.asarray(mu, dtype=float)
    return [
        RiskStretch(float(s_m[k]), float(s_m[j - 1]), float(mu_v[k:j].min()))
        for k, j in true_runs(mask)
    ]


class RouteRisk(NamedTuple):
    """Where a route is at risk (lists of stretches of planned poses).

    Attributes:
        margin: the margin [N rad] (``planner.margin``).
        below_margin: μ planned <= margin: even the best posture is at risk there.
        saved_by_planning: μ stowed <= margin < μ planned: the stowed arm would be at risk.
    """

    margin: float
    below_margin: list[RiskStretch]
    saved_by_planning: list[RiskStretch]


def route_risk(plan: RoutePlanLike, margin: float | None = None) -> RouteRisk:
    """The risk stretches of a route plan against ``margin`` [N rad].

    ``margin`` None: the plan's own (``plan.margin``, :class:`mmstab.PathPlan`'s
    ``planner.margin``), else 0.
    """
    if margin is None:
        margin = float(getattr(plan, "margin", 0.0))
    below = plan.mu_planned <= margin
    saved = (plan.mu_stowed <= margin) & ~below
    return RouteRisk(
        margin=float(margin),
        below_margin=stretches(below, plan.s, plan.mu_planned),
        saved_by_planning=stretches(saved, plan.s, plan.mu_stowed),
    )
