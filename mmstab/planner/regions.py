"""Where the planner may put the arm CoM: one region class with its cached views.

The region's shape is ``workspace.method``'s (``docs/planner.md``):

- ``hull_difference`` (the paper, default): V = hull(all CoMs) minus hull(colliding CoMs),
  the :class:`mmstab.workspace.Workspace` itself. Conservative: it drops every
  collision-free CoM inside hull(colliding), e.g. all CoMs near the stowed arm's.
- ``valid_samples``: the collision-free grid CoMs themselves, each thickened to a ball of
  the cloud's typical spacing (:class:`SampleBalls`). Every collision-free grid CoM is in
  it; a point between samples is only as safe as its nearest sample (the realising
  posture is collision-checked after planning, as with V).

:class:`PlanningRegion` keeps what the searches derive from it, each built once, on first
use, and held by the region itself (no cache keyed on it elsewhere): its samples (the
collision-free grid CoMs it contains), their k-d tree, their grid postures, and per robot
the tool points of the workspace's postures (``mmstab.planner.wrench``). A turret window
(``mmstab.planner.turret``) is a region too (:meth:`PlanningRegion.windowed`): it shares
its parent's views and restricts membership and samples to the window.

Build the region once per plan (:func:`planning_region`) and pass it on; a bare
:class:`~mmstab.workspace.Workspace` handed to a planner function is wrapped per call
(:func:`as_region`, its views then built again).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple, Protocol, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from mmstab.core.files import MmstabError
from mmstab.model.robot import FloatArray
from mmstab.workspace import Workspace

#: Membership slack [m] (as ``mmstab.workspace.HULL_TOL``).
TOL = 1e-9
#: Sample pairs used to estimate the cloud's spacing.
SPACING_SAMPLES = 4096
#: The ``workspace.method`` values (the region's shape).
METHODS = ("hull_difference", "valid_samples")

View = TypeVar("View")


class CoMRegion(Protocol):
    """The shape of a region: what a search asks of where the arm CoM may be.

    :class:`~mmstab.workspace.Workspace` (V), :class:`SampleBalls` and
    :class:`PlanningRegion` have it.
    """

    @property
    def diameter(self) -> float:
        """d_workspace of Eq. 6 [m]."""
        ...

    def contains(self, points: ArrayLike) -> NDArray[np.bool_]:
        """Membership of body-frame points (N, 3) [m]."""
        ...

    def violation(self, points: ArrayLike) -> FloatArray:
        """How far body-frame points (N, 3) lie outside the region, 0 inside [m]."""
        ...


class SampleIndex(NamedTuple):
    """A region's samples (N, 3) [m] and a k-d tree over them (local refinement, fallback)."""

    samples: FloatArray
    tree: cKDTree


class TurretWindow(Protocol):
    """An interval of turret angles (``mmstab.planner.turret.Window``)."""

    @property
    def lower(self) -> float:
        """Smallest turret angle in the window [rad]."""
        ...

    @property
    def upper(self) -> float:
        """Largest turret angle in the window [rad]."""
        ...

    def contains(self, angle: ArrayLike) -> NDArray[np.bool_]:
        """Whether turret angles [rad] lie in the window."""
        ...

    def excess(self, angle: ArrayLike) -> FloatArray:
        """How far turret angles lie outside the window, 0 inside [rad]."""
        ...


@dataclass(frozen=True, eq=False)
class SampleBalls:
    """The collision-free CoM samples of a workspace, each a ball of ``radius`` [m].

    Attributes:
        valid_com: the collision-free grid CoMs (N, 3) [m].
        radius: ball radius [m].
        diameter: d_workspace of Eq. 6: the workspace's (hull of all CoMs) [m], as for V.
    """

    valid_com: FloatArray
    radius: float
    diameter: float

    @functools.cached_property
    def tree(self) -> cKDTree:
        """k-d tree over the samples."""
        return cKDTree(self.valid_com)

    def distance(self, points: ArrayLike) -> FloatArray:
        """Distance of body-frame points (N, 3) to the nearest sample (N,) [m]."""
        d, _ = self.tree.query(np.atleast_2d(np.asarray(points, dtype=float)))
        return np.asarray(d, dtype=float)

    def contains(self, points: ArrayLike) -> NDArray[np.bool_]:
        """Whether points (N, 3) [m] lie within ``radius`` of a collision-free sample."""
        return self.distance(points) <= self.radius + TOL

    def violation(self, points: ArrayLike) -> FloatArray:
        """How far points (N, 3) lie outside the region, 0 inside [m]."""
        d = self.distance(points) - self.radius
        return np.where(d <= TOL, 0.0, np.maximum(d, TOL))


@dataclass(frozen=True, eq=False)
class PlanningRegion:
    """Where the arm CoM may be, with the views the searches use (module text).

    Attributes:
        shape: the membership test: V (the workspace itself), :class:`SampleBalls`, or
            any :class:`CoMRegion` (then without samples unless ``workspace`` is given).
        workspace: the labelled workspace its samples and postures come from; None: a
            bare shape (no samples: the searches that need them refuse it).
        window: the turret window of a windowed region, else None.
        parent: the unrestricted region of a windowed one, else None.
    """

    shape: CoMRegion
    workspace: Workspace | None = None
    window: TurretWindow | None = None
    parent: PlanningRegion | None = None
    _views: dict[object, object] = field(default_factory=dict, repr=False)

    # ------------------------------------------------------------------------ the shape
    @property
    def diameter(self) -> float:
        """d_workspace of Eq. 6: the workspace's (hull of all CoMs) [m], for every shape."""
        return float(self.shape.diameter)

    @property
    def balls(self) -> SampleBalls | None:
        """The ``valid_samples`` shape, else None."""
        return self.shape if isinstance(self.shape, SampleBalls) else None

    @property
    def radius(self) -> float:
        """Ball radius of the ``valid_samples`` shape [m] (0 otherwise)."""
        return 0.0 if self.balls is None else self.balls.radius

    def distance(self, points: ArrayLike) -> FloatArray:
        """Distance of points (N, 3) to the nearest collision-free sample (N,) [m].

        Raises:
            MmstabError: the region is V (whose distance is :meth:`violation`).
        """
        balls = self.balls
        if balls is None:
            raise MmstabError("planner: distance() is the valid_samples region's")
        return balls.distance(points)

    def contains(self, points: ArrayLike) -> NDArray[np.bool_]:
        """Whether body-frame CoMs (N, 3) [m] lie in the region (and their turret in the window)."""
        pts = np.atleast_2d(np.asarray(points, dtype=float))
        inside = np.asarray(self.shape.contains(pts), dtype=bool)
        if self.window is not None and inside.any():
            inside[inside] = self.window.contains(self.turret(pts[inside]))
        return inside

    def violation(self, points: ArrayLike) -> FloatArray:
        """How far CoMs (N, 3) lie outside, 0 inside: a ranking for CMA-ES.

        The shape's violation [m]; windowed, plus the turret's excess [rad] times
        d_workspace / 2π.
        """
        pts = np.atleast_2d(np.asarray(points, dtype=float))
        base = np.asarray(self.shape.violation(pts), dtype=float)
        if self.window is None:
            return base
        return base + self.window.excess(self.turret(pts)) * self.diameter / (2 * np.pi)

    # ------------------------------------------------------------------------ the views
    def view(self, key: object, build: Callable[[], View]) -> View:
        """A view of the region, built by ``build`` on first use and kept by the region.

        A windowed region keeps its views in its parent's (they describe the same samples).
        """
        if self.parent is not None:
            return self.parent.view(key, build)
        if key not in self._views:
            self._views[key] = build()
        return self._views[key]  # type: ignore[return-value]  # the key fixes the type

    @property
    def root(self) -> PlanningRegion:
        """The unrestricted region (itself unless windowed)."""
        return self if self.parent is None else self.parent

    @functools.cached_property
    def samples(self) -> FloatArray:
        """The region's samples: the collision-free grid CoMs it holds (M, 3) [m].

        V: ``Workspace.valid_com_in_V``; the balls: every collision-free grid CoM;
        windowed: those of the parent's whose turret angle is in the window; a bare shape
        has none (0, 3).
        """
        if self.parent is not None:
            return self.parent.samples[self.allowed_mask]
        if self.balls is not None:
            return np.asarray(self.balls.valid_com)
        if self.workspace is None:
            return np.empty((0, 3))
        return np.asarray(self.workspace.valid_com_in_V)

    @property
    def valid_com_in_V(self) -> FloatArray:
        """:attr:`samples` (the name the workspace gives them)."""
        return self.samples

    @property
    def labelled(self) -> Workspace:
        """The workspace the samples come from.

        Raises:
            MmstabError: a bare shape (no labelled workspace).
        """
        if self.workspace is None:
            raise MmstabError(
                "planner: this region keeps no labelled workspace (its collision-free "
                "postures, valid_q): the turret window and a tool wrench need them"
            )
        return self.workspace

    @property
    def valid_com(self) -> FloatArray:
        """Every collision-free grid CoM of the workspace (N, 3) [m]."""
        return np.asarray(self.labelled.valid_com)

    @property
    def valid_q(self) -> FloatArray:
        """Their postures (N, 4) [rad]."""
        return np.asarray(self.labelled.valid_q)

    @property
    def index(self) -> SampleIndex:
        """The unrestricted samples and their k-d tree (built once).

        Raises:
            MmstabError: the region holds no sample.
        """
        root = self.root
        return self.view("index", lambda: _index(root.samples))

    @property
    def postures(self) -> FloatArray:
        """The grid posture of each unrestricted sample (M, 4) [rad] (``index`` order)."""
        root = self.root
        return self.view("postures", lambda: _postures(root))

    @property
    def turret_angles(self) -> FloatArray:
        """link0 of each unrestricted sample (M,) [rad] (``index`` order)."""
        return self.postures[:, 0]

    def turret(self, points: ArrayLike) -> FloatArray:
        """Turret angle of body-frame CoMs (N, 3): their nearest sample's link0 [rad]."""
        _, rows = self.index.tree.query(np.atleast_2d(np.asarray(points, dtype=float)))
        return self.turret_angles[np.asarray(rows)]

    @functools.cached_property
    def allowed_mask(self) -> NDArray[np.bool_]:
        """Which unrestricted samples the region holds (M,) (all unless windowed)."""
        if self.window is None:
            return np.ones(len(self.root.samples), dtype=bool)
        return np.asarray(self.window.contains(self.turret_angles), dtype=bool)

    @property
    def allowed(self) -> NDArray[np.bool_] | None:
        """The window's :attr:`allowed_mask`, None without a window."""
        return None if self.window is None else self.allowed_mask

    def windowed(self, window: TurretWindow) -> PlanningRegion:
        """The unrestricted region restricted to turret angles in ``window``.

        Raises:
            MmstabError: no sample lies in the window.
        """
        out = PlanningRegion(self.shape, self.workspace, window, self.root)
        if not out.allowed_mask.any():
            raise MmstabError(
                f"planner: no CoM of V has link0 in [{window.lower:.3f}, {window.upper:.3f}] "
                "rad (turret_window too narrow)"
            )
        return out

    def nearest_valid_posture(self, point: ArrayLike) -> FloatArray:
        """The collision-free grid posture whose CoM is nearest to a point [rad]."""
        return np.asarray(self.labelled.nearest_valid_posture(point))


def _index(samples: FloatArray) -> SampleIndex:
    if samples.size == 0:
        raise MmstabError(
            "planner: the workspace V holds no collision-free grid CoM (exhaustive and "
            "coarse-seeded planning score V's samples); V may be empty"
        )
    pts = samples.reshape(-1, 3)
    return SampleIndex(pts, cKDTree(pts))


def _postures(region: PlanningRegion) -> FloatArray:
    """Grid postures of the unrestricted samples: V's mask of the valid CoMs, or all of them."""
    ws = region.labelled
    q = np.asarray(ws.valid_q, dtype=float)
    return q if region.balls is not None else q[np.asarray(ws.valid_in_V, dtype=bool)]


def sample_region(workspace: Workspace, rng: np.random.Generator | None = None) -> PlanningRegion:
    """The ``valid_samples`` region of a workspace, its radius the cloud's median spacing.

    Args:
        workspace: the labelled workspace.
        rng: draws the samples whose spacing is measured; default a generator seeded 0.
    """
    com = np.asarray(workspace.valid_com)
    rng = np.random.default_rng(0) if rng is None else rng
    rows = rng.choice(len(com), size=min(SPACING_SAMPLES, len(com)), replace=False)
    d, _ = cKDTree(com).query(com[rows], k=2)
    balls = SampleBalls(com, float(np.median(d[:, 1])), float(workspace.diameter))
    return PlanningRegion(balls, workspace)


def planning_region(workspace: Workspace, method: str) -> PlanningRegion:
    """The region for ``workspace.method``: V itself or the sample balls."""
    if method == "hull_difference":
        return PlanningRegion(workspace, workspace)
    if method == "valid_samples":
        return sample_region(workspace)
    raise ValueError(f"unknown workspace method {method!r}")


def as_region(region: CoMRegion) -> PlanningRegion:
    """The region itself, V of a bare workspace, or a bare shape (without samples).

    A bare workspace's views are built again on every call (see the module text).
    """
    if isinstance(region, PlanningRegion):
        return region
    if isinstance(region, Workspace):
        return PlanningRegion(region, region)
    return PlanningRegion(region)
