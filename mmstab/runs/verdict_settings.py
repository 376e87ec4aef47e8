"""What a plan's verdicts read from a problem: the margin and the slide's limits.

``planner.margin`` (μ must exceed it [N rad]) and the ``physics:`` section's slide check
(``slip_distance``, ``slip_window``, ``turn_ratio``, ``slide_budget``): :class:`VerdictSettings`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from mmstab.core.defaults import SECTION_DEFAULTS

#: ``planner.margin`` when the problem does not set it [N rad].
DEFAULT_MARGIN = 0.0


@dataclass(frozen=True)
class VerdictSettings:
    """The limits a plan is judged by (:mod:`mmstab.runs.verdict`, :mod:`mmstab.runs.along`).

    Attributes:
        margin: a pose holds when its μ exceeds this (``planner.margin``) [N rad].
        slip_distance: a downhill slide beyond this within ``slip_window`` slides
            (``physics.slip_distance``) [m].
        slip_window: [s] (``physics.slip_window``).
        turn_ratio: the drive layer's η in (0, 1], or ``"auto"`` (the robot's pivot-turn
            ratio) (``physics.turn_ratio``) [-].
        shear_modulus: the belts' shear modulus K of the skid-steer model
            (``physics.shear_modulus``) [m].
        slide_budget: the share of ``slip_distance`` a route's turn may slide within
            ``slip_window``; the plan slows the corners that would slide more
            (``physics.slide_budget``, :mod:`mmstab.runs.time_law`; None: none slowed) [-].
        arm_over_crests: measure the arm's height over the ground along a route plan, at
            the rests and rocked over crests (``physics.arm_over_crests``,
            :mod:`mmstab.runs.arm_ground`; a record, not a verdict).
    """

    margin: float = DEFAULT_MARGIN
    slip_distance: float = SECTION_DEFAULTS["physics"]["slip_distance"]
    slip_window: float = SECTION_DEFAULTS["physics"]["slip_window"]
    turn_ratio: float | str = SECTION_DEFAULTS["physics"]["turn_ratio"]
    shear_modulus: float = SECTION_DEFAULTS["physics"]["shear_modulus"]
    slide_budget: float | None = SECTION_DEFAULTS["physics"]["slide_budget"]
    arm_over_crests: bool = SECTION_DEFAULTS["physics"]["arm_over_crests"]

    @classmethod
    def from_sections(
        cls, planner: Mapping[str, Any], physics: Mapping[str, Any]
    ) -> VerdictSettings:
        """Build from validated ``planner:`` and ``physics:`` sections."""
        ratio = physics.get("turn_ratio", cls.turn_ratio)
        budget = physics.get("slide_budget", cls.slide_budget)
        return cls(
            margin=float(planner.get("margin", DEFAULT_MARGIN)),
            slip_distance=float(physics.get("slip_distance", cls.slip_distance)),
            slip_window=float(physics.get("slip_window", cls.slip_window)),
            turn_ratio=ratio if isinstance(ratio, str) else float(ratio),
            shear_modulus=float(physics.get("shear_modulus", cls.shear_modulus)),
            slide_budget=None if budget is None else float(budget),
            arm_over_crests=bool(physics.get("arm_over_crests", cls.arm_over_crests)),
        )
