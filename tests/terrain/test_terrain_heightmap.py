"""Heightmaps: layout, bilinear height/normal, loaders (npz, GeoTIFF, mesh), generators."""

from __future__ import annotations

import numpy as np
import pytest

from mmstab.core.files import ConfigError
from mmstab.terrain.generators import Grid, bumps, ditch, fractal_elevation, generate, kerb, plane
from mmstab.terrain.heightmap import Heightmap, OffMapError
from mmstab.terrain.io import load_heightmap, rasterise, save_npz, write_geotiff


def test_layout_cell_centres_and_bilinear_on_a_plane(rng):
    # grid_map layout: cell [iy, ix] centre = origin + res (ix, iy); row = y
    e = np.arange(12.0).reshape(3, 4)  # e[iy, ix] = 4 iy + ix
    hm = Heightmap.build(e, 0.5, [1.0, -2.0])
    assert hm.height([1.0 + 0.5 * 3, -2.0 + 0.5 * 2]) == pytest.approx(e[2, 3])
    assert hm.height([1.0 + 0.5 * 1, -2.0 + 0.5 * 0]) == pytest.approx(e[0, 1])
    # bilinear reproduces any plane exactly, with its slope and normal
    a, b, c = rng.normal(size=3)
    g = Grid(nx=9, ny=7, resolution=0.3, center=(0.4, -0.2))
    x, y = g.xy()
    hm = g.heightmap(a * x + b * y + c, "plane")
    lo, hi = np.array([hm.bounds[0], hm.bounds[2]]), np.array([hm.bounds[1], hm.bounds[3]])
    pts = rng.uniform(lo, hi, size=(50, 2))
    np.testing.assert_allclose(hm.height(pts), a * pts[:, 0] + b * pts[:, 1] + c, atol=1e-12)
    n = np.array([-a, -b, 1.0]) / np.linalg.norm([-a, -b, 1.0])
    np.testing.assert_allclose(hm.normal(pts), np.broadcast_to(n, (50, 3)), atol=1e-12)


def test_off_map_and_unknown_cells_raise_naming_the_map():
    e = np.zeros((4, 4))
    e[2, 2] = np.nan
    hm = Heightmap.build(e, 1.0, [0.0, 0.0], "m.npz")
    with pytest.raises(OffMapError, match=r"m.npz: point \(3.500, 0.000\) m is off the map"):
        hm.height([[0.5, 0.5], [3.5, 0.0]])
    with pytest.raises(OffMapError, match="unknown"):
        hm.height([1.5, 1.5])  # bilinear needs the NaN cell [2, 2]
    s = hm.sample([[0.5, 0.5], [1.5, 1.5], [-1.0, 0.0]])
    assert s.valid.tolist() == [True, False, False]
    assert np.isnan(s.height[1:]).all() and s.height[0] == 0.0


def test_quarter_turn_and_translation_move_heights_with_the_map(rng):
    hm = generate(
        {
            "kind": "bumps",
            "seed": 3,
            "size": [2.0, 1.4],
            "resolution": 0.1,
            "amplitude": 0.1,
            "wavelength": 0.7,
        }
    )
    p = rng.uniform([-0.9, -0.6], [0.9, 0.6], size=(40, 2))
    turned = hm.rotated90()
    np.testing.assert_allclose(turned.height(np.c_[-p[:, 1], p[:, 0]]), hm.height(p), atol=1e-12)
    np.testing.assert_allclose(hm.rotated90(4).elevation, hm.elevation)
    moved = hm.translated([0.37, -1.1], dz=0.2)
    np.testing.assert_allclose(moved.height(p + [0.37, -1.1]), hm.height(p) + 0.2, atol=1e-12)


# ----------------------------------------------------------------------------------- files
def test_npz_round_trip(tmp_path, rng):
    hm = Heightmap.build(rng.normal(size=(5, 6)), 0.25, [3.0, -1.0])
    path = save_npz(tmp_path / "map.npz", hm)
    with np.load(path) as d:
        assert sorted(d.files) == ["elevation", "origin", "resolution"]
    back = load_heightmap(path)
    np.testing.assert_array_equal(back.elevation, hm.elevation)
    assert back.resolution == 0.25 and back.origin.tolist() == [3.0, -1.0]


def test_geotiff_round_trip_and_hand_made_tags(tmp_path, rng):
    import tifffile

    e = rng.normal(size=(4, 5)).astype(np.float32).astype(float)
    e[0, 0] = np.nan
    hm = Heightmap.build(e, 0.5, [10.0, 20.0])
    back = load_heightmap(write_geotiff(tmp_path / "dem.tif", hm))
    np.testing.assert_array_equal(back.elevation, hm.elevation)  # NaN via GDAL_NODATA
    np.testing.assert_allclose(back.origin, [10.0, 20.0])
    assert back.resolution == 0.5
    # written by hand: 2 x 3 raster, row 0 = north; pixel-is-point tie at pixel (0, 0)
    raster = np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]], dtype=np.float32)
    keys = (1, 1, 0, 1, 1025, 0, 1, 2)  # GTRasterTypeGeoKey = PixelIsPoint
    tags = [
        (33550, "d", 3, (2.0, 2.0, 0.0), True),
        (33922, "d", 6, (0.0, 0.0, 0.0, 100.0, 50.0, 0.0), True),
        (34735, "H", len(keys), keys, True),
    ]
    tifffile.imwrite(tmp_path / "point.tif", raster, extratags=tags)
    m = load_heightmap(tmp_path / "point.tif")
    # pixel (col 0, row 1) is at x = 100, y = 50 - 2 = 48: our cell [0, 0]
    assert m.origin.tolist() == [100.0, 48.0]
    assert m.height([100.0, 48.0]) == 4.0 and m.height([104.0, 50.0]) == 3.0
    assert m.height([101.0, 49.0]) == pytest.approx((4 + 5 + 1 + 2) / 4)


def test_mesh_is_rasterised_to_its_top_surface(tmp_path):
    import trimesh

    # a tilted square (2 triangles) z = 0.2 x + 0.1 y, and a lower copy that must not show
    v = np.array([[0, 0, 0], [2, 0, 0.4], [2, 1, 0.5], [0, 1, 0.1]], dtype=float)
    low = v - [0, 0, 1.0]
    faces = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
    mesh = trimesh.Trimesh(np.vstack([v, low]), faces, process=False)
    mesh.export(tmp_path / "slab.stl")
    hm = load_heightmap(tmp_path / "slab.stl", resolution=0.1)
    assert hm.shape == (11, 21)
    x, y = np.meshgrid(hm.x, hm.y)
    np.testing.assert_allclose(hm.elevation, 0.2 * x + 0.1 * y, atol=1e-6)
    direct = rasterise(np.vstack([v, low]), faces, 0.25)
    assert np.isfinite(direct.elevation).all()


@pytest.mark.parametrize(
    ("make", "field"),
    [
        (lambda p: np.savez(p, elevation=np.zeros((3, 3)), resolution=0.1), "origin"),
        (
            lambda p: np.savez(p, elevation=np.zeros((3, 3)), resolution=0.1, origin=[0, 0], x=1),
            "x",
        ),
        (
            lambda p: np.savez(p, elevation=np.zeros((3, 3), int), resolution=0.1, origin=[0, 0]),
            "elevation",
        ),
        (lambda p: np.savez(p, elevation=np.zeros(9), resolution=0.1, origin=[0, 0]), "elevation"),
        (
            lambda p: np.savez(p, elevation=np.full((3, 3), np.nan), resolution=0.1, origin=[0, 0]),
            "elevation",
        ),
        (
            lambda p: np.savez(p, elevation=np.zeros((3, 3)), resolution=0.0, origin=[0, 0]),
            "resolution",
        ),
        (
            lambda p: np.savez(p, elevation=np.zeros((3, 3)), resolution=np.inf, origin=[0, 0]),
            "resolution",
        ),
        (
            lambda p: np.savez(p, elevation=np.zeros((3, 3)), resolution=0.1, origin=[0, 0, 0]),
            "origin",
        ),
        (lambda p: p.write_bytes(b"not a zip file"), ""),
    ],
)
def test_bad_npz_names_file_and_field(tmp_path, make, field):
    path = tmp_path / "bad.npz"
    make(path)
    with pytest.raises(ConfigError) as err:
        load_heightmap(path)
    assert err.value.path == str(path) and err.value.field == field
    assert "\n" not in str(err.value)


def test_bad_files_of_every_kind(tmp_path):
    import trimesh

    with pytest.raises(ConfigError, match="no such file"):
        load_heightmap(tmp_path / "missing.tif")
    (tmp_path / "junk.tif").write_bytes(b"junk")
    with pytest.raises(ConfigError, match="cannot read as GeoTIFF"):
        load_heightmap(tmp_path / "junk.tif")
    with pytest.raises(ConfigError, match="unknown heightmap format"):
        load_heightmap(tmp_path / "map.png")
    trimesh.Trimesh(np.zeros((3, 3)), np.zeros((0, 3), int)).export(tmp_path / "empty.ply")
    with pytest.raises(ConfigError) as err:
        load_heightmap(tmp_path / "empty.ply", resolution=0.1)
    assert err.value.field == "faces"
    with pytest.raises(ConfigError) as err:
        load_heightmap(tmp_path / "empty.ply")
    assert err.value.field == "resolution"


# ------------------------------------------------------------------------------ generators
def test_generators_are_seeded_and_shaped_as_asked():
    settings = {
        "kind": "rough",
        "seed": 4,
        "size": [3.0, 2.0],
        "resolution": 0.05,
        "amplitude": 0.04,
        "correlation_length": 0.3,
        "hill_height": 0.0,
        "hill_radius": 1.0,
        "slope": 0.0,
        "azimuth": 0.0,
    }
    a, b = generate(settings), generate(settings)
    np.testing.assert_array_equal(a.elevation, b.elevation)
    assert not np.allclose(a.elevation, generate({**settings, "seed": 5}).elevation)
    assert a.shape == (41, 61) and np.allclose(a.origin, [-1.5, -1.0])
    g = Grid.of_size((3.0, 2.0), 0.05)
    e = fractal_elevation(g, 0.04, 0.3, np.random.default_rng(0))
    assert np.sqrt(np.mean(e**2)) == pytest.approx(0.04) and abs(e.mean()) < 1e-12
    # plane: slope and uphill azimuth; kerb: step at the distance; ditch: width and depth
    p = plane(g, 0.2, np.pi / 4)
    assert p.height([0.5, 0.5]) == pytest.approx(np.tan(0.2) * np.sqrt(0.5))
    k = kerb(g, 0.1, 0.5, 0.0)
    assert k.height([0.5, 0.3]) == 0.1 and k.height([0.45, 0.3]) == 0.0
    dch = ditch(g, 0.2, 0.4, -0.5, 0.0)
    assert dch.height([-0.3, 0.0]) == -0.2 and dch.height([-0.25, 0.0]) == 0.0
    bm = bumps(g, 0.05, 0.5, np.random.default_rng(1))
    assert np.abs(bm.elevation).max() <= 0.05 + 1e-12


def test_fast_row_sampler_matches_the_checked_one(rng):
    hm = generate(
        {
            "kind": "bumps",
            "seed": 1,
            "size": [1.0, 0.8],
            "resolution": 0.1,
            "amplitude": 0.1,
            "wavelength": 0.5,
        }
    )
    x0, x1, y0, y1 = hm.bounds
    x = rng.uniform(x0, x1, (5, 30))
    y = rng.uniform(y0, y1, (5, 30))
    x[:, 0], y[:, 1] = x1, y1  # the far edges are on the map
    x[3, 2] = x1 + 0.01  # row 3 leaves it
    h, hx, hy, valid = hm.sample_rows(x, y)
    s = hm.sample(np.stack([x, y], axis=-1))
    assert valid.tolist() == [True, True, True, False, True]
    for a, b in ((h, s.height), (hx, s.dh_dx), (hy, s.dh_dy)):
        np.testing.assert_allclose(a[valid], b[valid], atol=1e-12)


def test_height_alone_equals_the_sample_height_bit_for_bit() -> None:
    """``Heightmap.height`` (no slopes computed) gives ``sample``'s heights, the same floats.

    Seeded rough maps of 2 and 5 cm cells, points inside (on cell corners and edges too)
    and at the far edge; a point off the map or on an unknown cell raises as before.
    """
    import numpy as np
    import pytest

    from mmstab.terrain.heightmap import Heightmap, OffMapError

    rng = np.random.default_rng(2024)
    for res in (0.02, 0.05):
        elev = rng.normal(0.0, 0.03, (80, 120))
        hm = Heightmap.build(elev, res, (-1.3, -0.7))
        x0, x1, y0, y1 = hm.bounds
        xy = np.stack([rng.uniform(x0, x1, 5000), rng.uniform(y0, y1, 5000)], axis=1)
        corners = np.stack([hm.x[rng.integers(0, 120, 200)], hm.y[rng.integers(0, 80, 200)]], 1)
        edge = np.array([[x1, y1], [x0, y1], [x1, y0]])
        for pts in (xy, corners, edge, xy[:40].reshape(5, 8, 2), xy[0]):
            h = hm.height(pts)
            assert np.array_equal(h, hm.sample(pts).height) and np.shape(h) == pts.shape[:-1]
        with pytest.raises(OffMapError, match="off the map"):
            hm.height(np.array([[x1 + 0.1, y0]]))
        hole = elev.copy()
        hole[40, 60] = np.nan
        with pytest.raises(OffMapError, match="unknown"):
            Heightmap.build(hole, res, (-1.3, -0.7)).height(np.array([[hm.x[60], hm.y[40]]]))


def test_heights_on_a_grid_equal_the_points_heights_bit_for_bit() -> None:
    """``Heightmap.height_grid`` (each map row interpolated along x once) gives ``height``'s
    floats at every grid point: seeded rough maps of 2 and 5 cm cells, 1 cm lattices (the
    ground under the arm's tiles), random grids, the far edges; off the map or on an
    unknown cell it raises as ``height`` does."""
    rng = np.random.default_rng(77)
    for res in (0.02, 0.05):
        elev = rng.normal(0.0, 0.03, (80, 120))
        hm = Heightmap.build(elev, res, (-1.3, -0.7))
        x0, x1, y0, y1 = hm.bounds
        lattice = (np.arange(64) * 0.01 + 0.32, np.arange(64) * 0.01 - 0.64)
        scattered = (rng.uniform(x0, x1, 37), rng.uniform(y0, y1, 23))
        edges = (np.array([x0, 0.1, x1]), np.array([y1, y0]))
        for x, y in (lattice, scattered, edges):
            grid = hm.height_grid(x, y)
            points = hm.height(np.stack(np.meshgrid(x, y), axis=-1))
            assert grid.shape == (len(y), len(x)) and np.array_equal(grid, points)
        with pytest.raises(OffMapError, match="off the map"):
            hm.height_grid(np.array([x0, x1 + 0.1]), np.array([y0]))
        hole = elev.copy()
        hole[40, 60] = np.nan
        with pytest.raises(OffMapError, match="unknown"):
            Heightmap.build(hole, res, (-1.3, -0.7)).height_grid(hm.x[55:65], hm.y[38:42])
