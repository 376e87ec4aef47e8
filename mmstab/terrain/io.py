"""Heightmap files: ``.npz`` (the layout itself), GeoTIFF DEMs, triangle meshes.

* ``.npz``: exactly the arrays ``elevation`` (ny, nx) float, ``resolution`` (scalar) and
  ``origin`` (2,), as in :mod:`mmstab.terrain.heightmap`; :func:`save_npz` writes one.
* ``.tif``/``.tiff``: a GeoTIFF with one floating-point band; the pixel size comes from
  ``ModelPixelScaleTag`` (square pixels), the origin from ``ModelTiepointTag`` and the
  raster type (``GTRasterTypeGeoKey``: pixel-is-area, the default, or pixel-is-point);
  rows run north to south in the file and are flipped to row = +y here; the
  ``GDAL_NODATA`` value becomes NaN.
* ``.stl``/``.ply``/``.obj``: a triangle mesh (trimesh), z up, rasterised at a given
  resolution: each cell centre takes the highest surface above it, NaN where none is.

Every failure is a :class:`~mmstab.core.files.ConfigError` naming the file and the field.
"""

from __future__ import annotations

import logging
import os
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from mmstab.core.files import ConfigError, write_npz
from mmstab.core.sizes import TERRAIN_BYTES_PER_CELL, Estimate, refusal
from mmstab.terrain.heightmap import FloatArray, Heightmap, check_layout

NPZ_KEYS = ("elevation", "resolution", "origin")
TIFF_SUFFIXES = (".tif", ".tiff")
MESH_SUFFIXES = (".stl", ".ply", ".obj")
SUFFIXES = (".npz", *TIFF_SUFFIXES, *MESH_SUFFIXES)

# GeoTIFF tags and keys (OGC GeoTIFF 1.1)
TAG_PIXEL_SCALE = 33550
TAG_TIEPOINT = 33922
TAG_GEOKEYS = 34735
TAG_NODATA = 42113
KEY_RASTER_TYPE = 1025
PIXEL_IS_AREA, PIXEL_IS_POINT = 1, 2


def load_heightmap(path: str | os.PathLike[str], resolution: float | None = None) -> Heightmap:
    """Load a heightmap by the file's extension.

    Args:
        path: a ``.npz``, GeoTIFF or mesh file.
        resolution: cell size for rasterising a mesh [m/cell] (required for meshes only).

    Raises:
        ConfigError: missing/unreadable file, bad arrays or tags, an empty mesh.
    """
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in SUFFIXES:
        raise ConfigError(p, "", f"unknown heightmap format {suffix!r} (use {', '.join(SUFFIXES)})")
    if not p.is_file():
        raise ConfigError(p, "", "no such file")
    if suffix == ".npz":
        return load_npz(p)
    if suffix in TIFF_SUFFIXES:
        return load_geotiff(p)
    if resolution is None:
        raise ConfigError(p, "resolution", "a mesh needs a resolution [m/cell] to rasterise")
    return load_mesh(p, resolution)


def check_cells(path: Path, field: str, shape: Any) -> None:
    """Refuse a map of ``shape`` (rows, columns) cells that would not fit in memory.

    Bounded as a generated map (:data:`mmstab.core.sizes.TERRAIN_BYTES_PER_CELL`), before
    the file's cells are read or rasterised.

    Raises:
        ConfigError: naming ``path`` and ``field``.
    """
    cells = float(np.prod([float(n) for n in shape]))
    if not np.isfinite(cells):
        raise ConfigError(path, field, "the map would have infinitely many cells")
    work = f"{cells:.3g} map cells ({' x '.join(f'{float(n):.0f}' for n in shape)})"
    why = refusal(Estimate(field, work, 0.0, cells * TERRAIN_BYTES_PER_CELL), force=True)
    if why is not None:
        raise ConfigError(path, field, why)


@contextmanager
def _quiet(logger: str) -> Iterator[None]:
    """Silence a library's log lines (a bad file's complaints come back as one ConfigError)."""
    log = logging.getLogger(logger)
    level = log.level
    log.setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        log.setLevel(level)


# ------------------------------------------------------------------------------------- npz
def load_npz(path: Path) -> Heightmap:
    """Read an ``.npz`` holding exactly ``elevation``, ``resolution`` and ``origin``."""
    try:
        # opened here: np.load leaves its own handle open when the zip is garbage
        with open(path, "rb") as fh:
            data = np.load(fh, allow_pickle=False)
            if not isinstance(data, np.lib.npyio.NpzFile):  # one .npy array, renamed
                raise ConfigError(path, "", "a single .npy array, not an .npz archive")
            with data:
                arrays: dict[str, Any] = {k: data[k] for k in data.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise ConfigError(path, "", f"cannot read as .npz ({exc})") from None
    except MemoryError:  # an array header claiming more than this machine holds
        raise ConfigError(path, "", "its arrays do not fit in memory") from None
    missing = [k for k in NPZ_KEYS if k not in arrays]
    if missing:
        raise ConfigError(path, missing[0], "missing array (need elevation, resolution, origin)")
    extra = sorted(set(arrays) - set(NPZ_KEYS))
    if extra:
        raise ConfigError(path, extra[0], "unexpected array (only elevation, resolution, origin)")
    return Heightmap.build(arrays["elevation"], arrays["resolution"], arrays["origin"], str(path))


def save_npz(path: str | os.PathLike[str], heightmap: Heightmap) -> Path:
    """Write ``heightmap`` as an ``.npz`` in the layout, atomically."""
    return write_npz(
        path,
        elevation=heightmap.elevation,
        resolution=np.float64(heightmap.resolution),
        origin=heightmap.origin,
    )


# --------------------------------------------------------------------------------- GeoTIFF
def _geokeys(tags: Any) -> dict[int, int]:
    if TAG_GEOKEYS not in tags:
        return {}
    v = [int(x) for x in tags[TAG_GEOKEYS].value]
    return {v[i]: v[i + 3] for i in range(4, 4 + 4 * v[3], 4) if v[i + 1] == 0}


def load_geotiff(path: Path) -> Heightmap:
    """Read a one-band floating-point GeoTIFF DEM (see the module docstring)."""
    import tifffile

    try:
        with _quiet("tifffile"), tifffile.TiffFile(path) as tif:
            page = tif.pages[0]
            check_cells(path, "band", page.shape[:2])  # before reading: the tags may lie
            raster = page.asarray()
            tags = page.tags  # type: ignore[union-attr]
            scale = tags[TAG_PIXEL_SCALE].value if TAG_PIXEL_SCALE in tags else None
            tie = tags[TAG_TIEPOINT].value if TAG_TIEPOINT in tags else None
            nodata = tags[TAG_NODATA].value if TAG_NODATA in tags else None
            keys = _geokeys(tags)
    except (OSError, ValueError, tifffile.TiffFileError, IndexError, MemoryError) as exc:
        raise ConfigError(path, "", f"cannot read as GeoTIFF ({exc})") from None
    if raster.ndim == 3 and raster.shape[-1] == 1:
        raster = raster[..., 0]
    if raster.ndim != 2:
        raise ConfigError(path, "band", f"need one band (rows, columns), got shape {raster.shape}")
    if not np.issubdtype(raster.dtype, np.floating):
        raise ConfigError(path, "band", f"need floating-point heights, got dtype {raster.dtype}")
    if scale is None or len(scale) < 2:
        raise ConfigError(path, "ModelPixelScaleTag", "missing: the pixel size is unknown")
    if tie is None or len(tie) < 6:
        raise ConfigError(path, "ModelTiepointTag", "missing: the origin is unknown")
    sx, sy = _numbers(path, "ModelPixelScaleTag", scale, 2)
    if not (np.isfinite(sx) and np.isfinite(sy) and sx > 0 and sy > 0):
        raise ConfigError(path, "ModelPixelScaleTag", f"pixel size must be > 0, got {sx}, {sy}")
    if abs(sx - sy) > 1e-9 * max(sx, sy):
        raise ConfigError(path, "ModelPixelScaleTag", f"pixels must be square, got {sx} x {sy}")
    elevation = raster.astype(np.float64)
    if nodata is not None:
        try:
            nd = float(str(nodata).strip("\x00 "))
        except ValueError:
            raise ConfigError(path, "GDAL_NODATA", f"not a number: {nodata!r}") from None
        elevation[elevation == nd] = np.nan
    i, j, _, x_tie, y_tie = _numbers(path, "ModelTiepointTag", tie, 5)
    half = 0.5 if keys.get(KEY_RASTER_TYPE, PIXEL_IS_AREA) == PIXEL_IS_AREA else 0.0
    rows = elevation.shape[0]
    origin = np.array([x_tie + (half - i) * sx, y_tie - (rows - 1 + half - j) * sy])
    return Heightmap.build(elevation[::-1], sx, origin, str(path))


def _numbers(path: Path, tag: str, value: Any, n: int) -> list[float]:
    """The first ``n`` numbers of a tag's value (a tag written as text is refused by name)."""
    try:
        return [float(v) for v in value[:n]]
    except (TypeError, ValueError):
        raise ConfigError(path, tag, f"must hold numbers, got {type(value).__name__}") from None


def write_geotiff(path: str | os.PathLike[str], heightmap: Heightmap) -> Path:
    """Write ``heightmap`` as a float32 GeoTIFF (pixel-is-area, NaN as GDAL_NODATA)."""
    import tifffile

    r = heightmap.resolution
    ny = heightmap.shape[0]
    # top-left corner of the top-left pixel (the last row here is the first in the file)
    x_tie = heightmap.origin[0] - r / 2
    y_tie = heightmap.origin[1] + (ny - 1) * r + r / 2
    nodata = -9999.0
    data = np.where(np.isnan(heightmap.elevation), nodata, heightmap.elevation)[::-1]
    geokeys = (1, 1, 0, 1, KEY_RASTER_TYPE, 0, 1, PIXEL_IS_AREA)
    extratags = [
        (TAG_PIXEL_SCALE, "d", 3, (r, r, 0.0), True),
        (TAG_TIEPOINT, "d", 6, (0.0, 0.0, 0.0, x_tie, y_tie, 0.0), True),
        (TAG_GEOKEYS, "H", len(geokeys), geokeys, True),
        (TAG_NODATA, "s", 0, f"{nodata:g}", True),
    ]
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.tmp")
    tifffile.imwrite(tmp, data.astype(np.float32), extratags=extratags)
    os.replace(tmp, out)
    return out


# ------------------------------------------------------------------------------------ mesh
def rasterise(vertices: FloatArray, faces: np.ndarray, resolution: float) -> Heightmap:
    """Top surface of a triangle mesh sampled at cell centres ``resolution`` apart.

    Args:
        vertices: (V, 3) [m], z up.
        faces: (F, 3) vertex indices.
        resolution: cell size [m/cell].

    Returns:
        the map over the mesh's x-y bounding box (origin at its lower-left corner), NaN
        where no triangle lies above a cell centre.
    """
    lo = vertices[:, :2].min(axis=0)
    n = np.floor((vertices[:, :2].max(axis=0) - lo) / resolution + 1e-9).astype(int) + 1
    nx, ny = max(int(n[0]), 2), max(int(n[1]), 2)
    tri = vertices[faces]  # (F, 3, 3)
    uv = (tri[..., :2] - lo) / resolution  # cell coordinates of the corners
    i0 = np.clip(np.ceil(uv[..., 0].min(axis=1) - 1e-9), 0, nx - 1).astype(int)
    i1 = np.clip(np.floor(uv[..., 0].max(axis=1) + 1e-9), 0, nx - 1).astype(int)
    j0 = np.clip(np.ceil(uv[..., 1].min(axis=1) - 1e-9), 0, ny - 1).astype(int)
    j1 = np.clip(np.floor(uv[..., 1].max(axis=1) + 1e-9), 0, ny - 1).astype(int)
    w, h = np.maximum(i1 - i0 + 1, 0), np.maximum(j1 - j0 + 1, 0)
    counts = w * h
    f = np.repeat(np.arange(len(faces)), counts)
    k = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    ci = i0[f] + k % np.maximum(w[f], 1)
    cj = j0[f] + k // np.maximum(w[f], 1)
    a, b, c = uv[f, 0], uv[f, 1], uv[f, 2]
    p = np.stack([ci, cj], axis=1).astype(float)
    v0, v1, v2 = b - a, c - a, p - a
    den = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
    ok = np.abs(den) > 1e-12  # triangles seen edge-on from above carry no surface
    den = np.where(ok, den, 1.0)
    s = (v2[:, 0] * v1[:, 1] - v1[:, 0] * v2[:, 1]) / den
    t = (v0[:, 0] * v2[:, 1] - v2[:, 0] * v0[:, 1]) / den
    tol = 1e-9
    hit = ok & (s >= -tol) & (t >= -tol) & (s + t <= 1 + tol)
    z = tri[f, 0, 2] + s * (tri[f, 1, 2] - tri[f, 0, 2]) + t * (tri[f, 2, 2] - tri[f, 0, 2])
    elevation = np.full((ny, nx), -np.inf)
    np.maximum.at(elevation, (cj[hit], ci[hit]), z[hit])
    elevation[np.isneginf(elevation)] = np.nan
    return Heightmap(elevation=elevation, resolution=float(resolution), origin=lo.astype(float))


def load_mesh(path: Path, resolution: float) -> Heightmap:
    """Read an STL/PLY/OBJ triangle mesh (trimesh) and rasterise it at ``resolution``."""
    import trimesh

    res = float(resolution)
    if not np.isfinite(res) or res <= 0:
        raise ConfigError(path, "resolution", f"must be positive and finite, got {res}")
    try:
        mesh = trimesh.load(path, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many types for a bad file
        raise ConfigError(path, "", f"cannot read as a mesh ({type(exc).__name__})") from None
    faces = np.asarray(getattr(mesh, "faces", np.zeros((0, 3))), dtype=np.intp)
    vertices = np.asarray(getattr(mesh, "vertices", np.zeros((0, 3))), dtype=float)
    if faces.ndim != 2 or faces.shape[0] == 0:
        raise ConfigError(path, "faces", "the mesh has no faces")
    if not np.isfinite(vertices).all():
        raise ConfigError(path, "vertices", "the mesh has non-finite vertices")
    with np.errstate(over="ignore", invalid="ignore"):  # 1e308 vertices: inf cells, refused
        extent = np.ptp(vertices[:, :2], axis=0) / res + 1.0
    check_cells(path, "resolution", tuple(extent))
    hm = rasterise(vertices, faces, res)
    e, r, o = check_layout(path, hm.elevation, hm.resolution, hm.origin)
    return Heightmap.build(e, r, o, str(path))
