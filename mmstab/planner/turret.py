"""Turret continuity: the planner keeps link0 within a window of its previous angle.

The planner searches the arm CoM, not the posture, so Eq. 6's motion term sees a CoM that
moves from just left of the turret's front to just right of it as a few centimetres. When
the turret's end stop points forward (link0 limited to [0, 2π]), that move is a swing of
almost a full turn through the back, which the tracked arm cannot follow without
saturating or hitting the base. ``planner.turret_window`` [rad] bounds the turret angle of
each planned pose to within that window of the previous pose's (the realised posture's
link0); on a closed path the last pose is also kept within the window of the first, so
the lap closes. The first pose is free: the approach phase moves the arm from stowed.

The turret angle of a CoM is the link0 of its nearest sample of V (V's samples are the CoMs
of collision-free grid postures), so the same rule holds for the exhaustive reference,
the coarse seeds and the CMA-ES polish (:class:`WindowedRegion`).
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.core.files import MmstabError
from mmstab.model.robot import FloatArray
from mmstab.planner.exhaustive import SampleIndex, sample_index

#: Slack on the window [rad]: a posture at the window's edge is inside.
WINDOW_TOL = 1e-9

_POSTURES: weakref.WeakKeyDictionary[Any, FloatArray] = weakref.WeakKeyDictionary()


def sample_turret(region: Any) -> FloatArray:
    """link0 of each of the region's samples (M,) [rad], in ``sample_index`` order."""
    return sample_postures(region)[:, 0]


def sample_postures(region: Any) -> FloatArray:
    """The grid posture of each of the region's samples (M, 4) [rad] (``sample_index`` order).

    Raises:
        MmstabError: the region does not keep the postures of its samples.
    """
    try:
        return _POSTURES[region]
    except (KeyError, TypeError):
        pass
    ws = getattr(region, "workspace", region)
    valid_q = getattr(ws, "valid_q", None)
    valid_com = getattr(ws, "valid_com", None)
    if valid_q is None or valid_com is None:
        raise MmstabError(
            "planner: turret_window needs the workspace's postures (valid_q); this region "
            "keeps none"
        )
    samples = sample_index(region).samples
    valid_com = np.asarray(valid_com, dtype=float)
    # V's own mask when the region is V (computed once with its samples), else the test
    known = getattr(region, "valid_in_V", None)
    keep = region.contains(valid_com) if known is None else np.asarray(known, dtype=bool)
    postures = np.asarray(valid_q, dtype=float)[keep]
    if len(postures) != len(samples) or not np.array_equal(valid_com[keep], samples):
        raise MmstabError("planner: the region's samples are not its workspace's valid CoMs")
    try:
        _POSTURES[region] = postures
    except TypeError:
        pass
    return postures


class Window(NamedTuple):
    """An interval of turret angles [rad]: ``lower <= link0 <= upper``."""

    lower: float
    upper: float

    def contains(self, angle: ArrayLike) -> NDArray[np.bool_]:
        """Whether turret angles [rad] lie in the window (with ``WINDOW_TOL``)."""
        a = np.asarray(angle, dtype=float)
        return (a >= self.lower - WINDOW_TOL) & (a <= self.upper + WINDOW_TOL)

    def excess(self, angle: ArrayLike) -> FloatArray:
        """How far turret angles lie outside the window, 0 inside [rad]."""
        a = np.asarray(angle, dtype=float)
        return np.maximum(0.0, np.maximum(self.lower - a, a - self.upper))


def turret_window(previous: float, width: float, first: float | None = None) -> Window:
    """The window of a pose: within ``width`` [rad] of the previous pose's link0 [rad].

    Args:
        previous: link0 of the previous pose's posture [rad].
        width: ``planner.turret_window`` [rad].
        first: link0 of the path's first pose [rad] when this is the last pose of a closed
            path; the window is then also within ``width`` of it, where both overlap.
    """
    lower, upper = previous - width, previous + width
    if first is not None:
        lo, hi = max(lower, first - width), min(upper, first + width)
        if lo <= hi:
            lower, upper = lo, hi
    return Window(float(lower), float(upper))


@dataclass(frozen=True, eq=False)
class WindowedRegion:
    """A planning region restricted to CoMs whose turret angle lies in a window.

    Attributes:
        region: the unrestricted region (V or its samples).
        window: the allowed turret angles [rad].
        allowed: which of the region's samples (``sample_index`` order) are in the window.
    """

    region: Any
    window: Window
    allowed: NDArray[np.bool_]

    @property
    def diameter(self) -> float:
        """d_workspace of Eq. 6 [m]: the unrestricted region's (the penalty's scale)."""
        return float(self.region.diameter)

    @property
    def index(self) -> SampleIndex:
        """The unrestricted region's samples and k-d tree."""
        return sample_index(self.region)

    @property
    def valid_com_in_V(self) -> FloatArray:
        """The samples in the window (M', 3) [m]."""
        return self.index.samples[self.allowed]

    def turret(self, points: ArrayLike) -> FloatArray:
        """Turret angle of body-frame CoMs (N, 3): their nearest sample's link0 [rad]."""
        _, rows = self.index.tree.query(np.atleast_2d(np.asarray(points, dtype=float)))
        return sample_turret(self.region)[np.asarray(rows)]

    def contains(self, points: ArrayLike) -> NDArray[np.bool_]:
        """Whether CoMs (N, 3) [m] lie in the region and their turret angle in the window."""
        pts = np.atleast_2d(np.asarray(points, dtype=float))
        inside = np.asarray(self.region.contains(pts), dtype=bool)
        if inside.any():
            inside[inside] = self.window.contains(self.turret(pts[inside]))
        return inside

    def violation(self, points: ArrayLike) -> FloatArray:
        """How far CoMs (N, 3) lie outside, 0 inside: a ranking for CMA-ES.

        The region's violation [m] plus the turret's excess [rad] times V's diameter / 2π.
        """
        pts = np.atleast_2d(np.asarray(points, dtype=float))
        base = np.asarray(self.region.violation(pts), dtype=float)
        turret = self.window.excess(self.turret(pts)) * self.diameter / (2 * np.pi)
        return base + turret


def windowed_region(region: Any, window: Window) -> WindowedRegion:
    """The region restricted to the window.

    Raises:
        MmstabError: no sample of the region lies in the window.
    """
    allowed = window.contains(sample_turret(region))
    if not allowed.any():
        raise MmstabError(
            f"planner: no CoM of V has link0 in [{window.lower:.3f}, {window.upper:.3f}] rad "
            "(turret_window too narrow)"
        )
    return WindowedRegion(region, window, allowed)
