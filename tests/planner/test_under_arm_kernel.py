"""The ground under the arm's C kernel against its NumPy twin, on seeded random maps.

The kernel (mmstab/planner/ground/kernel.c) follows
:mod:`mmstab.planner.ground.under_arm`'s NumPy functions operation for operation: the
pieces' lowest points (over the attitude margin's tilts) come out bit for bit, their
centres to 1 ulp (NumPy's matrix product may fuse multiply-adds), the heights above the
ground bit for bit from the same pieces, and a route's plan is the same posture for
posture and move for move.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
from test_random_routes import COARSE, pair_problem

MARGINS = (0.0, 0.0524)


@pytest.fixture(scope="module")
def pairs(tmp_path_factory):
    from mmstab.core.problem import load_problem

    folder = tmp_path_factory.mktemp("pairs")
    return [load_problem(pair_problem(k, folder, COARSE)) for k in (0, 1, 2)]


def _route_poses(problem, spacing=0.5):
    route = problem.route
    return route.route.sample(np.arange(0.0, route.length, spacing)).pose


@pytest.mark.parametrize("margin", MARGINS)
def test_pieces_in_body_c_equals_numpy(robot, margin):
    from mmstab.planner.ground.under_arm import arm_pieces, pieces_in_body

    pieces = arm_pieces(robot)
    q = np.random.default_rng(7).uniform(robot.joint_lower, robot.joint_upper, (3000, 4))
    twin = pieces_in_body(robot, pieces, q, margin, "numpy")
    kernel = pieces_in_body(robot, pieces, q, margin, "c")
    assert np.array_equal(kernel.low, twin.low)  # bit for bit
    assert np.allclose(kernel.centre, twin.centre, rtol=0.0, atol=1e-15)
    assert np.ptp(twin.low) > 0.5  # the postures spread the arm: a real comparison


@pytest.mark.parametrize("margin", MARGINS)
def test_pieces_of_postures_sharing_their_first_joints(robot, margin):
    """Postures on a lattice, sorted: the kernel reuses a link's pieces where its frame repeats.

    The reused values are those computed: bit for bit the NumPy twin's, sorted or not.
    """
    from mmstab.planner.ground.under_arm import arm_pieces, pieces_in_body

    pieces = arm_pieces(robot)
    rng = np.random.default_rng(8)
    lo, hi = robot.joint_lower, robot.joint_upper
    axes = [np.linspace(lo[j], hi[j], n) for j, n in enumerate((6, 5, 4))]
    q = np.stack([rng.choice(a, 3000) for a in axes] + [rng.uniform(lo[3], hi[3], 3000)], 1)
    q[::7, 3] = q[1::7, 3][: len(q[::7])]  # some whole postures repeated too
    q = q[np.lexsort(q.T[::-1])]
    twin = pieces_in_body(robot, pieces, q, margin, "numpy")
    kernel = pieces_in_body(robot, pieces, q, margin, "c")
    assert np.array_equal(kernel.low, twin.low)
    assert np.allclose(kernel.centre, twin.centre, rtol=0.0, atol=1e-15)
    shuffled = rng.permutation(len(q))  # no repeats next to each other: each computed
    alone = pieces_in_body(robot, pieces, q[shuffled], margin, "c")
    assert np.array_equal(alone.low, kernel.low[shuffled])
    assert np.array_equal(alone.centre, kernel.centre[shuffled])
    assert (np.diff(q[:, 0]) == 0).mean() > 0.9  # the first joint repeats: reuse is tested


@pytest.mark.parametrize("margin", MARGINS)
def test_heights_c_equal_numpy_on_random_maps(robot, pairs, margin):
    from mmstab.planner.ground.under_arm import GroundUnderArm

    rng = np.random.default_rng(11)
    q = rng.uniform(robot.joint_lower, robot.joint_upper, (1500, 4))
    low_seen = 0
    for problem in pairs:
        poses = _route_poses(problem)
        twin = GroundUnderArm(robot, problem.terrain, poses, margin=margin, backend="numpy")
        kernel = GroundUnderArm(robot, problem.terrain, poses, margin=margin, backend="c")
        body = twin.body(q)
        for k in range(len(poses)):
            for above, plane in ((np.inf, False), (0.05, False), (0.05, True)):
                h_twin = twin.poses[k].heights(body, above, plane)
                h_kernel = kernel.poses[k].heights(body, above, plane)
                assert np.array_equal(h_kernel, h_twin), (k, above, plane)
            # and the kernel's own pieces decide the same clearances
            assert np.array_equal(kernel.clear(k, q, 0.05), twin.clear(k, q, 0.05, body))
            low_seen += int((~twin.clear(k, q, 0.05, body)).sum())
        ks = (0, 1)
        path = q[:6]
        a, b = twin.sweep_clear(ks, path, np.full(4, 0.8), 0.05)
        c, d = kernel.sweep_clear(ks, path, np.full(4, 0.8), 0.05)
        assert np.array_equal(a, c) and np.array_equal(b, d)
    assert low_seen > 100  # the ground rules some postures out: both paths say which


@pytest.mark.parametrize("margin", MARGINS)
def test_heights_of_kept_rows_equal_those_of_their_pieces(robot, pairs, margin):
    """The kernel reading the kept pieces by row (no copy) gives the copied pieces' heights."""
    from mmstab.planner.ground.under_arm import GroundUnderArm, KeptPieces

    rng = np.random.default_rng(12)
    q = rng.uniform(robot.joint_lower, robot.joint_upper, (2000, 4))
    problem = pairs[1]
    poses = _route_poses(problem)
    kernel = GroundUnderArm(robot, problem.terrain, poses, margin=margin, backend="c")
    twin = GroundUnderArm(robot, problem.terrain, poses, margin=margin, backend="numpy")
    kept = KeptPieces(kernel, q)
    kept.add(rng.permutation(2000)[:700])  # kept out of order, then more on demand
    low_seen = 0
    for k in range(len(poses)):
        rows = rng.integers(0, 2000, 400)  # repeats, any order
        view, copied = kept.view(rows), kept(rows)
        assert np.array_equal(copied.low, kernel.body(q[rows]).low)
        for above, plane in ((np.inf, False), (0.05, False), (0.05, True)):
            h = kernel.poses[k].heights(copied, above, plane)
            assert np.array_equal(kernel.poses[k].heights(view, above, plane), h)
            assert np.array_equal(twin.poses[k].heights(view, above, plane), h)  # NumPy's
        clear = kernel.clear(k, q[rows], 0.05, view)
        assert np.array_equal(clear, twin.clear(k, q[rows], 0.05, copied))
        low_seen += int((~clear).sum())
    assert low_seen > 50


def test_a_route_plans_the_same_with_the_kernel_and_its_twin(pairs, monkeypatch):
    """The plan's postures and moves identical, the kernel's against the NumPy twin's."""
    import mmstab.planner.searches.roadmap as search
    from mmstab import app
    from mmstab.planner.ground.under_arm import GroundUnderArm

    for problem in pairs[:2]:
        assert problem.section("planner")["attitude_margin"]  # every default check on
        ws = app.workspace(problem, progress=False)
        plans = {}
        for backend in ("numpy", "c"):
            monkeypatch.setattr(
                search, "GroundUnderArm", functools.partial(GroundUnderArm, backend=backend)
            )
            plans[backend] = app.plan(problem, ws=ws)
        twin, kernel = plans["numpy"], plans["c"]
        assert np.array_equal(kernel.postures, twin.postures)
        assert len(kernel.moves) == len(twin.moves) == len(twin.s)
        assert all(np.array_equal(a, b) for a, b in zip(kernel.moves, twin.moves, strict=True))


class _Holed:
    """A terrain with a NaN sample (its interface for the tiles only)."""

    def __init__(self, terrain):
        self.terrain, self.bounds = terrain, terrain.bounds

    def G_T_M(self):
        return self.terrain.G_T_M()

    def surface_G(self, x, y):
        p = self.terrain.surface_G(x, y)
        p[..., 2] = np.where(
            (np.abs(x - 0.30) < 0.004) & (np.abs(y - 0.10) < 0.004), np.nan, p[..., 2]
        )
        return p


def test_peak_map_c_equals_numpy_on_random_maps(pairs):
    """The pose's peak map by the kernel (tiles unstacked) is NumPy's and SciPy's, bit for bit."""
    from mmstab.planner.ground.under_arm import GroundTiles, PoseGround

    rng = np.random.default_rng(5)
    spread = 0.0
    for problem in pairs:
        tiles = GroundTiles(problem.terrain)
        poses = _route_poses(problem, 0.8)
        for T in problem.terrain.M_T_B(poses):
            tilt = np.eye(4)  # the resting pose, and one tilted more: a steeper plane
            a, b = rng.uniform(-0.3, 0.3, 2)
            tilt[:3, :3] = [[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]]
            tilt[:3, :3] = tilt[:3, :3] @ [
                [1, 0, 0],
                [0, np.cos(b), -np.sin(b)],
                [0, np.sin(b), np.cos(b)],
            ]
            for M_T_B in (T, T @ tilt):
                for cells in (7, 12):
                    twin = PoseGround(tiles, M_T_B, cells, backend="numpy")
                    kernel = PoseGround(tiles, M_T_B, cells, backend="c")
                    c = np.floor(M_T_B[:2, 3] / 0.01 / 64).astype(int)
                    for box in (
                        (c[0] - 1, c[0] + 1, c[1] - 2, c[1] + 1),
                        (c[0] - 3, c[0], c[1], c[1]),
                    ):
                        twin._build(box)
                        kernel._build(box)
                        assert kernel.peak.shape == twin.peak.shape
                        assert np.array_equal(kernel.peak, twin.peak)
                        assert kernel.top == twin.top
                        spread = max(spread, float(np.ptp(twin.peak)))
    assert spread > 0.02  # the maps' ground varies: a real comparison


def test_peak_map_with_a_nan_takes_numpys_path(pairs):
    """A tile with a NaN sample: the kernel is not used, the map is NumPy's (NaN kept)."""
    from mmstab.planner.ground.under_arm import GroundTiles, PoseGround

    terrain = _Holed(pairs[0].terrain)
    T = pairs[0].terrain.M_T_B(np.array([[0.3, 0.1, 0.2]]))[0]
    maps = []
    for backend in ("numpy", "c"):
        ground = PoseGround(GroundTiles(terrain), T, 7, backend=backend)
        ground._build((-1, 1, -1, 1))
        assert ground.tiles.nonfinite == {(0, 0)}
        maps.append(ground)
    assert np.isnan(maps[0].top) and np.isnan(maps[1].top)
    assert np.array_equal(maps[0].peak, maps[1].peak, equal_nan=True)
    assert not maps[1].tiles.finite((-1, 1, -1, 1)) and maps[1].tiles.finite((1, 2, 1, 2))


def test_tiles_sampled_together_equal_one_by_one(pairs):
    """A box's new tiles in one call of the terrain: each tile's values its own call's."""
    from mmstab.planner.ground.under_arm import TILE, GroundTiles

    for problem in pairs:
        together = GroundTiles(problem.terrain)
        b = problem.terrain.bounds
        edge = int(np.floor(b[1] / 0.01 / TILE))  # a box across the map's edge: clipped
        for box in ((-2, 1, -1, 2), (edge - 1, edge + 1, 0, 1)):
            tiles = together.mosaic(box)
            for tj, row in zip(range(box[2], box[3] + 1), tiles, strict=True):
                for ti, tile in zip(range(box[0], box[1] + 1), row, strict=True):
                    assert tile.shape == (TILE, TILE) and tile.flags.c_contiguous
                    assert np.array_equal(tile, _tile_alone(together, ti, tj))
        assert np.ptp(together.z_M((-2, 1, -1, 2))) > 0.01  # the ground varies


def _tile_alone(tiles, ti, tj):
    """Tile (ti, tj) as before the batch: numpy.meshgrid, a terrain call of its own."""
    from mmstab.planner.ground.under_arm import LATTICE, TILE

    x = (ti * TILE + np.arange(TILE)) * LATTICE
    y = (tj * TILE + np.arange(TILE)) * LATTICE
    X, Y = np.meshgrid(x, y)
    b = tiles.terrain.bounds
    if b is not None:
        X, Y = np.clip(X, b[0], b[1]), np.clip(Y, b[2], b[3])
    return tiles.terrain.surface_G(X, Y) @ tiles.M_T_G[2, :3] + tiles.M_T_G[2, 3]


def test_a_heightmaps_tiles_from_its_grid_heights_equal_its_points(robot):
    """GroundTiles asks a ground that gives heights on a grid (a heightmap) for a tile's rows
    at once: the same tiles as sampling its points (surface_G, written in M)."""
    from mmstab.planner.ground.under_arm import GroundTiles
    from mmstab.terrain.base import GridHeights
    from mmstab.terrain.generators import Grid, bumps
    from mmstab.terrain.heightmap_terrain import HeightmapTerrain

    terrain = HeightmapTerrain(bumps(Grid.of_size((4.0, 3.0), 0.05), 0.08, 0.6,
                                     np.random.default_rng(5))).with_robot(robot)  # fmt: skip
    assert isinstance(terrain, GridHeights)

    class PointsOnly:  # the same ground without the grid method
        def __init__(self, t):
            self.t, self.bounds = t, t.bounds

        def G_T_M(self):
            return self.t.G_T_M()

        def surface_G(self, x, y):
            return self.t.surface_G(x, y)

    keys = [(i, j) for i in range(-4, 4) for j in range(-3, 3)]  # past the map's edges too
    fast, slow = GroundTiles(terrain), GroundTiles(PointsOnly(terrain))  # type: ignore[arg-type]
    fast._sample(keys)
    slow._sample(keys)
    for key in keys:
        np.testing.assert_array_equal(fast.tiles[key], slow.tiles[key])
    assert len(set(np.round(fast.tiles[(0, 0)].ravel(), 6))) > 100  # the bumps, not a plane
