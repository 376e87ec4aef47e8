"""Make ``ditch.npz``: the ground of ``problems/ditch.yaml`` (seeded, reproducible).

A user's map written with NumPy: a 15° side slope rising toward +y, a flat-bottomed ditch
20 cm deep and 0.6 m wide across x = 0, and six Gaussian bumps 6 cm high (σ 0.3 m, seed 7);
10 m x 10 m at 5 cm cells, float32, origin (-5, -5) m. Run from the repository root:
``.venv/bin/python problems/terrains/make_ditch.py``.
"""

from pathlib import Path

import numpy as np

rng = np.random.default_rng(7)
res = 0.05
x = np.arange(-5, 5 + 1e-9, res)
y = np.arange(-5, 5 + 1e-9, res)
X, Y = np.meshgrid(x, y)  # rows: y, columns: x (grid_map's layout)
z = np.tan(np.radians(15)) * Y
z -= 0.20 * (np.abs(X) < 0.3)
for _ in range(6):
    cx, cy = rng.uniform(-4, 4, 2)
    z += 0.06 * np.exp(-((X - cx) ** 2 + (Y - cy) ** 2) / (2 * 0.3**2))
np.savez_compressed(
    Path(__file__).with_name("ditch.npz"),
    elevation=z.astype(np.float32),
    resolution=res,
    origin=np.array([x[0], y[0]]),
)
