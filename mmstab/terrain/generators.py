"""Seeded terrain generators: plane, kerb, ditch, sinusoidal bumps, fractal rough ground.

Every generator fills a :class:`Grid` (a square-celled map centred on G's origin) and
returns a :class:`~mmstab.terrain.heightmap.Heightmap`. Those with randomness take an
``rng`` (``numpy.random.Generator``); :func:`generate` builds one from a problem file's
``terrain.generate`` mapping, seed included, so a map is reproduced from its settings.

Directions are azimuths [rad] in G, counter-clockwise from +x: a plane's azimuth is its
uphill direction, a kerb's or ditch's the direction it is crossed in (the kerb rises
going that way).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mmstab.terrain.heightmap import Heightmap

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Grid:
    """Cells of a generated map: ``nx`` x ``ny`` centres ``resolution`` apart [m].

    ``center`` is the G (x, y) of the middle of the map [m].
    """

    nx: int
    ny: int
    resolution: float
    center: tuple[float, float] = (0.0, 0.0)

    @classmethod
    def of_size(
        cls, size: tuple[float, float], resolution: float, center: tuple[float, float] = (0, 0)
    ) -> Grid:
        """A grid covering at least ``size`` (x, y) [m] at ``resolution`` [m/cell]."""
        nx = int(np.ceil(size[0] / resolution - 1e-9)) + 1
        ny = int(np.ceil(size[1] / resolution - 1e-9)) + 1
        return cls(nx, ny, float(resolution), (float(center[0]), float(center[1])))

    @property
    def origin(self) -> FloatArray:
        """G (x, y) of the centre of cell [0, 0] [m]."""
        half = self.resolution * np.array([self.nx - 1, self.ny - 1]) / 2
        return np.asarray(self.center, dtype=float) - half

    def xy(self) -> tuple[FloatArray, FloatArray]:
        """G x and y of every cell centre, each (ny, nx) [m]."""
        o = self.origin
        x = o[0] + self.resolution * np.arange(self.nx)
        y = o[1] + self.resolution * np.arange(self.ny)
        return np.meshgrid(x, y)

    def along(self, azimuth: float) -> FloatArray:
        """Signed distance of every cell centre along the azimuth [rad], from the map centre."""
        x, y = self.xy()
        return (x - self.center[0]) * np.cos(azimuth) + (y - self.center[1]) * np.sin(azimuth)

    def heightmap(self, elevation: FloatArray, source: str) -> Heightmap:
        """Wrap ``elevation`` (ny, nx) [m] as a checked heightmap."""
        return Heightmap.build(elevation, self.resolution, self.origin, source)


def plane_elevation(grid: Grid, slope: float, azimuth: float) -> FloatArray:
    """A plane through the map centre at height 0 rising ``slope`` [rad] toward ``azimuth``."""
    return np.tan(slope) * grid.along(azimuth)


def plane(grid: Grid, slope: float, azimuth: float) -> Heightmap:
    """Planar ground of ``slope`` [rad], uphill toward ``azimuth`` [rad]."""
    return grid.heightmap(plane_elevation(grid, slope, azimuth), f"plane({slope:g}, {azimuth:g})")


def kerb(grid: Grid, height: float, distance: float, azimuth: float) -> Heightmap:
    """A step of ``height`` [m] (negative: a drop) ``distance`` [m] from the centre.

    Cells whose centre is at least ``distance`` along ``azimuth`` are raised; with bilinear
    heights the face rises over the one cell before the first raised centre.
    """
    d = grid.along(azimuth)
    e = np.where(d >= distance - 1e-9 * grid.resolution, height, 0.0)
    return grid.heightmap(e, f"kerb({height:g} m)")


def ditch(grid: Grid, depth: float, width: float, distance: float, azimuth: float) -> Heightmap:
    """A flat-bottomed ditch ``depth`` [m] deep, ``width`` [m] wide, centred ``distance`` away."""
    d = grid.along(azimuth)
    e = np.where(np.abs(d - distance) <= width / 2 + 1e-9 * grid.resolution, -depth, 0.0)
    return grid.heightmap(e, f"ditch({depth:g} m x {width:g} m)")


def bumps_elevation(
    grid: Grid, amplitude: float, wavelength: float, rng: np.random.Generator
) -> FloatArray:
    """Egg-box bumps ``amplitude`` [m] high, ``wavelength`` [m] apart, at random phases."""
    x, y = grid.xy()
    phase = rng.uniform(0.0, 2 * np.pi, size=2)
    k = 2 * np.pi / wavelength
    return amplitude * np.sin(k * x + phase[0]) * np.sin(k * y + phase[1])


def bumps(grid: Grid, amplitude: float, wavelength: float, rng: np.random.Generator) -> Heightmap:
    """Sinusoidal bumps (see :func:`bumps_elevation`)."""
    e = bumps_elevation(grid, amplitude, wavelength, rng)
    return grid.heightmap(e, f"bumps({amplitude:g} m, {wavelength:g} m)")


def fractal_elevation(
    grid: Grid,
    amplitude: float,
    correlation_length: float,
    rng: np.random.Generator,
    hurst: float = 0.8,
) -> FloatArray:
    """Gaussian random rough ground: RMS height ``amplitude`` [m], zero mean.

    Spectral synthesis (FFT of white noise shaped by a von Karman spectrum
    ``(1 + (k l)^2)^-(hurst + 1)``, ``l`` = ``correlation_length`` [m]): self-affine (fractal)
    below ``l``, flat above. Computed on a grid twice as large so the map does not wrap.
    """
    ny, nx = 2 * grid.ny, 2 * grid.nx
    noise = rng.standard_normal((ny, nx))
    kx = 2 * np.pi * np.fft.fftfreq(nx, d=grid.resolution)
    ky = 2 * np.pi * np.fft.fftfreq(ny, d=grid.resolution)
    k2 = kx[None, :] ** 2 + ky[:, None] ** 2
    amp = (1.0 + k2 * correlation_length**2) ** (-(hurst + 1) / 2)
    field = np.fft.ifft2(np.fft.fft2(noise) * amp).real[: grid.ny, : grid.nx]
    field -= field.mean()
    rms = float(np.sqrt(np.mean(field**2)))
    return amplitude * field / rms if rms > 0 else field


def rough(
    grid: Grid,
    amplitude: float,
    correlation_length: float,
    rng: np.random.Generator,
    hill_height: float = 0.0,
    hill_radius: float = 1.0,
    slope: float = 0.0,
    azimuth: float = 0.0,
) -> Heightmap:
    """Fractal rough ground on a Gaussian hill on a plane (any part may be zero).

    Args:
        grid: the cells.
        amplitude: RMS height of the roughness [m].
        correlation_length: its correlation length [m].
        rng: random generator (the roughness).
        hill_height: height of a Gaussian hill at the map centre [m].
        hill_radius: its standard deviation [m].
        slope: slope of the underlying plane [rad].
        azimuth: its uphill direction [rad].
    """
    x, y = grid.xy()
    r2 = (x - grid.center[0]) ** 2 + (y - grid.center[1]) ** 2
    e = fractal_elevation(grid, amplitude, correlation_length, rng)
    e = e + hill_height * np.exp(-r2 / (2 * hill_radius**2)) + plane_elevation(grid, slope, azimuth)
    return grid.heightmap(e, f"rough({amplitude:g} m, {correlation_length:g} m)")


# ------------------------------------------------------------------- from a problem file
def _plane(g: Grid, s: dict[str, Any], rng: np.random.Generator) -> Heightmap:
    return plane(g, s["slope"], s["azimuth"])


def _kerb(g: Grid, s: dict[str, Any], rng: np.random.Generator) -> Heightmap:
    return kerb(g, s["height"], s["distance"], s["azimuth"])


def _ditch(g: Grid, s: dict[str, Any], rng: np.random.Generator) -> Heightmap:
    return ditch(g, s["depth"], s["width"], s["distance"], s["azimuth"])


def _bumps(g: Grid, s: dict[str, Any], rng: np.random.Generator) -> Heightmap:
    return bumps(g, s["amplitude"], s["wavelength"], rng)


def _rough(g: Grid, s: dict[str, Any], rng: np.random.Generator) -> Heightmap:
    return rough(
        g,
        s["amplitude"],
        s["correlation_length"],
        rng,
        hill_height=s["hill_height"],
        hill_radius=s["hill_radius"],
        slope=s["slope"],
        azimuth=s["azimuth"],
    )


#: kind -> builder(grid, settings, rng); the settings' keys are in ``schema_terrain.TERRAIN_KINDS``.
KINDS: dict[str, Callable[[Grid, dict[str, Any], np.random.Generator], Heightmap]] = {
    "plane": _plane,
    "kerb": _kerb,
    "ditch": _ditch,
    "bumps": _bumps,
    "rough": _rough,
}


#: Features ``generate`` lays onto a map, in this order.
FEATURES = ("ditch", "kerb", "bumps")


def generate(settings: dict[str, Any]) -> Heightmap:
    """Build the map a (validated) ``terrain.generate`` mapping describes.

    Args:
        settings: ``kind``, ``seed``, ``size`` [m, m], ``resolution`` [m/cell], the
            kind's own keys (``schema_terrain.TERRAIN_KINDS``) and optional ``features``: a
            ``ditch``, a ``kerb`` and/or ``bumps`` (their kinds' keys) added to the elevation
            in that order (the bumps' phases drawn after the kind's randomness).
    """
    grid = Grid.of_size(tuple(settings["size"]), settings["resolution"])
    rng = np.random.default_rng(settings["seed"])
    hm = KINDS[settings["kind"]](grid, settings, rng)
    name = f"generate.{settings['kind']}(seed {settings['seed']})"
    elevation = hm.elevation
    features = settings.get("features", {})
    if features:  # laid onto the map (drawn after the kind's randomness)
        elevation = elevation.copy()
        for feature in FEATURES:
            if feature in features:
                elevation += KINDS[feature](grid, features[feature], rng).elevation
        name += " + " + " + ".join(f for f in FEATURES if f in features)
    return Heightmap.build(elevation, hm.resolution, hm.origin, name)
