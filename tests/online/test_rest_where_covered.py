"""The online loop's one batched rest equals resting each pose alone, off-map poses left out."""

from __future__ import annotations

import numpy as np

from mmstab.core.files import MmstabError
from mmstab.runs.online.horizon import rest_where_covered
from mmstab.terrain.base import GRAVITY_G
from mmstab.terrain.heightmap import Heightmap
from mmstab.terrain.heightmap_terrain import HeightmapTerrain


def test_one_batch_equals_each_pose_alone_and_leaves_out_the_poses_off_the_map(robot):
    rng = np.random.default_rng(3)
    x, y = np.meshgrid(np.arange(120) * 0.05, np.arange(100) * 0.05)
    z = 0.08 * np.sin(1.3 * x) * np.cos(0.9 * y) + rng.normal(0.0, 0.005, x.shape)
    z[60:70, 20:40] = np.nan  # unknown cells
    terrain = HeightmapTerrain(Heightmap.build(z, 0.05, [0.0, 0.0])).with_robot(robot)
    poses = np.column_stack(
        [rng.uniform(-0.5, 6.5, 40), rng.uniform(-0.5, 5.5, 40), rng.uniform(-np.pi, np.pi, 40)]
    )
    got = rest_where_covered(terrain, poses)
    for i, pose in enumerate(poses):
        try:
            alone = terrain.rest(pose[None])
        except MmstabError:  # off the map or on unknown cells: not covered
            assert not got.covered[i]
            assert np.isnan(got.G_T_B[i]).all() and np.isnan(got.ground[i]).all()
            continue
        assert got.covered[i]
        np.testing.assert_array_equal(got.G_T_B[i], alone.G_T_B[0])
        np.testing.assert_array_equal(got.ground[i], [alone.z[0], alone.roll[0], alone.pitch[0]])
        g_alone = np.einsum("nji,j->ni", alone.G_T_B[:, :3, :3], GRAVITY_G)[0]
        np.testing.assert_array_equal(got.gravity_body[i], g_alone)
    assert 5 < got.covered.sum() < len(poses) - 5  # both kinds occur
