"""Make ``bumps_ditch.tif``: the GeoTIFF DEM of ``problems/dem.yaml`` (seeded, reproducible).

Sinusoidal bumps (5 cm, 1.6 m apart, seed 5) crossed by a 12 cm deep, 0.5 m wide ditch
running along y at x = 1.2 m; 8 m x 8 m at 5 cm cells, float32, origin (-4, -4) m.
Run from the repository root: ``.venv/bin/python problems/terrains/make_geotiff.py``.
"""

from pathlib import Path

import numpy as np

from mmstab.terrain.generators import Grid, bumps_elevation
from mmstab.terrain.heightmap import Heightmap
from mmstab.terrain.io import write_geotiff

grid = Grid.of_size((8.0, 8.0), 0.05)
elevation = bumps_elevation(grid, 0.05, 1.6, np.random.default_rng(5))
elevation[np.abs(grid.along(0.0) - 1.2) <= 0.25] -= 0.12
hm = Heightmap.build(elevation.astype(np.float32).astype(float), grid.resolution, grid.origin)
out = write_geotiff(Path(__file__).with_name("bumps_ditch.tif"), hm)
print(f"wrote {out} ({out.stat().st_size} bytes)")
