"""A gridded elevation map in the ROS grid_map convention, with bilinear height and normal.

Layout (``docs/terrain.md``): ``resolution`` [m/cell]; ``origin`` = G (x, y) [m] of the
*centre* of cell ``[0, 0]``; ``elevation[iy, ix]`` [m] with row = y and column = x, so the
centre of cell ``[iy, ix]`` is ``origin + resolution * (ix, iy)``; NaN = unknown.
Heights are bilinear between the four surrounding cell centres, so the map covers the
rectangle spanned by the cell centres. Queries off that rectangle or touching an unknown
cell raise :class:`OffMapError` (or, in the unchecked batch form, come back invalid).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.core.files import ConfigError, MmstabError

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


class OffMapError(MmstabError):
    """A query point lies off the map or on an unknown (NaN) cell."""


class HeightSample(NamedTuple):
    """Bilinear samples at query points (any leading shape ``S``).

    Attributes:
        height: terrain height (S) [m]; NaN where invalid.
        dh_dx: slope along G's x (S) [m/m]; NaN where invalid.
        dh_dy: slope along G's y (S) [m/m]; NaN where invalid.
        valid: inside the map and on four known cells (S).
    """

    height: FloatArray
    dh_dx: FloatArray
    dh_dy: FloatArray
    valid: BoolArray


def _real(a: np.ndarray) -> bool:
    """Integer or floating point: not complex (its imaginary part would be dropped), not bool."""
    return bool(np.issubdtype(a.dtype, np.integer) or np.issubdtype(a.dtype, np.floating))


def check_layout(
    source: str | os.PathLike[str], elevation: ArrayLike, resolution: ArrayLike, origin: ArrayLike
) -> tuple[FloatArray, float, FloatArray]:
    """Check a heightmap's three arrays; return them as (elevation, resolution, origin).

    Args:
        source: where they came from (file name), for the error message.
        elevation: (ny, nx) heights [m], floating point, NaN = unknown, ny, nx >= 2.
        resolution: cell size [m], a positive finite scalar.
        origin: (2,) G (x, y) of the centre of cell [0, 0] [m], finite.

    Raises:
        ConfigError: naming ``source`` and the field at fault.
    """
    e = np.asarray(elevation)
    if e.ndim != 2 or min(e.shape) < 2:
        raise ConfigError(source, "elevation", f"must be a 2-D array, at least 2x2, got {e.shape}")
    if not np.issubdtype(e.dtype, np.floating):
        raise ConfigError(source, "elevation", f"must be floating point, got dtype {e.dtype}")
    e = e.astype(np.float64)
    if np.isinf(e).any():
        raise ConfigError(source, "elevation", "contains infinite heights (use NaN for unknown)")
    if not np.isfinite(e).any():
        raise ConfigError(source, "elevation", "all cells are unknown (NaN)")
    r = np.asarray(resolution)
    if r.size != 1 or not _real(r):  # shape and dtype only: an array's repr spans lines
        msg = f"must be one real number [m/cell], got shape {r.shape}, dtype {r.dtype}"
        raise ConfigError(source, "resolution", msg)
    res = float(r.reshape(()))
    if not np.isfinite(res) or res <= 0:
        raise ConfigError(source, "resolution", f"must be positive and finite, got {res}")
    o = np.asarray(origin)
    if o.shape != (2,) or not _real(o):
        msg = f"must be 2 real numbers (x, y) [m], got shape {o.shape}, dtype {o.dtype}"
        raise ConfigError(source, "origin", msg)
    o = o.astype(np.float64)
    if not np.isfinite(o).all():
        raise ConfigError(source, "origin", f"must be finite, got {o.tolist()}")
    return e, res, o


@dataclass(frozen=True, eq=False)
class Heightmap:
    """A checked elevation grid (see the module docstring for the layout).

    Attributes:
        elevation: (ny, nx) heights [m], NaN = unknown.
        resolution: cell size [m].
        origin: G (x, y) of the centre of cell [0, 0] (2,) [m].
        source: where it came from (file name or generator), for error messages.
    """

    elevation: FloatArray
    resolution: float
    origin: FloatArray
    source: str = "<heightmap>"

    @classmethod
    def build(
        cls, elevation: ArrayLike, resolution: float, origin: ArrayLike, source: str = "<heightmap>"
    ) -> Heightmap:
        """Check the arrays (:func:`check_layout`) and build the map."""
        e, r, o = check_layout(source, elevation, resolution, origin)
        e.setflags(write=False)
        o.setflags(write=False)
        return cls(elevation=e, resolution=r, origin=o, source=str(source))

    @property
    def shape(self) -> tuple[int, int]:
        """(ny, nx) cells."""
        ny, nx = self.elevation.shape
        return int(ny), int(nx)

    @property
    def x(self) -> FloatArray:
        """G x of the cell centres, one per column (nx,) [m]."""
        return self.origin[0] + self.resolution * np.arange(self.shape[1])

    @property
    def y(self) -> FloatArray:
        """G y of the cell centres, one per row (ny,) [m]."""
        return self.origin[1] + self.resolution * np.arange(self.shape[0])

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) [m] of the region heights are defined on."""
        return float(self.x[0]), float(self.x[-1]), float(self.y[0]), float(self.y[-1])

    def sample(self, xy: ArrayLike) -> HeightSample:
        """Bilinear height and slope at points, unchecked (invalid points come back NaN).

        Args:
            xy: query points (..., 2) in G [m].
        """
        u, v, ix, iy, inside = self._cells(xy)
        height, dh_dx, dh_dy = self._bilinear(u, v, ix, iy)
        valid = inside & np.isfinite(height)
        if not valid.all():
            bad = ~valid
            height = np.where(bad, np.nan, height)
            dh_dx = np.where(bad, np.nan, dh_dx)
            dh_dy = np.where(bad, np.nan, dh_dy)
        return HeightSample(height, dh_dx, dh_dy, valid)

    def _cells(self, xy: ArrayLike) -> tuple[FloatArray, FloatArray, Any, Any, Any]:
        """Grid coordinates u, v [cells] of points (..., 2) in G [m], lower-left cells, on map.

        The lower-left cells are clipped into the map; ``inside``: the points on it.
        """
        p = np.asarray(xy, dtype=np.float64)
        u, ix, in_x = self._axis(p[..., 0], 0)
        v, iy, in_y = self._axis(p[..., 1], 1)
        return u, v, ix, iy, in_x & in_y

    def _axis(self, c: FloatArray, axis: int) -> tuple[FloatArray, Any, Any]:
        """Grid coordinates [cells] of G coordinates ``c`` [m] along x (0) or y (1).

        With each one's lower cell (clipped into the map) and whether it lies on the map.
        """
        n = self.shape[1 - axis]
        u = (c - self.origin[axis]) / self.resolution
        eps = 1e-9  # the far edge is inside (rounding of a query exactly on it)
        inside = (u >= -eps) & (u <= n - 1 + eps)
        return u, np.clip(np.floor(u), 0, n - 2).astype(np.intp), inside

    def sample_rows(
        self, x: FloatArray, y: FloatArray, slopes: bool = True
    ) -> tuple[FloatArray, ...]:
        """Fast bilinear samples for rows of points; validity per row (the resting-pose loop).

        Args:
            x: G x of the points (n, K) [m].
            y: G y of the points (n, K) [m].
            slopes: also the slopes (``False``: those two come back ``None``).

        Returns:
            ``(height, dh_dx, dh_dy)`` each (n, K), and ``valid`` (n,): every point of the
            row inside the map and on known cells (invalid rows hold garbage).
        """
        ny, nx = self.shape
        u = (x - self.origin[0]) * (1.0 / self.resolution)
        v = (y - self.origin[1]) * (1.0 / self.resolution)
        eps = 1e-9
        valid = (
            (u.min(axis=1) >= -eps)
            & (u.max(axis=1) <= nx - 1 + eps)
            & (v.min(axis=1) >= -eps)
            & (v.max(axis=1) <= ny - 1 + eps)
        )
        ix = np.minimum(np.maximum(u, 0.0).astype(np.intp), nx - 2)  # floor for u >= 0
        iy = np.minimum(np.maximum(v, 0.0).astype(np.intp), ny - 2)
        height, dh_dx, dh_dy = self._bilinear(u, v, ix, iy, slopes)
        valid &= np.isfinite(height.sum(axis=1))
        return height, dh_dx, dh_dy, valid

    def _bilinear(
        self,
        u: FloatArray,
        v: FloatArray,
        ix: NDArray[np.intp],
        iy: NDArray[np.intp],
        slopes: bool = True,
    ) -> tuple[Any, Any, Any]:
        """Bilinear height [m] and slopes d/dx, d/dy at grid coordinates ``u``, ``v`` [cells].

        ``ix``, ``iy`` are the lower-left cells of the points (clipped into the map);
        ``slopes=False`` leaves the slopes out (``None``).
        """
        nx = self.shape[1]
        fx, fy = u - ix, v - iy
        flat = self.elevation.ravel()
        k = iy * nx + ix
        h00, h10 = flat[k], flat[k + 1]
        h01, h11 = flat[k + nx], flat[k + nx + 1]
        ax, bx = h10 - h00, h11 - h01
        low = h00 + fx * ax
        dy = h01 + fx * bx - low
        if not slopes:
            return low + fy * dy, None, None
        inv = 1.0 / self.resolution
        return low + fy * dy, (ax + fy * (bx - ax)) * inv, dy * inv

    def check(self, sample: HeightSample, xy: ArrayLike, what: str = "point") -> None:
        """Raise :class:`OffMapError` naming the first invalid point of ``sample``."""
        if sample.valid.all():
            return
        p = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        k = int(np.flatnonzero(~sample.valid.ravel())[0])
        x, y = p[k]
        x0, x1, y0, y1 = self.bounds
        inside = x0 <= x <= x1 and y0 <= y <= y1
        why = "on an unknown (NaN) cell" if inside else "off the map"
        raise OffMapError(
            f"{self.source}: {what} ({x:.3f}, {y:.3f}) m is {why} "
            f"(map x {x0:.3f}..{x1:.3f}, y {y0:.3f}..{y1:.3f} m)"
        )

    def height(self, xy: ArrayLike) -> FloatArray:
        """Bilinear height at points (..., 2) in G [m] -> (...) [m].

        Raises:
            OffMapError: a point is off the map or on an unknown cell.
        """
        u, v, ix, iy, inside = self._cells(xy)
        height = self._bilinear(u, v, ix, iy, slopes=False)[0]  # :meth:`sample`'s heights
        valid = inside & np.isfinite(height)
        if not valid.all():
            self.check(HeightSample(height, height, height, valid), xy)  # raises
        return height

    def height_grid(self, x: ArrayLike, y: ArrayLike) -> FloatArray:
        """:meth:`height` on the grid of x (n,) times y (m,) in G [m] -> (m, n) [m].

        The same arithmetic as :meth:`height` at each point (the lower row's and the upper
        row's interpolation along x, then along y), each map row interpolated along x once.

        Raises:
            OffMapError: a point is off the map or on an unknown cell.
        """
        xa, ya = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
        (u, ix, in_x), (v, iy, in_y) = self._axis(xa, 0), self._axis(ya, 1)
        if not (in_x.all() and in_y.all()) or not len(ix) or not len(iy):
            return self.height(np.stack(np.meshgrid(xa, ya), axis=-1))  # raises, or empty
        first = int(iy.min())
        rows = self.elevation[first : int(iy.max()) + 2]
        h0, h1 = rows[:, ix], rows[:, ix + 1]
        along = h0 + (u - ix) * (h1 - h0)  # every row's h00 + fx ax of _bilinear
        low, up = along[iy - first], along[iy + 1 - first]
        height = low + (v - iy)[:, None] * (up - low)
        if not np.isfinite(height).all():
            return self.height(np.stack(np.meshgrid(xa, ya), axis=-1))  # raises
        return np.asarray(height)

    def normal(self, xy: ArrayLike) -> FloatArray:
        """Upward unit normal of the bilinear surface at points (..., 2) -> (..., 3).

        Raises:
            OffMapError: a point is off the map or on an unknown cell.
        """
        s = self.sample(xy)
        self.check(s, xy)
        n = np.stack([-s.dh_dx, -s.dh_dy, np.ones_like(s.height)], axis=-1)
        return n / np.linalg.norm(n, axis=-1, keepdims=True)

    def rotated90(self, turns: int = 1) -> Heightmap:
        """The map turned by ``turns`` quarter turns counter-clockwise about G's origin."""
        e, o = self.elevation, self.origin
        r = self.resolution
        for _ in range(turns % 4):
            # (x, y) -> (-y, x): new column ix' reads old row ny-1-ix', new row iy' old column iy'
            x_far = o[1] + r * (e.shape[0] - 1)
            e = e[::-1, :].T
            o = np.array([-x_far, o[0]])
        return Heightmap.build(e, r, o, f"{self.source} (turned {turns % 4} x 90 deg)")

    def translated(self, offset: ArrayLike, dz: float = 0.0) -> Heightmap:
        """The map moved by ``offset`` (2,) in G [m] and raised by ``dz`` [m]."""
        o = self.origin + np.asarray(offset, dtype=float)
        return Heightmap.build(self.elevation + dz, self.resolution, o, self.source)
