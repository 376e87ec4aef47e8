"""The tip-over envelope atlas: axes, cells, envelope, Dask runs, resume, bad sections."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from conftest import write_problem

from experiments.__main__ import build_parser as experiments_parser
from experiments.atlas.cell import (
    ChunkTask,
    VariantPayload,
    cell_rng,
    compute_chunk,
    worker_counts,
)
from experiments.atlas.figures import binds_first, envelope
from experiments.atlas.runner import payload, run_atlas
from experiments.atlas.spec import atlas_spec, flipper_ground_angle, with_flipper_angle
from experiments.atlas.store import CELL_VARIABLES
from mmstab.cli import main
from mmstab.core.problem import load_problem
from mmstab.model.robot import FLIPPER_CONTACT_TOL
from mmstab.planner import solve_pose
from mmstab.stability.static import robot_force_angle
from mmstab.terrain import Ramp

pytestmark = pytest.mark.dask
CACHE = None  # set per session by the ``cache`` fixture

TINY_ATLAS = {
    "axes": {
        "slope": [0.0, 0.3, 0.6],
        "heading": {"start": 0.0, "stop": 2 * math.pi, "num": 4},
        "flipper_angle": ["robot", "ground"],
    },
    "chunks": {"slope": 2, "heading": 2},
    "margin": 300.0,
}


def tiny(prob, rob, atlas=None):
    """A fast problem: coarse workspace grid, small CMA-ES budget, the tiny atlas."""
    prob["workspace"]["grid"] = [8, 8, 8, 8]
    prob["planner"].update(popsize=6, max_iterations=4)
    prob["atlas"] = atlas if atlas is not None else TINY_ATLAS


@pytest.fixture(scope="module", autouse=True)
def cache(tmp_path_factory):
    """Workspace caches of the tests go to a temporary folder."""
    global CACHE
    CACHE = tmp_path_factory.mktemp("workspace")
    yield CACHE


@pytest.fixture(scope="module")
def tiny_problem(tmp_path_factory):
    return load_problem(write_problem(tmp_path_factory.mktemp("atlas"), tiny))


@pytest.fixture(scope="module")
def cluster():
    """A real local Dask cluster of two single-threaded worker processes."""
    import logging

    from distributed import Client, LocalCluster

    with (
        LocalCluster(
            n_workers=2,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            silence_logs=logging.CRITICAL,
        ) as c,
        Client(c) as client,
    ):
        yield c.scheduler_address, client


def serial_cells(problem, tmp_path):
    """Every cell computed in this process, one chunk at a time (no Dask, no store)."""
    spec = atlas_spec(problem)
    out = {n: np.full(spec.shape, np.nan) for n in CELL_VARIABLES}
    for v in spec.variants:
        p = payload(spec, v, progress=False, cache_dir=tmp_path)
        for b in spec.blocks():
            if b.variant[:3] != v.position:
                continue
            terrain = spec.terrains[b.variant[3]]
            r = compute_chunk(
                p, ChunkTask(b, spec.slopes[b.slope], spec.headings[b.heading], terrain)
            )
            for n in CELL_VARIABLES:
                out[n][(*b.variant, b.slope, b.heading)] = getattr(r, n)
    return out


# --------------------------------------------------------------------------- spec and axes
def test_axes_defaults_and_blocks_cover_every_cell_once(tmp_path):
    atlas = {
        "axes": {"heading": {"start": 0.0, "stop": 2 * math.pi, "num": 6}},
        "chunks": {"slope": 3, "heading": 4},
        "margin": 0.0,
    }  # noqa: E501
    spec = atlas_spec(load_problem(write_problem(tmp_path, lambda p, r: tiny(p, r, atlas))))
    # full turn: the end (2 pi, same heading as 0) is left out
    np.testing.assert_allclose(spec.headings, np.arange(6) * math.pi / 3)
    np.testing.assert_allclose(spec.slopes, [0.10])  # terrain.slope of the problem
    assert spec.robot_labels == ("cameleon",) and spec.flipper_labels == ("robot",)
    assert spec.variants[0].flipper_angle == 0.6
    hits = np.zeros(spec.shape, dtype=int)
    for b in spec.blocks():
        hits[(*b.variant, b.slope, b.heading)] += 1
    assert (hits == 1).all() and len(spec.blocks()) == 2  # headings 0-3 and 4-5


def test_ground_flipper_angle_touches_and_widens_the_polygon(robot):
    angle = flipper_ground_angle(robot)
    lowered = with_flipper_angle(robot, angle)
    low = lowered.base.flippers.box("left").corners()[:, 2].min()
    assert 0.0 <= low <= FLIPPER_CONTACT_TOL and angle < robot.base.flippers.angle
    assert len(robot.base.support_points()) == 4
    assert len(lowered.base.support_points()) == 8  # two tip corners per flipper
    assert lowered.source_hash != robot.source_hash  # its own workspace cache
    assert with_flipper_angle(robot, robot.base.flippers.angle) is robot


def test_cells_do_not_depend_on_chunking_and_match_the_planner(tiny_problem):
    spec = atlas_spec(tiny_problem)
    v = spec.variants[0]
    p = payload(spec, v, progress=False, cache_dir=CACHE)
    whole = [b for b in spec.blocks() if b.variant[:3] == v.position and b.block == (0, 0)][0]
    r = compute_chunk(p, ChunkTask(whole, spec.slopes[whole.slope], spec.headings[whole.heading]))
    # the same cell alone, through the planner directly with the cell's own generator
    i, j = 1, 1
    ctx_robot = v.robot
    target = solve_pose(
        ctx_robot,
        Ramp(spec.slopes[i]),
        p.workspace,
        [0.0, 0.0, spec.headings[j]],
        ctx_robot.arm_com(ctx_robot.stowed),
        spec.settings,
        cell_rng(spec.settings.seed, v.position, i, j),
    )
    assert r.mu_planned[i, j] == pytest.approx(target.mu, abs=1e-9)
    np.testing.assert_allclose(r.arm_com[i, j], target.target_com, atol=1e-12)
    gravity = Ramp(spec.slopes[i]).gravity_body([0.0, 0.0, spec.headings[j]])
    stowed = robot_force_angle(ctx_robot, gravity, ctx_robot.arm_com(ctx_robot.stowed)).mu[0]
    assert r.mu_stowed[i, j] == pytest.approx(stowed)


def test_arm_removed_measure_matches_the_hand_formula(tiny_problem):
    # heading 0: body x across the slope, the downhill track edge is the tip-over axis, so
    # mu = m_b g (atan(half width / CoM height) - slope) (force-angle, DESIGN section 3)
    spec = atlas_spec(tiny_problem)
    v = spec.variants[0]
    b = spec.blocks()[0]
    r = compute_chunk(
        payload(spec, v, progress=False, cache_dir=CACHE),
        ChunkTask(b, spec.slopes[b.slope], spec.headings[b.heading]),
    )
    base = v.robot.base
    half_w = base.tracks.separation / 2 + base.tracks.width / 2
    expected = base.mass * 9.81 * (math.atan2(half_w, base.com[2]) - spec.slopes[b.slope])
    np.testing.assert_allclose(r.mu_arm_removed[:, 0], expected, rtol=1e-9)


# ------------------------------------------------------------------------------- envelope
def test_envelope_interpolates_the_first_crossing():
    slopes = [0.0, 0.1, 0.2, 0.3]
    mu = np.array(
        [
            [400.0, 300.0, 200.0, 100.0],  # crosses 250 halfway between 0.1 and 0.2
            [400.0, 400.0, 400.0, 400.0],  # never below: the last slope, censored
            [200.0, 400.0, 400.0, 400.0],  # below at the first slope: no limit
            [300.0, 200.0, 300.0, 300.0],  # recovers later: the first crossing counts
        ]
    ).T
    env = envelope(slopes, mu, 250.0)
    np.testing.assert_allclose(env.limit[[0, 1, 3]], [0.15, 0.3, 0.05])
    assert math.isnan(env.limit[2])
    assert env.censored.tolist() == [False, True, False, False]
    # slip at 0.12 rad: before the tip limits 0.15 and 0.3, after 0.05; NaN tips first
    assert binds_first(env, 0.12) == ["slip", "slip", "tip", "tip"]


# ---------------------------------------------------------------------- Dask, store, resume
def quiet_counts(client, settle: float = 0.5, timeout: float = 60.0) -> int:
    """Cells computed by all workers so far, once no task is still running."""
    last, t0 = None, time.monotonic()
    while True:
        now = sum(c["cells"] for c in client.run(worker_counts).values())
        if now == last:
            return now
        assert time.monotonic() - t0 < timeout, "workers did not settle"
        last = now
        time.sleep(settle)


@pytest.fixture(scope="module")
def full_run(tiny_problem, cluster, tmp_path_factory):
    """The uninterrupted atlas, through the command line, on the 2-process cluster."""
    address, client = cluster
    out = tmp_path_factory.mktemp("full")
    before = quiet_counts(client)
    with pytest.MonkeyPatch.context() as mp:
        mp.chdir(out)  # whatever the command writes in its working folder goes there too
        argv = ["atlas", str(tiny_problem.path), "-o", str(out), "--scheduler", address]
        assert main(argv, parser=experiments_parser) == 0
    import xarray as xr

    ds = xr.open_zarr(out / "atlas.zarr", consolidated=False, chunks=None).load()
    return out, ds, quiet_counts(client) - before


def test_cluster_run_stores_the_serial_cells_and_loads_each_variant_once(
    full_run, tiny_problem, cluster, tmp_path
):
    out, ds, computed = full_run
    _, client = cluster
    assert computed == 24 and ds["chunk_done"].values.all()
    serial = serial_cells(tiny_problem, tmp_path)
    for n in ("mu_planned", "mu_stowed", "mu_arm_removed"):
        np.testing.assert_allclose(ds[n].values, serial[n], rtol=0, atol=1e-9, err_msg=n)
    assert (ds["planner_seconds"].values > 0).all()
    counts = client.run(worker_counts)
    assert len(counts) == 2
    # context = robot kinematics + V per variant: at most once per process, not per cell
    assert all(c["contexts"] <= 2 for c in counts.values())
    assert sum(c["chunks"] for c in counts.values()) >= 8
    for name in ("mu_polar.png", "envelope.png", "summary.json", "problem.yaml"):
        assert (out / name).stat().st_size > 0
    import json

    s = json.loads((out / "summary.json").read_text())
    assert s["cells"] == 24 and s["chunks_stored"] == s["chunks"] == 8
    v = s["variants"][0]
    env = envelope(ds["slope"].values, ds["mu_stowed"].values[0, 0, 0, 0], 300.0)
    np.testing.assert_allclose(
        np.array(v["envelope_deg"]["stowed"], dtype=float), np.degrees(env.limit)
    )
    # the slip limit: atan(friction) (default 0.7) against each heading's tip limit
    assert s["friction"] == 0.7 and s["slip_limit_deg"] == pytest.approx(34.992020, abs=1e-6)
    for arm, limits in v["envelope_deg"].items():
        tip = np.nan_to_num(np.array(limits, dtype=float), nan=0.0)
        assert v["binds_first"][arm] == ["slip" if 34.99202 < t else "tip" for t in tip]


def test_interrupted_run_resumes_to_the_same_store(full_run, tiny_problem, cluster, tmp_path):
    import xarray as xr

    _, reference, _ = full_run
    address, client = cluster
    stored = []

    def stop_after_three(result):
        stored.append(result.block)
        if len(stored) == 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_atlas(
            tiny_problem,
            tmp_path,
            address,
            progress=False,
            workspace_cache=tmp_path,
            on_chunk=stop_after_three,
        )
    with xr.open_zarr(
        tmp_path / "atlas.zarr", consolidated=False, chunks=None
    ) as ds:  # a valid store
        done = ds["chunk_done"].values.astype(bool)
    assert done.sum() == 3 and not (tmp_path / "summary.json").exists()
    missing_cells = sum(b.cells for b in atlas_spec(tiny_problem).blocks()) - sum(
        b.cells for b in stored
    )
    before = quiet_counts(client)  # chunks in flight at Ctrl-C finish (and are discarded)
    s = run_atlas(tiny_problem, tmp_path, address, progress=False, workspace_cache=tmp_path)
    assert quiet_counts(client) - before == missing_cells  # no stored cell computed again
    assert s["run"]["cells_computed"] == missing_cells
    assert s["run"]["cells_already_stored"] == 24 - missing_cells
    with xr.open_zarr(tmp_path / "atlas.zarr", consolidated=False, chunks=None) as ds:
        for n in ("mu_planned", "mu_stowed", "mu_arm_removed", "arm_com", "chunk_done"):
            np.testing.assert_array_equal(ds[n].values, reference[n].values, err_msg=n)
    # a third run finds nothing to do
    assert (
        run_atlas(tiny_problem, tmp_path, address, progress=False, workspace_cache=tmp_path)["run"][
            "cells_computed"
        ]
        == 0
    )


# ------------------------------------------------------------------------------ bad input
def _bad(atlas):
    return lambda p, r: tiny(p, r, atlas)


BAD = [
    ({**TINY_ATLAS, "axes": {"payload": [-1.0, 2.0]}}, "atlas.axes.payload.mass", ">= 0"),
    ({**TINY_ATLAS, "axes": {"payload": [2.0, 1.0]}}, "atlas.axes.payload", "increasing"),
    ({**TINY_ATLAS, "payload_com": [0.0, 0.1]}, "atlas.payload_com", "too short"),
    ({**TINY_ATLAS, "axes": {"terrain_seeds": [1]}}, "atlas.axes.terrain_seeds", "heightmap"),
    ({**TINY_ATLAS, "axes": {"flipper_angle": [-0.6]}}, "atlas.axes.flipper_angle[0]", "below"),
    ({**TINY_ATLAS, "axes": {"slope": [0.3, 0.1]}}, "atlas.axes.slope", "increasing"),
    ({**TINY_ATLAS, "axes": {"tilt": [0.1]}}, "atlas.axes.tilt", "unknown key"),
    ({**TINY_ATLAS, "margin": "high"}, "atlas.margin", "is not of type"),
]


@pytest.mark.parametrize(("atlas", "field", "words"), BAD)
def test_bad_atlas_section_is_one_line_and_exit_2(tmp_path, capsys, atlas, field, words):
    path = write_problem(tmp_path, _bad(atlas))
    out = tmp_path / "out"
    assert main(["atlas", str(path), "-o", str(out)], parser=experiments_parser) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(path) in err and field in err and words in err
    assert not out.exists()


def test_store_of_another_atlas_is_not_resumed(tmp_path, capsys, tiny_problem):
    spec = atlas_spec(tiny_problem)
    from experiments.atlas.store import AtlasStore

    AtlasStore.open_or_create(tmp_path / "atlas.zarr", spec, np.ones(spec.shape[:3]))
    path = write_problem(
        tmp_path, _bad({**TINY_ATLAS, "margin": 1.0, "chunks": {"slope": 1, "heading": 4}})
    )  # noqa: E501
    assert main(["atlas", str(path), "-o", str(tmp_path)], parser=experiments_parser) == 2
    err = capsys.readouterr().err
    assert "holds another atlas" in err and len(err.strip().splitlines()) == 1


def test_payload_is_picklable_without_kinematics(tiny_problem):
    import pickle

    spec = atlas_spec(tiny_problem)
    p = payload(spec, spec.variants[1], progress=False, cache_dir=CACHE)
    q = pickle.loads(pickle.dumps(p))
    assert isinstance(q, VariantPayload) and q.key == p.key
    assert q.robot.base.flippers.angle == pytest.approx(flipper_ground_angle(tiny_problem.robot))


def test_unreachable_scheduler_is_one_line(tmp_path, capsys, tiny_problem, monkeypatch):
    import experiments.atlas.driver as driver

    monkeypatch.setattr(driver, "CONNECT_TIMEOUT", 1.0)
    argv = [
        "atlas",
        str(tiny_problem.path),
        "-o",
        str(tmp_path),
        "--scheduler",
        "tcp://127.0.0.1:9",
    ]
    monkeypatch.chdir(tmp_path)
    assert main(argv, parser=experiments_parser) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot reach the Dask scheduler at tcp://127.0.0.1:9" in err[0]


# ----------------------------------------------------------- payload and terrain-seed axes
PLANE = {"kind": "plane", "seed": 0, "size": [3.0, 3.0], "resolution": 0.1}
ROUGH_SEEDED = {
    "kind": "rough",
    "seed": 3,
    "size": [3.0, 3.0],
    "resolution": 0.05,
    "amplitude": 0.03,
    "correlation_length": 0.3,
    "hill_height": 0.0,
    "hill_radius": 1.0,
    "slope": 0.2,
    "azimuth": 0.5,
}
SMALL_AXES = {"slope": [0.1, 0.4], "heading": [0.0, 2.0]}


def _problem(tmp_path, atlas, terrain=None):
    def edit(p, r):
        tiny(p, r, {"chunks": {"slope": 2, "heading": 2}, "margin": 300.0, **atlas})
        if terrain is not None:
            p["terrain"] = {"generate": terrain}

    tmp_path.mkdir(parents=True, exist_ok=True)
    return load_problem(write_problem(tmp_path, edit))


def test_payload_axis_loads_the_wrist_and_has_its_own_workspace(tmp_path):
    axes = {**SMALL_AXES, "payload": [0.0, 3.0]}
    problem = _problem(tmp_path / "p", {"axes": axes, "payload_com": [0.0, 0.0, 0.05]})
    spec = atlas_spec(problem)
    assert spec.shape == (1, 1, 2, 1, 2, 2)
    empty, loaded = spec.variants
    assert empty.robot is problem.robot  # 0 kg: the robot, its hash and its V unchanged
    assert loaded.robot.arm_mass == pytest.approx(problem.robot.arm_mass + 3.0)
    pe, pl = (payload(spec, v, progress=False, cache_dir=tmp_path) for v in spec.variants)
    # V, the arm-CoM workspace, depends on the arm's masses: the loaded arm has its own
    assert pe.key != pl.key and len(list(tmp_path.glob("*.npz"))) == 2
    assert not np.allclose(
        pe.workspace.valid_com_in_V.mean(axis=0), pl.workspace.valid_com_in_V.mean(axis=0)
    )
    cells = serial_cells(problem, tmp_path)
    # the 0 kg cells are the cells of the same atlas without the axis (same generators)
    plain = serial_cells(_problem(tmp_path / "plain", {"axes": SMALL_AXES}), tmp_path)
    for n in ("mu_planned", "mu_stowed", "mu_arm_removed"):
        np.testing.assert_array_equal(cells[n][:, :, :1], plain[n], err_msg=n)
    # the loaded robot by hand: the payload folded into the wrist moves the stowed CoM
    r = loaded.robot
    gravity = Ramp(0.4).gravity_body([0.0, 0.0, 2.0])
    by_hand = robot_force_angle(r, gravity, r.arm_com(r.stowed)).mu[0]
    assert cells["mu_stowed"][0, 0, 1, 0, 1, 1] == pytest.approx(by_hand, rel=1e-12)
    assert abs(by_hand - cells["mu_stowed"][0, 0, 0, 0, 1, 1]) > 0.05  # stowed: near the base
    assert np.isfinite(cells["mu_planned"]).all()


def test_plane_heightmap_cells_are_the_ramps(tmp_path):
    """A generated plane swept over its slope parameter is the ramp."""
    ramp = _problem(tmp_path / "ramp", {"axes": SMALL_AXES})
    plane = _problem(
        tmp_path / "plane", {"axes": SMALL_AXES}, {**PLANE, "slope": 0.1, "azimuth": 0.7}
    )
    spec = atlas_spec(plane)
    assert spec.terrain_labels == ("plane seed 0",) and not spec.on_ramp
    a, b = serial_cells(ramp, tmp_path), serial_cells(plane, tmp_path)
    for n in ("mu_stowed", "mu_arm_removed", "mu_planned"):
        np.testing.assert_allclose(b[n], a[n], rtol=0, atol=1e-6, err_msg=n)


def test_payload_and_seed_axes_on_the_cluster(cluster, tmp_path):
    import json

    import xarray as xr

    from experiments.atlas.cell import heightmap_yaw
    from mmstab.stability.stance import stance
    from mmstab.terrain.generators import generate
    from mmstab.terrain.heightmap_terrain import HeightmapTerrain

    axes = {"slope": [0.1, 0.3], "heading": [0.0, 1.6], "payload": [0.0, 2.0]}
    problem = _problem(tmp_path / "p", {"axes": {**axes, "terrain_seeds": [1, 2]}}, ROUGH_SEEDED)
    address, _ = cluster
    out = tmp_path / "out"
    s = run_atlas(problem, out, address, progress=False, workspace_cache=tmp_path)
    ds = xr.open_zarr(out / "atlas.zarr", consolidated=False, chunks=None).load()
    assert ds["mu_planned"].shape == (1, 1, 2, 2, 2, 2) and ds["chunk_done"].values.all()
    assert ds["terrain_seed"].values.tolist() == [1, 2]
    serial = serial_cells(problem, tmp_path)
    for n in ("mu_planned", "mu_stowed", "mu_arm_removed"):
        np.testing.assert_allclose(ds[n].values, serial[n], rtol=0, atol=1e-9, err_msg=n)
    # a cell by hand: the robot with 2 kg at rest at the map's centre of seed 2, slope 0.3
    spec = atlas_spec(problem)
    robot = spec.variants[1].robot
    ground = HeightmapTerrain(generate({**ROUGH_SEEDED, "seed": 2, "slope": 0.3}))
    yaw = heightmap_yaw(spec.terrains[1], 0.3, np.array([1.6]))[0]
    # mmstab's one μ: what ``mmstab rest`` reports for that state (its loaded contacts)
    by_hand = stance(ground, robot, np.array([0.0, 0.0, yaw])).mu
    assert ds["mu_stowed"].values[0, 0, 1, 1, 1, 1] == pytest.approx(by_hand, rel=1e-9)
    # not the tracks' rectangle under the same rest (a bumpy map: another support)
    gravity = ground.with_robot(robot).gravity_body([0.0, 0.0, yaw])
    rectangle = robot_force_angle(robot, gravity, robot.arm_com(robot.stowed)).mu[0]
    assert abs(rectangle - by_hand) > 1.0
    # other seeds are other ground
    seeds = ds["mu_stowed"].values[:, :, :, 0], ds["mu_stowed"].values[:, :, :, 1]
    assert np.abs(seeds[0] - seeds[1]).max() > 1.0
    assert len(s["variants"]) == 4
    assert {(v["payload_kg"], v["terrain"]) for v in s["variants"]} == {
        (p, f"rough seed {k}") for p in (0.0, 2.0) for k in (1, 2)
    }
    assert json.loads((out / "summary.json").read_text())["axes"]["payload_kg"] == [0.0, 2.0]
    for name in ("mu_polar.png", "envelope.png"):
        assert (out / name).stat().st_size > 0
