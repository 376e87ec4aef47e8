"""The levers experiments' settings and shared helpers (``levers:`` section, bisection)."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from mmstab.core.files import ConfigError
from mmstab.core.problem import Problem
from mmstab.model.robot import FloatArray
from mmstab.terrain import Terrain, from_section

#: Window of the second differences of simulated states [s] (module text).
SIM_WINDOW = 0.02
#: Directions the payload is held in: turret angle [rad] (0 = forward, positive = left).
DIRECTIONS = {"front": 0.0, "left": math.pi / 2, "right": -math.pi / 2}


class LeversSettings(NamedTuple):
    """The ``levers:`` section (see ``problems/levers.yaml``)."""

    margin: float  # [N rad]
    speeds: tuple[float, ...]  # lap-speed factors
    samples: int  # per lap
    side_slope: float  # [rad]
    max_payload: float  # [kg]
    payload_com: FloatArray  # in the wrist frame (3,) [m]
    payload_reach: float  # [m] beyond the tracks' edge
    bisection_steps: int
    max_slope: float  # [rad]
    robots: tuple[str, ...]
    variant_grid: tuple[int, int, int, int]
    flipper_angles: int
    rough_problem: str | None  # a problem file whose terrain and circle are the rough lap


def levers_settings(problem: Problem) -> LeversSettings:
    """The problem's ``levers:`` section.

    Raises:
        ConfigError: the section is missing.
    """
    if "levers" not in problem.data:
        raise ConfigError(problem.path, "levers", "missing section: make levers needs it")
    s = problem.section("levers")
    rough = s.get("rough_problem")
    if rough is not None and not (problem.path.parent / rough).is_file():
        raise ConfigError(problem.path, "levers.rough_problem", f"no problem file {rough}")
    return LeversSettings(
        margin=float(s["margin"]),
        speeds=tuple(float(v) for v in s["speeds"]),
        samples=int(s["samples"]),
        side_slope=float(s["side_slope"]),
        max_payload=float(s["max_payload"]),
        payload_com=np.asarray(s["payload_com"], dtype=float),
        payload_reach=float(s["payload_reach"]),
        bisection_steps=int(s["bisection_steps"]),
        max_slope=float(s["max_slope"]),
        robots=tuple(s["robots"]),
        variant_grid=tuple(int(n) for n in s["variant_grid"]),  # type: ignore[arg-type]
        flipper_angles=int(s["flipper_angles"]),
        rough_problem=rough,
    )


def planar_slope(problem: Problem, slope: float) -> Terrain:
    """A planar slope of ``slope`` [rad] (the terrain factory's ``{slope}`` form)."""
    return from_section(problem.path, {"slope": float(slope)}, problem.robot)


def bisect_largest(ok: Callable[[float], bool], lo: float, hi: float, steps: int) -> float:
    """Largest x in [lo, hi] with ``ok(x)``, assuming ok holds below a threshold.

    Returns ``lo - 0`` = ``lo`` when ``ok(lo)`` fails is signalled by NaN; ``hi`` when
    ``ok(hi)`` holds (the bracket's end: a lower bound).
    """
    if not ok(lo):
        return math.nan
    if ok(hi):
        return hi
    for _ in range(steps):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if ok(mid) else (lo, mid)
    return lo
