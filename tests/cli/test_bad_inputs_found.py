"""What the bad-input campaign (tests/cli/test_bad_inputs_fuzz.py) found, one test per fix.

Each was a traceback, a message that named nothing or the wrong thing, an output written
before the refusal, or an invalid input run; now one line, exit status 2, nothing written.
"""

from __future__ import annotations

import copy
import io
import shutil
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import PROBLEMS, write_problem

from experiments.__main__ import build_parser as experiments_parser
from mmstab.cli import build_parser, main
from mmstab.core.files import ConfigError, read_yaml, validate
from mmstab.core.problem import load_problem
from mmstab.core.schema import ROBOT
from mmstab.model.robot import robot_from_dict
from mmstab.terrain.heightmap import check_layout


def _refused(capsys: pytest.CaptureFixture[str], argv: list[str], parser=build_parser) -> str:
    """Run ``argv`` (``parser``'s command line): exit status 2 and one line on stderr, returned."""
    assert main(argv, parser=parser) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("mmstab: error: "), err
    return err[0]


# ------------------------------------------------------------------------------- YAML text
def test_binary_or_control_bytes_in_a_yaml_file_are_one_line(tmp_path, capsys):
    path = tmp_path / "p.yaml"
    path.write_bytes(b"robot: r.yaml\n\xff\xfe\n")  # UnicodeDecodeError escaped read_yaml
    line = _refused(capsys, ["rest", str(path), "--pose", "0", "0", "0"])
    assert line.endswith("p.yaml: not UTF-8 text (byte 14): not a YAML file")
    path.write_bytes(b"robot: \x00\n")
    with pytest.raises(ConfigError, match=r"character 7: U\+0000 is not allowed in YAML"):
        read_yaml(path)


def test_a_key_given_twice_is_refused_not_overwritten(tmp_path, capsys):
    path = write_problem(tmp_path)
    text = path.read_text()
    path.write_text(text + "terrain: {slope: 1.1}\n")  # PyYAML ran on the second, silently
    line = _refused(capsys, ["rest", str(path), "--pose", "0", "0", "0"])
    first = 1 + next(i for i, t in enumerate(text.splitlines()) if t.startswith("terrain:"))
    last = len(text.splitlines()) + 1
    assert line.endswith(f"terrain: given twice in one mapping (lines {first} and {last})")
    path.write_text("a: &x {b: 1}\nc: *x\nd: {<<: *x, e: 2}\n")  # aliases, merges: one each
    assert read_yaml(path) == {"a": {"b": 1}, "c": {"b": 1}, "d": {"b": 1, "e": 2}}


def test_integers_beyond_64_bits_are_refused(tmp_path):
    for big, digits in ((10**400, 401), (2**63, 19)):
        with pytest.raises(ConfigError) as info:
            validate(tmp_path / "p.yaml", {"planner": {"seed": big}}, {})
        assert info.value.field == "planner.seed"
        assert info.value.message == f"integer of {digits} digits; at most 2**63 - 1"
    validate(tmp_path / "p.yaml", {"planner": {"seed": 2**63 - 1}}, {})  # the largest: kept


def test_a_typo_in_a_capsule_is_not_read_as_a_box():
    robot = yaml.safe_load((PROBLEMS / "robots" / "cameleon.yaml").read_text())
    geometry = robot["arm"]["links"][1]["geometry"]
    assert geometry["type"] == "capsule"
    cases = [
        (
            lambda g: g.__setitem__("radus", 0.04),
            "arm.links[1].geometry.radus",
            "unknown key; did you mean 'radius'?",
        ),
        (lambda g: g.pop("radius"), "arm.links[1].geometry.radius", "missing required key"),
        (
            lambda g: g.__setitem__("type", "sphere"),
            "arm.links[1].geometry.type",
            "must be one of box, capsule",
        ),
    ]
    for edit, field, message in cases:  # before: "geometry.type: 'box' was expected"
        data = yaml.safe_load(yaml.safe_dump(robot))
        edit(data["arm"]["links"][1]["geometry"])
        with pytest.raises(ConfigError) as info:
            validate("r.yaml", data, ROBOT)
        assert (info.value.field, info.value.message) == (field, message)
    with pytest.raises(ConfigError, match="geometry.radius: -1 is less than or equal"):
        data = yaml.safe_load(yaml.safe_dump(robot))
        data["arm"]["links"][1]["geometry"]["radius"] = -1
        robot_from_dict(data, "r.yaml")


# ------------------------------------------------------------------------------ heightmaps
def test_heightmap_arrays_of_the_wrong_kind_are_one_line():
    e, origin = np.zeros((4, 4)), np.zeros(2)
    with pytest.raises(ConfigError) as info:  # the 3 x 3 array's repr spanned three lines
        check_layout("g.npz", e, np.full((3, 3), 0.05), origin)
    assert str(info.value) == (
        "g.npz: resolution: must be one real number [m/cell], got shape (3, 3), dtype float64"
    )
    with pytest.raises(ConfigError, match="origin: must be 2 real numbers.*complex128"):
        check_layout("g.npz", e, 0.05, np.array([1j, 0.0]))  # imaginary part dropped, warning
    with pytest.raises(ConfigError, match="resolution: must be one real number"):
        check_layout("g.npz", e, np.complex128(0.05 + 1j), origin)
    _, res, o = check_layout("g.npz", e, np.int64(1), np.array([1, 2]))  # integers: fine
    assert res == 1.0 and o.tolist() == [1.0, 2.0]


def _lying_npz(side: int) -> bytes:
    head = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        head, {"descr": "<f8", "fortran_order": False, "shape": (side, side)}
    )
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as z:
        z.writestr("elevation.npy", head.getvalue() + b"\0" * 64)
    return out.getvalue()


def _terrain_problem(tmp_path: Path, terrain: dict) -> Path:
    return write_problem(tmp_path, lambda p, r: p.__setitem__("terrain", terrain))


def test_heightmaps_beyond_memory_name_the_file_before_reading(tmp_path, capsys):
    (tmp_path / "g.npz").write_bytes(_lying_npz(10**7))  # 800 TB: "out of memory", no file
    path = _terrain_problem(tmp_path, {"file": "g.npz"})
    assert _refused(capsys, ["rest", str(path), "--pose", "0", "0", "0"]).endswith(
        "g.npz: its arrays do not fit in memory"
    )
    stl = "solid s\nfacet normal 0 0 1\nouter loop\n"
    stl += "vertex -5 -5 0\nvertex 5 -5 0\nvertex 5 5 0\nendloop\nendfacet\nendsolid s\n"
    (tmp_path / "g.stl").write_text(stl)
    path = _terrain_problem(tmp_path, {"file": "g.stl", "resolution": 1e-7})
    line = _refused(capsys, ["rest", str(path), "--pose", "0", "0", "0"])
    assert "g.stl: resolution: 1e+16 map cells (100000001 x 100000001) need about" in line


def test_a_geotiff_whose_tags_claim_too_many_pixels_is_one_line(tmp_path, capsys):
    import tifffile

    shutil.copy(PROBLEMS / "terrains" / "bumps_ditch.tif", tmp_path / "g.tif")
    with tifffile.TiffFile(tmp_path / "g.tif", mode="r+b") as tif:
        for tag in ("ImageWidth", "ImageLength"):
            tif.pages[0].tags[tag].overwrite(10**8)  # tifffile logged two lines, then no memory
    path = _terrain_problem(tmp_path, {"file": "g.tif"})
    line = _refused(capsys, ["rest", str(path), "--pose", "0", "0", "0"])
    assert "g.tif: band: 1e+16 map cells (100000000 x 100000000) need about" in line


# ---------------------------------------------------------------------------------- routes
def test_a_route_of_1e300_m_is_refused_before_its_speed_profile(tmp_path, capsys):
    def edit(p, r):
        p["path"] = {"waypoints": [[0, 0], [3, 0], [1e300, 0]], "speed": 0.25, "turn_radius": 0}

    path = write_problem(tmp_path, edit)  # OverflowError in Route.resample
    line = _refused(capsys, ["rest", str(path), "--pose", "0.5", "0", "0.3"])
    assert line.endswith(
        "problem.yaml: path.waypoints: the line through the waypoints is 1e+300 m long; "
        "at most 10000 m"
    )
    (tmp_path / "r.csv").write_text("0,0\n9999,0\n9999,2\n")  # 10.001 km from a file
    path = write_problem(
        tmp_path,
        lambda p, r: p.__setitem__("path", {"file": "r.csv", "speed": 0.25, "turn_radius": 0}),
    )
    with pytest.raises(ConfigError) as info:
        load_problem(path)
    assert info.value.path.endswith("r.csv") and info.value.field == "waypoints"


# ------------------------------------------------------------------------------- workspace
def test_a_sampled_workspace_grid_is_bounded(tmp_path):
    from mmstab.core.sizes import (
        WS_BYTES_PER_POSTURE,
        WS_CHUNK_BYTES,
        workspace_estimate,
        workspace_workers,
    )

    def edit(grid):
        return lambda p, r: p["workspace"].update(grid=grid, samples=1000)

    path = write_problem(tmp_path, edit([2**16] * 4))  # 2**64 postures: OverflowError in choice
    with pytest.raises(ConfigError) as info:
        load_problem(path)
    assert info.value.field == "workspace.grid"
    assert info.value.message == "has 1.84e+19 postures; at most 2**62 can be numbered"
    # a sampled grid still holds each joint's samples, 8 B each (10**9: 8 GB, estimated 0)
    base = (workspace_workers() + 1) * WS_CHUNK_BYTES + 1000 * WS_BYTES_PER_POSTURE
    assert workspace_estimate([10**9, 2, 2, 2], 1000).bytes == base + 8.0 * (10**9 + 6)


# ----------------------------------------------------------------------- command options
def test_simulate_bounds_its_duration_before_any_work(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = write_problem(tmp_path)
    out = tmp_path / "out"
    argv = ["simulate", str(path), "-o", str(out), "--duration", "1e300"]
    line = _refused(capsys, argv)  # ValueError: Maximum allowed size exceeded
    assert line.startswith("mmstab: error: --duration: 2.5e+302 control periods (1e+300 s at dt")
    path = write_problem(tmp_path, lambda p, r: p.__setitem__("physics", {"duration": 1e6}))
    line = _refused(capsys, ["simulate", str(path), "-o", str(out)])
    assert "problem.yaml: physics.duration: 2.5e+08 control periods (1e+06 s" in line
    assert not out.exists()


def test_stability_map_and_export_bound_their_options(tmp_path, capsys):
    out = tmp_path / "map"
    rough = str(PROBLEMS / "rough.yaml")
    line = _refused(capsys, ["stability-map", rough, "-o", str(out), "--spacing", "inf"])
    assert line.endswith("--spacing must be finite and > 0 [m] and --headings >= 1")
    line = _refused(capsys, ["stability-map", rough, "-o", str(out), "--spacing", "0.0005"])
    assert "--spacing / --headings: 5.12e+09 resting poses (every 0.0005 m, 8 headings)" in line
    line = _refused(capsys, ["stability-map", rough, "-o", str(out), "--headings", "10000000"])
    assert "2.67e+10 resting poses (every 0.25 m, 10000000 headings)" in line
    assert not out.exists()  # --spacing inf wrote four files, then a traceback
    npz = tmp_path / "t.npz"
    ramp = str(PROBLEMS / "ramp.yaml")
    line = _refused(capsys, ["terrain", "export", ramp, "-o", str(npz), "--resolution", "1e-6"])
    assert "--size / --resolution: 3.6e+13 map cells need about" in line
    line = _refused(capsys, ["terrain", "export", ramp, "-o", str(npz), "--resolution", "inf"])
    assert line.endswith("--resolution: must be finite, got [inf]")
    assert not npz.exists()


# ------------------------------------------------------------------------------ recordings
@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """problems/rough.yaml (robot path absolute) and its first second recorded."""
    from mmstab.outputs.recording import record_route

    d = tmp_path_factory.mktemp("rec")
    data = yaml.safe_load((PROBLEMS / "rough.yaml").read_text())
    data["robot"] = str(PROBLEMS / "robots" / "cameleon.yaml")
    problem = d / "rough.yaml"
    problem.write_text(yaml.safe_dump(data))
    record_route(load_problem(problem), d / "run.mcap", 1.0)
    return problem, d / "run.mcap"


@pytest.mark.slow
def test_follow_refuses_odometry_after_every_map_before_writing(recording, tmp_path, capsys):
    from rosbags.highlevel import AnyReader

    from mmstab.core.bags import BagWriter
    from mmstab.terrain.gridmap import typestore

    problem, run = recording
    late = tmp_path / "late.mcap"
    store = typestore(False)
    with AnyReader([run], default_typestore=store) as r, BagWriter(late, store) as w:
        for c, stamp, raw in r.messages():
            t = (stamp - r.start_time) * 1e-9 + (10.0 if "odom" in c.topic else 0.0)
            w.write(c.topic, c.msgtype, t, r.deserialize(raw, c.msgtype))
    out = tmp_path / "out"
    line = _refused(capsys, ["follow", str(problem), "--bag", str(late), "-o", str(out)])
    assert line.endswith("late.mcap: odometry: no map arrived after any odometry")
    assert not out.exists()  # summary.json was written, then the refusal


def test_follow_without_a_covered_map_writes_null_not_nan(recording, tmp_path, capsys):
    import json

    problem, run = recording
    out = tmp_path / "out"
    assert main(["follow", str(problem), "--bag", str(run), "-o", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())  # ValueError: NaN not JSON compliant
    assert s["updates"] == 11 and s["robot_not_covered_updates"] == 11
    assert s["mu_min"] is None and s["tilt_max_rad"] is None
    assert "mu min n/a; QP failures 0" in capsys.readouterr().out


# ---------------------------------------------------------------------------------- levers
@pytest.mark.parametrize(
    "robots, field, message",
    [
        (["robots/cameleon.yaml", "robots/none.yaml"], "levers.robots[1]", "no robot description"),
        (["robots/six.yaml"], "levers.robots[0]", "robots/six.yaml: controller.w_b: has 6"),
    ],
)
def test_levers_checks_its_robot_files_before_any_work(
    tmp_path, capsys, monkeypatch, robots, field, message
):
    import mmstab.app

    def work(*args, **kwargs):
        raise AssertionError("the workspace was built before the robot files were checked")

    monkeypatch.setattr(mmstab.app, "workspace", work)
    six = yaml.safe_load((PROBLEMS / "robots" / "cameleon_6dof.yaml").read_text())
    levers = yaml.safe_load((PROBLEMS / "levers.yaml").read_text())["levers"]

    def edit(p, r):
        p["levers"] = {**levers, "robots": robots}
        p["levers"].pop("rough_problem")

    path = write_problem(tmp_path, edit)
    (tmp_path / "robots" / "six.yaml").write_text(yaml.safe_dump(six))
    out = tmp_path / "out"
    line = _refused(capsys, ["levers", str(path), "-o", str(out)], experiments_parser)
    assert f"problem.yaml: {field}: " in line and message in line
    assert not out.exists()


# ------------------------------------------------------------------------- terrain section
@pytest.mark.parametrize(
    "key, value, field, message",
    [
        ("size", [20.0, 8.0, 1.0], "size", "[20.0, 8.0, 1.0] is too long"),
        ("resolution", "fine", "resolution", "'fine' is not of type 'number'"),
        ("resolution", 0, "resolution", "0 is less than or equal to the minimum of 0"),
        ("size", [20, "a"], "size[1]", "'a' is not of type 'number'"),
        ("kind", {"a": 1}, "kind", "must be one of plane, kerb, ditch, bumps, rough"),
    ],
)
def test_a_generated_terrain_is_checked_before_its_size_bound(tmp_path, key, value, field, message):
    rough = yaml.safe_load((PROBLEMS / "rough.yaml").read_text())["terrain"]
    rough["generate"][key] = value  # the size bound read them first: ValueError, ZeroDivision
    path = write_problem(tmp_path, lambda p, r: p.__setitem__("terrain", rough))
    with pytest.raises(ConfigError) as info:
        load_problem(path)
    assert (info.value.field, info.value.message) == (f"terrain.generate.{field}", message)


def test_a_robot_beyond_100_m_or_1e6_kg_is_refused(tmp_path, capsys):
    def edit(p, r):
        r["base"]["body"]["center"][1] = 1e300  # ValueError in the route's footprint sampling

    rough = yaml.safe_load((PROBLEMS / "rough.yaml").read_text())
    path = write_problem(tmp_path, lambda p, r: (p.update(rough, robot=p["robot"]), edit(p, r)))
    line = _refused(capsys, ["rest", str(path), "--pose", "0", "0", "0"])
    assert line.endswith(
        "cameleon.yaml: base.body.center[1]: 1e+300 is greater than the maximum of 100.0"
    )
    robot = yaml.safe_load((PROBLEMS / "robots" / "cameleon.yaml").read_text())
    robot["arm"]["links"][0]["mass"] = 2e6
    with pytest.raises(ConfigError, match=r"arm.links\[0\].mass: 2000000.0 is greater than"):
        robot_from_dict(robot, "r.yaml")


def _shipped(name: str, edit: Callable[[dict], None]) -> Callable[[dict, dict], None]:
    """An edit of write_problem that takes problems/NAME.yaml (robot kept), then ``edit``."""
    data = yaml.safe_load((PROBLEMS / name).read_text())

    def e(p, r):
        p.update(copy.deepcopy(data), robot=p["robot"])
        edit(p)

    return e


@pytest.mark.parametrize(
    "name, edit, field, message",
    [  # ValueError: Maximum allowed size exceeded; OverflowError (34, 'Numerical result ...')
        (
            "kerb.yaml",
            lambda p: p["planner"].__setitem__("spacing", 1e-300),
            "planner.spacing",
            "1e-300 is less than the minimum of 0.001",
        ),
        (
            "rough.yaml",
            lambda p: p["terrain"]["generate"].__setitem__("correlation_length", 1e300),
            "terrain.generate.correlation_length",
            "1e+300 is greater than the maximum of 1000000.0",
        ),
        (  # a map of one cell, refused naming the generator ("rough(0.03 m, 0.4 m)")
            "rough.yaml",
            lambda p: p["terrain"]["generate"].__setitem__("resolution", 1e300),
            "terrain.generate.resolution",
            "1e+300 m is coarser than the map's size [20.0, 8.0] m",
        ),
    ],
)
def test_planner_spacing_and_generator_sizes_are_bounded(tmp_path, name, edit, field, message):
    with pytest.raises(ConfigError) as info:
        load_problem(write_problem(tmp_path, _shipped(name, edit)))
    assert (info.value.field, info.value.message) == (field, message)


def test_planned_poses_are_counted_as_sampled(tmp_path):
    from mmstab.paths.route import route_samples

    route = load_problem(write_problem(tmp_path, _shipped("kerb.yaml", lambda p: None))).route
    for spacing in (0.25, 0.3, 1e-3, 100.0):
        assert route.planned_poses(spacing) == len(route_samples(route.length, spacing))


def test_a_plain_npy_array_named_npz_is_one_line(tmp_path, capsys):
    with open(tmp_path / "g.npz", "wb") as fh:
        np.save(fh, np.zeros((40, 40)))  # TypeError: ndarray is no context manager
    path = _terrain_problem(tmp_path, {"file": "g.npz"})
    line = _refused(capsys, ["rest", str(path), "--pose", "0", "0", "0"])
    assert line.endswith("g.npz: a single .npy array, not an .npz archive")


def test_geotiff_tags_written_as_text_are_one_line(tmp_path, capsys):
    import tifffile

    tie = (33922, "d", 6, (0.0, 0.0, 0.0, -1.0, 1.0, 0.0), True)
    scale_text = (33550, "s", 0, "abc", True)  # ValueError: could not convert 'a'
    tifffile.imwrite(
        tmp_path / "g.tif", np.zeros((20, 20), np.float32), extratags=[scale_text, tie]
    )
    path = _terrain_problem(tmp_path, {"file": "g.tif"})
    line = _refused(capsys, ["rest", str(path), "--pose", "0", "0", "0"])
    assert line.endswith("g.tif: ModelPixelScaleTag: must hold numbers, got str")


def test_follow_refuses_a_garbage_recording_before_building_anything(tmp_path, capsys, monkeypatch):
    import mmstab.runs.online.run as run

    def build(*args, **kwargs):
        raise AssertionError("V and the roadmap were built before the recording was read")

    monkeypatch.setattr(run, "build_follower", build)
    bag = tmp_path / "run.bag"
    bag.write_bytes(b"\x89MCAP0\r\n" + b"\x01" * 40)  # 20 s of workspace build, then refused
    out = tmp_path / "out"
    line = _refused(
        capsys, ["follow", str(PROBLEMS / "rough.yaml"), "--bag", str(bag), "-o", str(out)]
    )
    assert "run.bag: not a readable recording" in line and not out.exists()
