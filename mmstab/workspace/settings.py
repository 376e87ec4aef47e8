"""The ``workspace:`` section of a problem: how the arm-CoM workspace V is sampled."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from mmstab.core.defaults import DEFAULT_SECTIONS, SECTION_DEFAULTS


@dataclass(frozen=True)
class WorkspaceSettings:
    """The ``workspace:`` section of a problem file (defaults: the 4-DoF Cameleon's).

    Attributes:
        grid: grid samples per arm joint (one per joint) [-].
        precision_samples: postures drawn to measure V's precision [-].
        seed: seed of the precision draw and of ``samples``' draw.
        method: the planner's region, ``hull_difference`` (V) or ``valid_samples``.
        samples: grid postures drawn (seeded by ``seed``) instead of the whole grid; None:
            the whole grid.
    """

    grid: tuple[int, ...] = tuple(DEFAULT_SECTIONS["workspace"]["grid"])
    precision_samples: int = DEFAULT_SECTIONS["workspace"]["precision_samples"]
    seed: int = DEFAULT_SECTIONS["workspace"]["seed"]
    method: str = SECTION_DEFAULTS["workspace"]["method"]
    samples: int | None = None

    @classmethod
    def from_section(cls, section: Mapping[str, Any]) -> WorkspaceSettings:
        """Build from a validated ``workspace:`` section."""
        samples = section.get("samples")
        return cls(
            grid=tuple(int(n) for n in section["grid"]),
            precision_samples=int(section["precision_samples"]),
            seed=int(section["seed"]),
            method=str(section.get("method", cls.method)),
            samples=None if samples is None else int(samples),
        )
