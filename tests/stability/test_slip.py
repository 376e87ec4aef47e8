"""The slip limit: the friction cone of a rigid robot on its support."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml
from conftest import PROBLEMS, ROBOT_YAML, write_problem

from mmstab.cli import main
from mmstab.core.problem import load_problem
from mmstab.model.robot import load_robot
from mmstab.runs.verdict import describe_sliding, slip_verdict
from mmstab.stability.slip import binding_limit, slip_limit, terrain_slip
from mmstab.stability.stance import stance
from mmstab.terrain.base import DEFAULT_FRICTION
from mmstab.terrain.generators import generate
from mmstab.terrain.heightmap_terrain import HeightmapTerrain
from mmstab.terrain.ramp import Ramp

ROBOT = ROBOT_YAML
TINY = 1e-7  # [rad]


@pytest.mark.parametrize("friction", [0.3, 0.7, 1.0, 2.0])
def test_a_plane_slides_at_atan_friction_whatever_the_heading(friction):
    """Gravity on a plane of slope a: tangential g sin a, normal g cos a; slides past atan(mu)."""
    rng = np.random.default_rng(7)
    poses = np.c_[rng.uniform(-2, 2, (50, 2)), rng.uniform(-np.pi, np.pi, 50)]
    edge = math.atan(friction)
    holds = terrain_slip(Ramp(edge - TINY, friction), poses)
    slides = terrain_slip(Ramp(edge + TINY, friction), poses)
    assert not holds.slides.any() and slides.slides.all()
    np.testing.assert_allclose(holds.tilt, edge - TINY, rtol=0, atol=1e-12)
    np.testing.assert_allclose(slides.margin, -TINY, rtol=0, atol=1e-12)
    # the cone by hand: |g_t| against friction * g_n
    g = 9.81
    for a, expect in ((edge - TINY, False), (edge + TINY, True)):
        tangential, normal = g * math.sin(a), g * math.cos(a)
        assert (tangential > friction * normal) == expect


def test_upside_down_and_level():
    s = slip_limit([[0, 0, -9.81], [0, 0, 9.81], [9.81, 0, 0]], 0.7)
    np.testing.assert_allclose(s.tilt, [0, np.pi, np.pi / 2], atol=1e-15)
    assert list(s.slides) == [False, True, True] and s.critical_tilt == math.atan(0.7)
    assert binding_limit(0.8, 0.6) == "slip" and binding_limit(0.6, 0.8) == "tip"


def test_stance_on_the_ramp_says_which_limit_binds():
    robot = load_robot(ROBOT)
    edge = math.atan(0.5)
    below = stance(Ramp(edge - 1e-6, 0.5), robot, [0.0, 0.0, 0.3])
    above = stance(Ramp(edge + 1e-6, 0.5), robot, [0.0, 0.0, 0.3])
    assert "slides" not in below.flags and below.binding == "none" and below.mu > 0
    assert "slides" in above.flags and above.binding == "slip"
    assert above.tilt == pytest.approx(edge + 1e-6, abs=1e-12)
    assert above.slip_margin == pytest.approx(-1e-6, abs=1e-12)
    steep = stance(Ramp(1.15, 0.5), robot, [0.0, 0.0, 0.0])  # rolled past its tip angle
    assert steep.mu < 0 and steep.binding == "both"
    assert set(below.to_json()) >= {"tilt", "friction", "slip_margin", "binding"}


@pytest.mark.parametrize("slope", [0.2, 0.55])
def test_a_tilted_plane_heightmap_gives_the_ramps_answer(slope):
    """A generated plane rising along +y: rest anywhere on it tilts the robot by the slope."""
    robot = load_robot(ROBOT)
    hm = generate(
        {"kind": "plane", "seed": 0, "size": [8.0, 8.0], "resolution": 0.05, "slope": slope,
         "azimuth": math.pi / 2}
    )  # fmt: skip
    ground = HeightmapTerrain(hm, friction=0.6).with_robot(robot)
    rng = np.random.default_rng(3)
    poses = np.c_[rng.uniform(-1.5, 1.5, (12, 2)), rng.uniform(-np.pi, np.pi, 12)]
    on_map = terrain_slip(ground, poses)
    on_ramp = terrain_slip(Ramp(slope, 0.6), poses)
    np.testing.assert_allclose(on_map.tilt, on_ramp.tilt, rtol=0, atol=1e-6)
    assert list(on_map.slides) == list(on_ramp.slides) == [slope > math.atan(0.6)] * 12
    for p in poses[:3]:
        st = stance(ground, robot, p)
        assert st.tilt == pytest.approx(slope, abs=1e-6)


def test_random_rough_maps_tilt_of_the_resting_pose():
    """Independent: the tilt is the angle of the rest pose's z_B from G's z."""
    robot = load_robot(ROBOT)
    for seed in (1, 2):
        hm = generate(
            {"kind": "rough", "seed": seed, "size": [6.0, 6.0], "resolution": 0.05,
             "amplitude": 0.04, "correlation_length": 0.4, "slope": 0.6, "azimuth": 0.3,
             "hill_height": 0.0, "hill_radius": 1.0}
        )  # fmt: skip
        ground = HeightmapTerrain(hm, friction=0.7).with_robot(robot)
        rng = np.random.default_rng(seed)
        poses = np.c_[rng.uniform(-1.2, 1.2, (20, 2)), rng.uniform(-np.pi, np.pi, 20)]
        r = ground.rest(poses, strict=False)
        ok = np.isfinite(r.z)
        s = terrain_slip(ground, poses[ok])
        tilt = np.arccos(np.clip(r.G_T_B[ok][:, 2, 2], -1, 1))
        np.testing.assert_allclose(s.tilt, tilt, rtol=0, atol=1e-9)
        np.testing.assert_array_equal(s.slides, tilt > math.atan(0.7))
        assert 0 < s.slides.sum() < ok.sum()  # both answers occur on these maps


def test_slip_verdict_lists_the_sliding_poses():
    poses = [[0, 0, 0], [1, 0, 1]]
    v = slip_verdict(Ramp(0.5, 0.5), poses)
    assert v["slides"] and [b["index"] for b in v["sliding_poses"]] == [0, 1]
    assert v["tilt_max"] == pytest.approx(0.5) and v["critical_tilt"] == math.atan(0.5)
    assert "2 of 2 poses" in describe_sliding(v, 2)
    assert not slip_verdict(Ramp(0.5, 0.6), poses)["slides"]


def _friction(value):
    def edit(p, r):
        p["terrain"]["friction"] = value

    return edit


def test_friction_from_the_problem_file(tmp_path, capsys):
    assert load_problem(write_problem(tmp_path)).terrain.friction == DEFAULT_FRICTION
    assert load_problem(write_problem(tmp_path, _friction(1.1))).terrain.friction == 1.1
    for bad in (0, -0.1, 2.5, "x"):
        path = write_problem(tmp_path, _friction(bad))
        assert main(["rest", str(path), "--pose", "0", "0", "0"]) == 2
        err = capsys.readouterr().err
        assert "terrain.friction" in err and str(path) in err and "Traceback" not in err


def test_friction_on_a_heightmap_problem(tmp_path):
    path = tmp_path / "p.yaml"
    data = yaml.safe_load((PROBLEMS / "rough.yaml").read_text())
    data["terrain"]["friction"] = 0.4
    data["robot"] = str(PROBLEMS / data["robot"])
    path.write_text(yaml.safe_dump(data))
    assert load_problem(path).terrain.friction == 0.4


def test_rest_command_reports_the_slip_limit(tmp_path, capsys):
    import json

    def steep(p, r):
        p["terrain"].update(slope=0.6, friction=0.6)

    path = write_problem(tmp_path, steep)
    assert main(["rest", str(path), "--pose", "0", "0", "0", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["binding"] == "slip" and "slides" in d["flags"]
    assert d["slip_margin"] == pytest.approx(math.atan(0.6) - 0.6, abs=1e-12)


def test_plan_where_the_tracks_slide_exits_4_unless_allowed(tmp_path, capsys, monkeypatch):
    """20 deg slope, friction 0.3 (16.7 deg): the plan holds against tipping but slides."""

    def edit(p, r):
        p["terrain"].update(slope=0.35, friction=0.3)
        p["workspace"]["grid"] = [10, 8, 8, 8]
        p["planner"]["poses"] = 4

    monkeypatch.chdir(tmp_path)
    path = write_problem(tmp_path, edit)
    out = tmp_path / "plan"
    assert main(["plan", str(path), "-o", str(out)]) == 4
    said = capsys.readouterr()
    err = [x for x in said.err.splitlines() if x.startswith("mmstab:")]
    # the lap's one verdict per limit, as a route's: the whole lap slides
    (line,) = [x for x in said.out.splitlines() if x.startswith("plan: verdicts along")]
    assert "(every 5 cm): tip: holds; slide: slides at s = 0.00-" in line
    assert len(err) == 1 and err[0].startswith("mmstab: slides: ") and "--allow-sliding" in err[0]
    import json

    s = json.loads((out / "summary.json").read_text())
    assert s["stability"]["stable"] and s["slip"]["slides"]
    # the lap starts at rest on its first pose; it passes the others, and every sample
    # around the lap is beyond the cone: one stretch, the whole lap
    assert [b["index"] for b in s["slip"]["sliding_poses"]] == [0] and len(s["poses"]) == 4
    assert [b["index"] for b in s["slip"]["passed_poses"]] == [1, 2, 3]
    (lap,) = s["slip"]["stretches"]
    dense = s["along_path"]
    assert lap["start_s"] == 0.0 and lap["worst"] == pytest.approx(0.35, abs=1e-9)
    assert lap["end_s"] == pytest.approx(dense["spacing_m"] * (dense["samples"] - 1))
    assert lap["slide_m"] is None  # at rest on it at the start: it never stops
    assert s["slip"]["tilt_max"] == pytest.approx(0.35, abs=1e-12)
    assert main(["plan", str(path), "-o", str(out), "--allow-sliding"]) == 0
    assert "mmstab: warning: the tracks would slide" in capsys.readouterr().err


@pytest.mark.slow
def test_track_where_the_tracks_slide_exits_4_unless_allowed(tmp_path, capsys, monkeypatch):
    """The tracked run's base poses, checked like the plan's (20 deg slope, friction 0.3)."""
    import json

    def edit(p, r):
        p["terrain"].update(slope=0.35, friction=0.3)
        p["workspace"]["grid"] = [10, 8, 8, 8]
        p["planner"]["poses"] = 4
        p["controller"]["duration"] = 0.2

    monkeypatch.chdir(tmp_path)
    path = write_problem(tmp_path, edit)
    out = tmp_path / "track"
    assert main(["track", str(path), "-o", str(out)]) == 4
    assert "mmstab: slides: " in capsys.readouterr().err
    s = json.loads((out / "summary.json").read_text())
    assert s["tipped"] is None and s["slip"]["slides"]
    assert s["slip"]["tilt_max"] == pytest.approx(0.35, abs=1e-12)
    assert main(["track", str(path), "-o", str(out), "--allow-sliding"]) == 0
