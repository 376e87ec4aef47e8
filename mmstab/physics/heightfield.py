"""A grid_map heightmap as a MuJoCo ``hfield`` (MJCF text) and its bilinear height.

Heightmap convention (ROS grid_map, ``docs/terrain.md``): ``resolution`` [m/cell],
``origin`` = G (x, y) of the centre of cell [0, 0] [m], ``elevation[iy, ix]`` [m] with
row = y and column = x. Samples sit at cell centres; the surface between them is
interpolated (bilinear here, two triangles per cell in MuJoCo: equal on planes).

MuJoCo's hfield conventions (checked by ``tests/physics/test_mujoco_drop.py``):

- ``size = (rx, ry, elevation_z, base_z)``: the field spans ``[-rx, rx] x [-ry, ry]`` about
  the geom's position, with its first and last samples ON those edges, so
  ``rx = (ncol - 1) * resolution / 2``;
- the data are normalised to [0, 1] by MuJoCo itself (it rescales whatever it is given), and
  the height is ``geom_z + elevation_z * data``: so we normalise by (min, max) ourselves and
  place the geom at ``z = min``; ``base_z`` is the depth of the solid below it;
- the ``elevation`` attribute lists rows from +y down to -y (image order): its first row is
  the field's last one (y = +ry), so grid_map rows (row 0 = smallest y) go in reversed.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.core.files import MmstabError
from mmstab.model.robot import FloatArray

#: Vertical extent given to a perfectly flat field so MuJoCo's size stays positive [m].
FLAT_RANGE = 1e-3


class Heightmap(NamedTuple):
    """A grid_map elevation grid.

    Attributes:
        elevation: heights ``[iy, ix]`` (ny, nx) [m], finite.
        resolution: cell size [m/cell].
        origin: G (x, y) of the centre of cell [0, 0] (2,) [m].
    """

    elevation: FloatArray
    resolution: float
    origin: FloatArray

    @property
    def extent(self) -> FloatArray:
        """(x_min, x_max, y_min, y_max) of the sample centres [m]."""
        ny, nx = self.elevation.shape
        x0, y0 = self.origin
        return np.array([x0, x0 + (nx - 1) * self.resolution, y0, y0 + (ny - 1) * self.resolution])

    def height(self, xy: ArrayLike) -> FloatArray:
        """Bilinear height at G points ``xy`` (..., 2) [m] -> (...) [m]; clamped at the edges."""
        p = np.asarray(xy, dtype=float)
        ny, nx = self.elevation.shape
        u = np.clip((p[..., 0] - self.origin[0]) / self.resolution, 0.0, nx - 1.0)
        v = np.clip((p[..., 1] - self.origin[1]) / self.resolution, 0.0, ny - 1.0)
        i0 = np.minimum(np.floor(u).astype(int), nx - 2)
        j0 = np.minimum(np.floor(v).astype(int), ny - 2)
        fu, fv = u - i0, v - j0
        e = self.elevation
        return (
            e[j0, i0] * (1 - fu) * (1 - fv)
            + e[j0, i0 + 1] * fu * (1 - fv)
            + e[j0 + 1, i0] * (1 - fu) * fv
            + e[j0 + 1, i0 + 1] * fu * fv
        )

    def contains(self, xy: ArrayLike) -> np.ndarray:
        """Whether G points ``xy`` (..., 2) [m] lie inside the sampled area (...) bool."""
        p = np.asarray(xy, dtype=float)
        x0, x1, y0, y1 = self.extent
        return (p[..., 0] >= x0) & (p[..., 0] <= x1) & (p[..., 1] >= y0) & (p[..., 1] <= y1)


def heightmap(elevation: ArrayLike, resolution: float, origin: ArrayLike) -> Heightmap:
    """Check and wrap a grid_map heightmap.

    Args:
        elevation: heights ``[iy, ix]`` (ny, nx) [m], ny, nx >= 2, all finite.
        resolution: cell size [m/cell], > 0.
        origin: G (x, y) of the centre of cell [0, 0] [m].

    Raises:
        MmstabError: a bad shape, a NaN/inf height (MuJoCo has no unknown cells) or resolution.
    """
    e = np.asarray(elevation, dtype=float)
    if e.ndim != 2 or min(e.shape) < 2:
        raise MmstabError(f"heightmap elevation: need a (ny, nx) grid, ny, nx >= 2, got {e.shape}")
    if not np.all(np.isfinite(e)):
        raise MmstabError("heightmap elevation: NaN/inf cells cannot be dropped on in MuJoCo")
    res = float(resolution)
    if not np.isfinite(res) or res <= 0:
        raise MmstabError(f"heightmap resolution: must be a positive number, got {resolution}")
    o = np.asarray(origin, dtype=float).reshape(-1)
    if o.shape != (2,) or not np.all(np.isfinite(o)):
        raise MmstabError(f"heightmap origin: need finite (x, y), got {o}")
    return Heightmap(e, res, o)


class HfieldSpec(NamedTuple):
    """The MJCF pieces of a heightmap: asset line, geom line, and the numbers in them."""

    asset: str
    geom: str
    size: FloatArray  # (rx, ry, elevation_z, base_z) [m]
    pos: FloatArray  # geom position in G [m]


def hfield_mjcf(hm: Heightmap, name: str = "terrain", base_z: float = 0.5) -> HfieldSpec:
    """MJCF ``<hfield>`` asset and ``<geom>`` that reproduce ``hm`` in G.

    Args:
        hm: the heightmap.
        name: asset and geom name.
        base_z: depth of the solid below the lowest sample [m].
    """
    e = hm.elevation
    ny, nx = e.shape
    lo, hi = float(e.min()), float(e.max())
    span = hi - lo
    data = (e - lo) / span if span > 0 else np.zeros_like(e)
    z_range = span if span > 0 else FLAT_RANGE
    rx, ry = (nx - 1) * hm.resolution / 2, (ny - 1) * hm.resolution / 2
    size = np.array([rx, ry, z_range, base_z])
    pos = np.array([hm.origin[0] + rx, hm.origin[1] + ry, lo])
    values = " ".join(f"{v:.9g}" for v in data[::-1].ravel())
    asset = (
        f'<hfield name="{name}" nrow="{ny}" ncol="{nx}" size="{_fmt(size)}" elevation="{values}"/>'
    )
    geom = f'<geom name="{name}" type="hfield" hfield="{name}" pos="{_fmt(pos)}"/>'
    return HfieldSpec(asset, geom, size, pos)


def _fmt(values: ArrayLike) -> str:
    return " ".join(f"{float(v):.12g}" for v in np.asarray(values).ravel())
