"""The ground's peaks under the arm on a live map: the C kernel against the NumPy tiles.

:class:`mmstab.planner.ground.map_lattice.LatticePeaks` (C) computes a pose's lattice peaks only
where pieces ask (blocks, rows and peaks kept); the NumPy path (:class:`MapTiles`,
:class:`FilledTiles`, :meth:`PoseGround._build`) samples whole tiles. Both must give the
same values, bit for bit, on maps with unknown cells, off the window, at tilted rests, and
the arm's measures on a sequence of maps (each changing some cells, states kept between
them) must be the same with the kernel and without.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_postures

from mmstab.planner.ground.kernel import kernel_available
from mmstab.planner.ground.map_ground import ArmGround, MapGround
from mmstab.planner.ground.map_lattice import FilledTiles, LatticePeaks, MapPoseGround, MapTiles
from mmstab.planner.ground.under_arm import LATTICE, SLACK
from mmstab.terrain.heightmap import Heightmap
from mmstab.terrain.heightmap_terrain import HeightmapTerrain

pytestmark = pytest.mark.skipif(not kernel_available(), reason="no C compiler")


def random_map(
    rng: np.random.Generator, res: float, unknown: float, rough: float = 0.05
) -> HeightmapTerrain:
    """A ``rough`` [m] 4 m map (its origin off the lattice), ``unknown`` of its cells NaN."""
    n = int(round(4.0 / res)) + 1
    z = rough * rng.standard_normal((n, n)) + 0.2 * rng.random() * np.linspace(0, 1, n)[:, None]
    z[rng.random(z.shape) < unknown] = np.nan
    origin = np.array([-2.0, -2.0]) + rng.uniform(-0.03, 0.03, 2)
    return HeightmapTerrain(Heightmap.build(z, res, origin, "random"))


def tilted_pose(rng: np.random.Generator, xy: np.ndarray, tilt: float = 0.3) -> np.ndarray:
    """A body pose in M (4, 4): yaw at random, roll and pitch up to ``tilt`` [rad], at ``xy``."""
    r, p, y = rng.uniform(-tilt, tilt), rng.uniform(-tilt, tilt), rng.uniform(-np.pi, np.pi)
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    T = np.eye(4)
    T[:3, :3] = np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )
    T[:2, 3], T[2, 3] = xy, rng.uniform(-0.1, 0.1)
    return T


def rested(T: np.ndarray, terrain: HeightmapTerrain) -> np.ndarray:
    """``T`` raised to the highest known ground within 0.3 m of its origin (a rough rest)."""
    hm = terrain.heightmap
    ij = np.round((T[:2, 3] - hm.origin) / hm.resolution).astype(int)
    around = hm.elevation[ij[1] - 6 : ij[1] + 7, ij[0] - 6 : ij[0] + 7]
    T = T.copy()
    T[2, 3] = float(np.nanmax(around))
    return T


@pytest.mark.parametrize("res", [0.05, 0.02, 0.03])
def test_kernel_peaks_equal_the_numpy_tiles(res: float) -> None:
    """Every asked peak, bit for bit: unknown cells, the window's edge, tilts, fills."""
    rng = np.random.default_rng(int(res * 1000))
    cells, half, radius = 12, 6, 1.2
    for _ in range(6):
        terrain = random_map(rng, res, unknown=0.1)
        # the reach near the window's edge half the time: samples off the map too
        T = tilted_pose(rng, rng.uniform(-1.8, 1.8, 2))
        centre, fill = T[:3, 3] + np.array([0.0, 0.0, 0.3]), float(rng.uniform(0.0, 0.2))
        numpy_path = MapPoseGround(FilledTiles(MapTiles(terrain), T, fill), T, cells)  # type: ignore[arg-type]
        numpy_path.top = fill
        kernel = LatticePeaks(terrain.heightmap, T, fill, half, centre, radius)
        for _ in range(3):  # asked in batches: the kernel's kept values reused
            xy = centre[:2] + radius * rng.uniform(-0.7, 0.7, (500, 2))
            i, j = (np.floor(xy / LATTICE).astype(np.intp) for xy in (xy[:, 0], xy[:, 1]))
            got = kernel(i, j)
            assert got is not None
            np.testing.assert_array_equal(got, numpy_path._peak_at(i, j))
        assert np.isinf(terrain.heightmap.elevation).sum() == 0  # NaN, not inf, is unknown


def test_a_sample_off_the_kernels_blocks_takes_the_numpy_path() -> None:
    """A piece beyond the radius it was built for: no answer, the tiles answer instead."""
    rng = np.random.default_rng(3)
    terrain = random_map(rng, 0.05, unknown=0.0)
    T = tilted_pose(rng, np.zeros(2))
    ground = MapPoseGround(FilledTiles(MapTiles(terrain), T, 0.0), T, 12)  # type: ignore[arg-type]
    ground.peaks = LatticePeaks(terrain.heightmap, T, 0.0, 6, T[:3, 3], 0.3)
    far = np.array([int(1.0 / LATTICE)]), np.array([0])
    assert ground.peaks(*far) is None
    reference = MapPoseGround(FilledTiles(MapTiles(terrain), T, 0.0), T, 12)  # type: ignore[arg-type]
    np.testing.assert_array_equal(ground._peak_at(*far), reference._peak_at(*far))


def test_the_arms_measures_on_a_map_sequence_are_the_same_with_and_without_the_kernel(
    robot, rng
) -> None:
    """Heights and clear/low answers of random postures, 8 maps, cells changing between.

    Each map changes a patch of cells (some to unknown) and moves one pose's rest: the
    other poses' states are kept from the map before (with their kept peaks), as online.
    """
    terrain = random_map(rng, 0.05, unknown=0.05, rough=0.01)
    arm = ArmGround.of(robot, terrain, 0.0)
    assert arm.kernel
    q = random_postures(robot, rng, 300)
    body = arm.base.body(q)
    poses = {
        k: rested(tilted_pose(rng, rng.uniform(-0.6, 0.6, 2), 0.05), terrain) for k in range(3)
    }
    ground = {True: None, False: None}
    z = terrain.heightmap.elevation.copy()
    seen = 0
    for step in range(8):
        if step:  # a patch changes; one pose rests anew
            r0, c0 = rng.integers(0, z.shape[0] - 10, 2)
            z[r0 : r0 + 10, c0 : c0 + 10] += rng.uniform(-0.05, 0.05)
            z[r0 : r0 + 2, c0 : c0 + 2] = np.nan
        hm = Heightmap.build(z.copy(), 0.05, terrain.heightmap.origin, "step")
        if step:
            at = rng.uniform(-0.6, 0.6, 2)
            poses[int(rng.integers(3))] = rested(tilted_pose(rng, at, 0.05), HeightmapTerrain(hm))
        answers = {}
        for on in (True, False):
            g = MapGround(arm._replace(kernel=on), HeightmapTerrain(hm), poses, 1, ground[on])
            ground[on] = g
            under = g.under([0, 1, 2])
            answers[on] = [
                (p.heights(body, np.inf), p.heights(body, 0.05) >= 0.05 - SLACK)
                for p in under.poses
            ]
            seen += sum(int(p.peaks is not None) for p in under.poses) if on else 0
        for (h_on, c_on), (h_off, c_off) in zip(answers[True], answers[False], strict=True):
            np.testing.assert_array_equal(h_on, h_off)
            np.testing.assert_array_equal(c_on, c_off)
            assert 0 < c_on.sum() < len(c_on)  # both answers occur: the test can tell
    assert seen == 24
