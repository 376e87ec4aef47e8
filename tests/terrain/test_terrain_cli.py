"""``mmstab rest``, ``stability-map``, ``terrain export``; terrain problems; bad input -> exit 2."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
import yaml
from conftest import RAMP_YAML, ROBOT_YAML

from mmstab.cli import main
from mmstab.core.problem import load_problem
from mmstab.stability.static import robot_force_angle

KERB = {
    "generate": {
        "kind": "kerb",
        "seed": 0,
        "size": [3.0, 3.0],
        "resolution": 0.05,
        "height": 0.1,
        "distance": 0.5,
        "azimuth": 0.0,
    }
}
REST_KEYS = ["roll", "pitch", "z", "G_T_B", "contacts", "support_polygon", "mu", "flags"]
REST_KEYS += ["tilt", "friction", "slip_margin", "binding"]  # the slip limit
REST_KEYS += ["pose", "arm", "arm_q_rad", "flipper_angle_rad", "units"]  # the inputs, units


def write_problem(tmp_path, terrain, name="p.yaml"):
    data = yaml.safe_load(RAMP_YAML.read_text())
    data["robot"] = str(ROBOT_YAML)
    data["terrain"] = terrain
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return path


def run(*args):
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.run(
        [sys.executable, "-m", "mmstab", *map(str, args)], capture_output=True, text=True, env=env
    )


def test_rest_json_on_the_ramp_is_the_ramp(robot):
    out = run("rest", RAMP_YAML, "--pose", 0.2, -0.3, 0.7, "--json")
    assert out.returncode == 0, out.stderr
    d = json.loads(out.stdout)
    assert list(d) == REST_KEYS
    problem = load_problem(RAMP_YAML)
    from mmstab.terrain import roll_pitch

    pose = [0.2, -0.3, 0.7]
    assert (d["roll"], d["pitch"]) == pytest.approx(roll_pitch(problem.terrain, pose), abs=1e-12)
    np.testing.assert_allclose(d["G_T_B"], problem.terrain.G_T_B(pose), atol=1e-12)
    g = problem.terrain.gravity_body(pose)
    mu = robot_force_angle(robot, g, robot.arm_com(robot.stowed)).mu[0]
    assert d["mu"] == pytest.approx(mu, abs=1e-9)
    # the ramp's slope is the tilt; atan(0.7) - 0.1 rad of slip margin
    assert d["tilt"] == pytest.approx(0.1, abs=1e-12) and d["binding"] == "none"
    assert d["slip_margin"] == pytest.approx(np.arctan(0.7) - 0.1, abs=1e-12)
    assert np.shape(d["contacts"]) == (4, 3) and d["flags"] == []


def test_rest_on_a_kerb_with_an_arm_posture(tmp_path, capsys, robot):
    path = write_problem(tmp_path, KERB)
    assert main(["rest", str(path), "--pose", "0.2", "0", "0", "--json", "--arm", "stowed"]) == 0
    stowed = json.loads(capsys.readouterr().out)
    assert stowed["pitch"] > 0.1 and stowed["flags"] == []  # climbing the kerb
    q = ["1.0", "0.5", "-0.5", "0.0"]
    assert main(["rest", str(path), "--pose", "0.2", "0", "0", "--json", "--arm", *q]) == 0
    moved = json.loads(capsys.readouterr().out)
    assert moved["mu"] != pytest.approx(stowed["mu"])
    assert main(["rest", str(path), "--pose", "0.2", "0", "0"]) == 0
    assert "rest: roll" in capsys.readouterr().out


def test_export_round_trip_and_a_file_problem(tmp_path, capsys):
    kerb = write_problem(tmp_path, KERB, "kerb.yaml")
    assert main(["terrain", "export", str(kerb), "-o", str(tmp_path / "kerb.npz")]) == 0
    assert "terrain export: 61 x 61 cells" in capsys.readouterr().out
    file_problem = write_problem(tmp_path, {"file": "kerb.npz"}, "file.yaml")
    answers = []
    for p in (kerb, file_problem):
        assert main(["rest", str(p), "--pose", "0.1", "0.2", "0.3", "--json"]) == 0
        answers.append(json.loads(capsys.readouterr().out))
    assert answers[0] == answers[1]
    # the ramp sampled: z = y tan(slope)
    assert main(["terrain", "export", str(RAMP_YAML), "-o", str(tmp_path / "ramp.npz")]) == 0
    with np.load(tmp_path / "ramp.npz") as d:
        y = d["origin"][1] + d["resolution"] * np.arange(d["elevation"].shape[0])
        np.testing.assert_allclose(d["elevation"][:, 0], y * np.tan(0.1), atol=1e-12)


def test_stability_map_agrees_with_rest(tmp_path, capsys):
    path = write_problem(tmp_path, KERB)
    out = tmp_path / "map"
    assert (
        main(["stability-map", str(path), "-o", str(out), "--spacing", "0.4", "--headings", "4"])
        == 0
    )
    assert {"stability_map.png", "terrain_3d.png", "summary.json", "problem.yaml"} <= {
        p.name for p in out.iterdir()
    }
    with np.load(out / "stability_map.npz") as d:
        mu, x, y, h = d["mu"], d["x"], d["y"], d["headings"]
        np.testing.assert_allclose(d["worst"], mu.min(axis=2))
        np.testing.assert_allclose(d["best"], mu.max(axis=2))
    capsys.readouterr()
    iy, ix, k = 1, 2, 3
    assert main(["rest", str(path), "--pose", str(x[ix]), str(y[iy]), str(h[k]), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["mu"] == pytest.approx(mu[iy, ix, k], abs=1e-9)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["poses"] == mu.size


@pytest.mark.parametrize(
    ("terrain", "where"),
    [
        ({"file": "nowhere.npz"}, "terrain.file"),
        ({"file": "flat.stl", "resolution": 0.0}, "terrain.resolution"),
        ({"generate": {**KERB["generate"], "kind": "crater"}}, "terrain.generate.kind"),
        ({"generate": {**KERB["generate"], "height": "high"}}, "terrain.generate.height"),
        ({"slope": 0.1, "file": "x.npz"}, "terrain.slope"),
        # the size bounds read size and resolution before the terrain's schema (a KeyError)
        ({"generate": {"kind": "bumps", "seed": 3}}, "terrain.generate.size"),
        ({"generate": {**KERB["generate"], "resolution": "fine"}}, "terrain.generate.resolution"),
        ({"generate": {**KERB["generate"], "resolution": 0}}, "terrain.generate.resolution"),
        ({"generate": {**KERB["generate"], "size": [3.0]}}, "terrain.generate.size"),
        ({}, "terrain.slope"),
    ],
)
def test_bad_terrain_sections(tmp_path, capsys, terrain, where):
    path = write_problem(tmp_path, terrain)
    assert main(["rest", str(path), "--pose", "0", "0", "0"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and f"{path}: {where}" in err


def test_a_mesh_without_a_cell_size_names_the_problems_key(tmp_path, capsys):
    """Before: 'flat.stl: resolution: ...' (the key to add is the problem's)."""
    import trimesh

    box = trimesh.creation.box(extents=(6.0, 6.0, 0.2))
    box.export(tmp_path / "flat.stl")
    path = write_problem(tmp_path, {"file": "flat.stl"})
    assert main(["rest", str(path), "--pose", "0", "0", "0"]) == 2
    assert capsys.readouterr().err.strip() == (
        f"mmstab: error: {path}: terrain.resolution: a mesh (flat.stl) needs the cell size "
        "[m/cell] to rasterise it at"
    )
    path = write_problem(tmp_path, {"file": "flat.stl", "resolution": 0.1})
    assert main(["rest", str(path), "--pose", "0", "0", "0"]) == 0  # the box's top: flat


@pytest.mark.slow
def test_bad_files_and_poses_one_line_exit_2_nothing_written(tmp_path):
    import trimesh

    np.savez(
        tmp_path / "nan.npz", elevation=np.full((4, 4), np.nan), resolution=0.1, origin=[0.0, 0.0]
    )
    trimesh.Trimesh(np.zeros((3, 3)), np.zeros((0, 3), int)).export(tmp_path / "empty.ply")
    cases = [
        ({"file": "nan.npz"}, ["--pose", 0, 0, 0], "nan.npz: elevation: all cells are unknown"),
        ({"file": "empty.ply", "resolution": 0.1}, ["--pose", 0, 0, 0], "empty.ply: faces"),
        (KERB, ["--pose", 1.3, 0, 0], "is off the map"),
        (KERB, ["--pose", 0, 0, 0, "--arm", 1, 2], "--arm"),
    ]
    for i, (terrain, extra, message) in enumerate(cases):
        path = write_problem(tmp_path, terrain, f"bad{i}.yaml")
        out = run("rest", path, *extra)
        assert out.returncode == 2, out.stderr
        assert out.stderr.count("\n") == 1 and message in out.stderr, out.stderr
    path = write_problem(tmp_path, {"file": "nan.npz"}, "export.yaml")
    out = run("terrain", "export", path, "-o", tmp_path / "out" / "x.npz")
    assert out.returncode == 2 and not (tmp_path / "out").exists()


def test_shipped_terrain_problems_load(robot):
    from mmstab.terrain.heightmap_terrain import HeightmapTerrain

    root = RAMP_YAML.parent
    for name in ("kerb", "rough", "dem"):
        p = load_problem(root / f"{name}.yaml")
        assert isinstance(p.terrain, HeightmapTerrain)
        r = p.terrain.rest([0.0, 0.0, 0.3])
        assert r.converged[0]
        # the stages see it through the Terrain interface: gravity in the body at rest
        g = p.terrain.gravity_body([0.0, 0.0, 0.3])[0]
        np.testing.assert_allclose(g, r.G_T_B[0][:3, :3].T @ [0, 0, -9.81], atol=1e-12)
    assert (root / "terrains" / "bumps_ditch.tif").stat().st_size <= 1_000_000


def test_rest_takes_one_angle_per_joint_and_the_flipper_limits(capsys):
    """``--arm`` wants the robot's joint count (6 on ramp_6dof.yaml), ``--flipper`` its limits."""
    six = RAMP_YAML.parent / "ramp_6dof.yaml"
    q = ["0", "0.5", "-0.5", "0", "0.2", "0"]
    assert main(["rest", str(six), "--pose", "0.2", "0", "0", "--json", "--arm", *q]) == 0
    stowed = json.loads(capsys.readouterr().out)
    assert stowed["mu"] > 0 and abs(stowed["roll"] - 0.1) < 1e-9  # the 0.1 rad ramp
    for problem, extra, message in [
        (six, ["--arm", "0", "0.5", "-0.5", "0"], "--arm: expected 'stowed' or 6 finite angles"),
        (RAMP_YAML, ["--flipper", "5"], "--flipper: 5.0 rad is outside base.flippers.limits"),
    ]:
        out = run("rest", problem, "--pose", 0.2, 0, 0, *extra)
        assert out.returncode == 2, out.stderr
        assert out.stderr.count("\n") == 1 and message in out.stderr, out.stderr


def test_a_reader_that_leaves_early_stops_it_quietly():
    """``mmstab rest ... | head -1``: stdout closed before it writes -> exit 141, no traceback."""
    cmd = [sys.executable, "-m", "mmstab", "rest", str(RAMP_YAML), "--pose", "0.2", "0", "0"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    proc.stdout.close()  # the child needs a second to import: it writes into a closed pipe
    err = proc.stderr.read()
    assert proc.wait() == 141 and err == "", err
