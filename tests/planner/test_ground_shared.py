"""The one ground-under-the-arm check (mmstab.planner.ground), offline and online, agrees.

On seeded random maps with a ditch, a kerb, a bump and unknown patches:

- the online verification of a node (:meth:`MapGround.node_clear`: the map cells' bound,
  then each doubtful piece's peak from its pose's ground, C or tiles) gives the answers of
  the former per-piece NumPy test (its own lattice about each piece, kept here as the
  reference), with the kernel and without, and batched over poses as one pose at a time;
- on a fully known map the online pose's heights (the live map's lattice, the C peaks)
  equal the offline planner's (:class:`GroundUnderArm` on the same map as a terrain, its
  peak map by tiles, heights by C and by NumPy).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_postures
from test_online_lattice import rested, tilted_pose

from mmstab.planner.ground.kernel import kernel_available
from mmstab.planner.ground.map_ground import ArmGround, MapGround
from mmstab.planner.ground.map_lattice import filled, lattice_z
from mmstab.planner.ground.under_arm import (
    BLOCK,
    LATTICE,
    SLACK,
    GroundUnderArm,
    KeptPieces,
    plane_z,
)
from mmstab.terrain.heightmap import Heightmap
from mmstab.terrain.heightmap_terrain import HeightmapTerrain

pytestmark = pytest.mark.skipif(not kernel_available(), reason="no C compiler")

GROUND = 0.05  #: the clearance tested [m]


def featured_map(rng: np.random.Generator, res: float, unknown: float) -> HeightmapTerrain:
    """A 4 m map [m]: 1 cm rough, a 12 cm ditch, a 10 cm kerb, an 8 cm bump, NaN patches."""
    n = int(round(4.0 / res)) + 1
    origin = np.array([-2.0, -2.0]) + rng.uniform(-0.03, 0.03, 2)
    x = origin[0] + res * np.arange(n)
    y = origin[1] + res * np.arange(n)
    X, Y = np.meshgrid(x, y)
    z = 0.01 * rng.standard_normal((n, n)) + 0.1 * rng.random() * Y
    a, b, c = rng.uniform(-0.8, 0.8, 3)
    z -= 0.12 * (np.abs(X - a) < 0.15)  # a ditch across x = a
    z += 0.10 * (Y > b)  # a kerb rising at y = b
    bump = rng.uniform(-0.8, 0.8, 2)
    z += 0.08 * np.exp(-((X - bump[0]) ** 2 + (Y - bump[1]) ** 2) / (2 * 0.1**2))
    for _ in range(int(unknown * 40)):  # square patches of unknown cells
        i, j = rng.integers(0, n - 6, 2)
        z[i : i + 6, j : j + 6] = np.nan
    return HeightmapTerrain(Heightmap.build(z, res, origin, "featured"))


def reference_node_clear(g: MapGround, ks: list[int], body, ground: float) -> tuple:
    """The former per-piece NumPy verification: each doubtful piece's own lattice square.

    Returns per pose whether clear; and per doubtful piece its pose, lattice sample (i, j)
    and peak [m].
    """
    T = np.stack([g.state(k).ground.M_T_B for k in ks])
    lowest = body.low / T[:, 2, 2, None]
    c_M = np.einsum("nij,npj->npi", T[:, :3, :3], body.centre) + T[:, None, :3, 3]
    n, P = lowest.shape
    pose = np.repeat(np.arange(n), P)
    fill = np.array([g.reach(k)[1] for k in ks])[pose]
    c_M = c_M.reshape(-1, 3)
    rise, _ = g._cell_bound(T[pose], c_M, fill)
    doubt = np.flatnonzero(lowest.ravel() - np.maximum(rise, 0.0) < ground - SLACK)
    ok = np.ones(n * P, dtype=bool)
    half = -(-g.arm.cells // BLOCK)
    m = (2 * half + 1) * BLOCK
    at = np.floor(c_M[doubt, :2] / LATTICE).astype(np.intp)
    peaks = np.empty(len(doubt))
    for d, p in enumerate(doubt):
        i, j = at[d] // BLOCK - half
        x = (i * BLOCK + np.arange(m)) * LATTICE
        y = (j * BLOCK + np.arange(m)) * LATTICE
        plane = plane_z(T[pose[p]], x[None, :], y[:, None])
        peak = peaks[d] = float((filled(lattice_z(g.hm, x, y), plane, fill[p]) - plane).max())
        h = lowest.ravel()[p] - peak if peak > SLACK else lowest.ravel()[p]
        ok[p] = h >= ground - SLACK
    return ok.reshape(n, P).all(axis=1), (np.asarray(ks)[pose[doubt]], at, peaks)


@pytest.mark.parametrize("res", [0.05, 0.02])
def test_node_clear_equals_the_former_per_piece_numpy_test(robot, res: float) -> None:
    """Batched and per pose, kernel on and off: the reference's answers, both kinds seen."""
    rng = np.random.default_rng(int(res * 1000) + 1)
    arm = ArmGround.of(robot, featured_map(rng, res, 0.0), 0.0524)
    q = random_postures(robot, rng, 400)
    kept = KeptPieces(arm.base, q)
    seen = [0, 0, 0]  # clear, not clear, doubtful pieces (the lattice test's)
    for _ in range(3):
        terrain = featured_map(rng, res, unknown=0.3)
        poses = {
            k: rested(tilted_pose(rng, rng.uniform(-0.6, 0.6, 2), 0.1), terrain) for k in range(4)
        }
        ks = [0, 1, 2, 3] * 25
        rows = rng.choice(len(q), len(ks), replace=False)
        fresh = MapGround(arm, terrain, poses, len(q))
        want, (of, at, peaks) = reference_node_clear(fresh, ks, kept(rows), GROUND)
        seen[0] += int(want.sum())
        seen[1] += int((~want).sum())
        seen[2] += len(peaks)
        for kernel in (True, False):
            a = arm._replace(kernel=kernel)
            got = MapGround(a, terrain, poses, len(q)).node_clear(ks, rows, kept, GROUND)
            np.testing.assert_array_equal(got, want)
            one = [
                MapGround(a, terrain, poses, len(q)).node_clear([k], rows[i : i + 1], kept, GROUND)
                for i, k in enumerate(ks)
            ]
            np.testing.assert_array_equal(np.concatenate(one), want)
            g = MapGround(a, terrain, poses, len(q))
            for k in range(4):  # each piece's peak, bit for bit
                np.testing.assert_array_equal(
                    g.pose(k)._peak_at(at[of == k, 0], at[of == k, 1]), peaks[of == k]
                )
    assert min(seen) > 20, seen  # both answers occur, the lattice test runs


def test_the_online_pose_measures_the_offline_planners_heights(robot) -> None:
    """A fully known map: the live map's heights equal the planner's, C and NumPy."""
    rng = np.random.default_rng(5)
    terrain = featured_map(rng, 0.05, unknown=0.0)
    q = random_postures(robot, rng, 500)
    poses = {k: rested(tilted_pose(rng, rng.uniform(-0.5, 0.5, 2), 0.1), terrain) for k in range(4)}
    T = np.stack([poses[k] for k in range(4)])
    arm = ArmGround.of(robot, terrain, 0.0524)
    body = arm.base.body(q)
    online = MapGround(arm, terrain, poses, len(q)).under([0, 1, 2, 3])
    low = 0
    for backend in ("c", "numpy"):
        offline = GroundUnderArm(robot, terrain, T[:, :3, 3], T, 0.0524, backend=backend)
        for k in range(4):
            h_off = offline.poses[k].heights(body, np.inf)
            h_on = online.poses[k].heights(body, np.inf)
            np.testing.assert_array_equal(h_on, h_off)
            low += int((h_off < GROUND).sum())
    assert 50 < low < 2 * 4 * len(q) - 50  # the ground rules some postures out, not all
