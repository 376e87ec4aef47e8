"""The resting pose's C kernel against its NumPy twin (same algorithm, two implementations)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mmstab.core.files import MmstabError
from mmstab.terrain.generators import Grid, generate, plane
from mmstab.terrain.heightmap_terrain import HeightmapTerrain

ROUGH = {
    "kind": "rough",
    "seed": 5,
    "size": [4.0, 4.0],
    "resolution": 0.05,
    "amplitude": 0.04,
    "correlation_length": 0.3,
    "hill_height": 0.4,
    "hill_radius": 1.0,
    "slope": 0.3,
    "azimuth": 1.2,
}
KERB = {
    "kind": "kerb",
    "seed": 0,
    "size": [3.0, 3.0],
    "resolution": 0.02,
    "height": 0.12,
    "distance": 0.0,
    "azimuth": 0.3,
}


def backends(terrain: HeightmapTerrain, **changes: object) -> tuple[HeightmapTerrain, ...]:
    """The terrain with the C kernel and with the NumPy path (same other settings)."""
    s = terrain.settings._replace(**changes)  # type: ignore[arg-type]
    assert s.backend == "c"  # the default
    return (
        dataclasses.replace(terrain, settings=s),
        dataclasses.replace(terrain, settings=s._replace(backend="numpy")),
    )


def assert_same_rests(a, b, atol: float = 1e-11) -> None:
    ok = np.isfinite(b.z)
    np.testing.assert_array_equal(np.isfinite(a.z), ok)
    np.testing.assert_allclose(a.roll[ok], b.roll[ok], atol=atol, rtol=0)
    np.testing.assert_allclose(a.pitch[ok], b.pitch[ok], atol=atol, rtol=0)
    np.testing.assert_allclose(a.z[ok], b.z[ok], atol=atol, rtol=0)
    np.testing.assert_array_equal(a.touching, b.touching)
    for name in ("converged", "high_centred", "line_contact", "tips_over"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    # the rounds too, but for a few poses: on flat ground many candidates tie for the
    # support and the two paths may order a pose's subset differently
    assert (a.iterations == b.iterations).mean() >= 0.98


@pytest.mark.parametrize("section", [ROUGH, KERB], ids=["rough", "kerb"])
@pytest.mark.parametrize("active", [24, 0], ids=["fast", "reference"])
def test_kernel_equals_the_numpy_path(robot, section, active):
    """Random poses over the map, both stages' paths: same rests, flags and rounds."""
    terrain = HeightmapTerrain(generate(section)).with_robot(robot)
    c_path, numpy_path = backends(terrain, active_candidates=active)
    rng = np.random.default_rng(3)
    n = 400
    poses = np.c_[rng.uniform(-0.8, 0.8, (n, 2)), rng.uniform(-np.pi, np.pi, n)]
    a, b = c_path.rest(poses), numpy_path.rest(poses)
    assert a.converged.mean() > 0.99
    assert_same_rests(a, b)
    # one pose at a time gives the batch's rest
    for i in rng.choice(n, 4, replace=False):
        np.testing.assert_allclose(c_path.rest(poses[i]).G_T_B[0], a.G_T_B[i], atol=1e-13)


def test_kernel_off_the_map_unknown_cells_and_flags(robot):
    """Poses whose ground is partly off the map or unknown (NaN), a high-centring ridge and a
    side slope the robot rolls off: the kernel flags what the NumPy path flags."""
    g = Grid.of_size((3.0, 3.0), 0.02)
    x, y = g.xy()
    elevation = np.where(np.abs(y) < 0.1, 0.12, 0.0) + 0.05 * np.sin(2 * x)
    elevation[(x > 0.8) & (y > 0.8)] = np.nan  # an unknown corner
    ridge = HeightmapTerrain(g.heightmap(elevation, "ridge")).with_robot(robot)
    rng = np.random.default_rng(4)
    poses = np.c_[rng.uniform(-1.1, 1.1, (300, 2)), rng.uniform(-np.pi, np.pi, 300)]
    a, b = (t.rest(poses, strict=False) for t in backends(ridge))
    assert np.isnan(a.z).sum() > 50 and a.high_centred.sum() >= 5  # both kinds are exercised
    assert_same_rests(a, b)
    steep = HeightmapTerrain(plane(Grid.of_size((4, 4), 0.1), 1.1, np.pi / 2)).with_robot(robot)
    a, b = (t.rest([[0.0, 0.0, 0.0], [0.1, 0.2, 0.3]]) for t in backends(steep))
    assert a.tips_over.all()
    assert_same_rests(a, b)


def test_unknown_backend_is_refused(robot):
    terrain = HeightmapTerrain(generate(KERB)).with_robot(robot)
    odd = dataclasses.replace(terrain, settings=terrain.settings._replace(backend="fortran"))
    with pytest.raises(ValueError, match="backend"):
        odd.rest([0.0, 0.0, 0.0])


def test_compiled_library_is_cached_by_source(tmp_path, monkeypatch):
    """One build per source text: the same source is reused, an edited one rebuilt."""
    from mmstab.core.clib import compiled_library

    monkeypatch.setenv("MMSTAB_CACHE", str(tmp_path / "cache"))
    src = tmp_path / "k.c"
    src.write_text("int mmstab_k(void) { return 1; }\n")
    first = compiled_library(src, "mmstab_k")
    assert first.is_file() and compiled_library(src, "mmstab_k") == first
    src.write_text("int mmstab_k(void) { return 2; }\n")
    second = compiled_library(src, "mmstab_k")
    assert second != first and second.is_file()
    src.write_text("int mmstab_k(void) { return }\n")
    with pytest.raises(MmstabError, match="compiling k.c failed"):
        compiled_library(src, "mmstab_k")
    assert sorted(p.name for p in (tmp_path / "cache").iterdir()) == sorted(
        [first.name, second.name]
    )  # nothing half-written left behind
