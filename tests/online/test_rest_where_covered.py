"""The online loop's one batched rest equals resting each pose alone, off-map poses left out;
the state's μ from that batch and the step target's placement are the library's, bitwise."""

from __future__ import annotations

import numpy as np

from mmstab.core.files import MmstabError
from mmstab.runs.online.follow import place_two
from mmstab.runs.online.horizon import rest_where_covered, rested_rows
from mmstab.stability.support import loaded_support, state_load, support_on_rests
from mmstab.terrain.base import GRAVITY_G, place_local
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


def test_states_rested_in_the_maps_batch_give_loaded_mu_to_the_bit(robot):
    """Follower.update rests the state now in the map's one batch (under its own CoM, beside
    poses under the stowed arm's); support_on_rests on its row is loaded_mu alone, bitwise."""
    rng = np.random.default_rng(5)
    x, y = np.meshgrid(np.arange(120) * 0.05, np.arange(100) * 0.05)
    z = 0.08 * np.sin(1.3 * x) * np.cos(0.9 * y) + rng.normal(0.0, 0.01, x.shape)
    z[60:70, 20:40] = np.nan
    terrain = HeightmapTerrain(Heightmap.build(z, 0.05, [0.0, 0.0])).with_robot(robot)
    n = 30
    poses = np.column_stack(
        [rng.uniform(0.5, 5.5, n), rng.uniform(0.5, 4.5, n), rng.uniform(-np.pi, np.pi, n)]
    )
    q = np.array(robot.stowed) + rng.uniform(-1.0, 1.0, (n, len(robot.stowed)))
    others = poses[rng.permutation(n)] + [0.1, -0.1, 0.2]  # the horizon's, under the stowed arm
    mass, com, wrench = state_load(robot, robot.arm_com(q), q, n)
    batch = terrain.rest(
        np.vstack([others, poses]), strict=False,
        com_body=np.vstack([np.broadcast_to(terrain.com_body, (n, 3)), com]),
    )  # fmt: skip
    got = support_on_rests(terrain, batch, np.arange(n, 2 * n), mass, com, wrench)
    alone = [loaded_support(robot, terrain, p, robot.arm_com(a), a[None], strict=False) for p, a in
             zip(poses, q, strict=True)]  # fmt: skip
    for field in ("mu", "gravity_body", "line", "tips_over", "high_centred", "converged"):
        want = np.concatenate([getattr(a, field) for a in alone])
        np.testing.assert_array_equal(getattr(got, field), want, err_msg=field)
    mu = got.mu[np.isfinite(got.mu)]
    assert len(mu) >= n // 2 and np.ptp(mu) > 50.0  # states of many kinds, most on the map
    rested = rested_rows(batch, n)  # the first rows: as rested without the states
    np.testing.assert_array_equal(rested.G_T_B, rest_where_covered(terrain, others).G_T_B)


def test_the_step_targets_placement_is_place_locals_to_the_bit() -> None:
    rng = np.random.default_rng(11)
    for _ in range(2000):
        pose = rng.normal(size=3) * [5.0, 5.0, 3.0]
        ground = rng.normal(size=3) * [1.0, 0.5, 0.5]
        points = rng.normal(size=(2, 3))
        want = place_local(np.repeat(pose[None], 2, 0), np.repeat(ground[None], 2, 0), points)
        np.testing.assert_array_equal(place_two(pose, ground, points), want.points)
    # and by hand: a quarter turn, flat: the point (1, 0, 0) lands at (x, y + 1, z)
    np.testing.assert_allclose(
        place_two(np.array([1.0, 2.0, np.pi / 2]), np.array([0.3, 0.0, 0.0]), np.eye(3)[:2]),
        [[1.0, 3.0, 0.3], [0.0, 2.0, 0.3]], atol=1e-15,
    )  # fmt: skip


def test_the_steps_support_is_the_states_own_support_alone(robot):
    """Follower.update takes the state's support (body pose, polygon, flags) from its row of
    the map's batch: the same as the terrain's support of that state alone, bitwise."""
    from mmstab.terrain.heightmap_terrain import rest_support

    rng = np.random.default_rng(7)
    x, y = np.meshgrid(np.arange(120) * 0.05, np.arange(100) * 0.05)
    z = 0.08 * np.sin(1.3 * x) * np.cos(0.9 * y) + rng.normal(0.0, 0.01, x.shape)
    terrain = HeightmapTerrain(Heightmap.build(z, 0.05, [0.0, 0.0])).with_robot(robot)
    n = 20
    poses = np.column_stack(
        [rng.uniform(0.8, 5.2, n), rng.uniform(0.8, 4.2, n), rng.uniform(-np.pi, np.pi, n)]
    )
    q = np.array(robot.stowed) + rng.uniform(-1.0, 1.0, (n, len(robot.stowed)))
    com = np.asarray(robot.overall_com(robot.arm_com(q)))
    others = poses[rng.permutation(n)] + [0.1, -0.1, 0.2]
    batch = terrain.rest(
        np.vstack([others, poses]), strict=False,
        com_body=np.vstack([np.broadcast_to(terrain.com_body, (n, 3)), com]),
    )  # fmt: skip
    moved = 0
    for i in range(n):
        got = rest_support(batch, n + i, terrain.candidates.points)
        alone = terrain.with_robot(robot, arm_q=q[i]).support(robot, poses[i])
        np.testing.assert_array_equal(got.G_T_B, alone.G_T_B)
        np.testing.assert_array_equal(got.polygon_G, alone.polygon_G)
        assert got.flags == alone.flags
        by_com = terrain.support(robot, poses[i], com_body=com[i])
        np.testing.assert_array_equal(by_com.polygon_G, alone.polygon_G)
        moved += not np.allclose(terrain.support(robot, poses[i]).G_T_B, alone.G_T_B, atol=1e-6)
    assert moved > 0  # the arm moved some rests: the stowed arm's support is another
