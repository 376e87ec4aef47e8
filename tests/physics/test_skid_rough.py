"""The skid-steer model against MuJoCo on rough ground (experiments.skid_rough).

``make skid``'s ``rough_ground`` section drives the robot at poses along ``rough.yaml``'s
route over its heightfield. Checked here: a heightmap that is a plane gives the ramp's
twist; the uphill / downhill classification of a turn by hand; the model's side of each case
recomputed from the case's own gravity; the experiment end to end on a coarse spacing; a bad
section exits 2 naming its field.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import ROOT

pytestmark = pytest.mark.mujoco
pytest.importorskip("mujoco")

from experiments.skid_rough import _case, route_poses  # noqa: E402
from mmstab.core.defaults import SECTION_DEFAULTS  # noqa: E402
from mmstab.physics.skid_sim import MeasuredTwist, measure_twist, measure_twist_at  # noqa: E402
from mmstab.stability.skid import skid_twist, track_patch  # noqa: E402
from mmstab.terrain.factory import ramp_heightmap  # noqa: E402
from mmstab.terrain.heightmap_terrain import HeightmapTerrain  # noqa: E402
from mmstab.terrain.ramp import Ramp  # noqa: E402


@pytest.mark.parametrize("v, w", [(0.25, 0.3), (0.0, 0.4)])
def test_a_plane_heightmap_gives_the_ramps_twist(robot, v, w):
    """The same 31.5 deg slope as a MuJoCo plane and as a heightfield: one twist (to 3 %)."""
    slope, b = 0.55, robot.base.tracks.separation
    belts = (v - w * b / 2, v + w * b / 2)
    ground = HeightmapTerrain(ramp_heightmap(Ramp(slope, 0.7), (6.0, 6.0), 0.05), friction=0.7)
    on_map = measure_twist_at(robot, ground.with_robot(robot), (0.0, 0.0, 0.0), belts,
                              duration=1.0)  # fmt: skip
    on_ramp = measure_twist(robot, slope, 0.0, belts, 0.7, duration=1.0)
    assert on_map.yaw_rate == pytest.approx(on_ramp.yaw_rate, rel=0.03)
    np.testing.assert_allclose(on_map.velocity_body, on_ramp.velocity_body, atol=2e-3)
    np.testing.assert_allclose(on_map.gravity_body, on_ramp.gravity_body, atol=0.02)
    assert abs(on_map.velocity_body[1]) > 0.03  # it does slide downhill while it turns


def test_turns_are_named_by_the_side_they_swing_the_nose_to(robot):
    """Left side uphill (gravity in B toward -y): a left turn swings the nose uphill."""
    g = 9.81 * np.array([0.0, -np.sin(0.4), -np.cos(0.4)])
    twist = MeasuredTwist(np.array([0.25, -0.01]), 0.1, g)
    model = skid_twist(track_patch(robot), g, [0.0, 0.0, 0.1], (0.2, 0.3), 0.7)
    c = (0.06, 0.0)  # the CoM's x, y in B
    left = _case(1.0, (0, 0, 0), "arc_left", (0.25, 0.2), twist, model, c)
    right = _case(1.0, (0, 0, 0), "arc_right", (0.25, -0.2), twist, model, c)
    straight = _case(1.0, (0, 0, 0), "straight", (0.25, 0.0), twist, model, c)
    assert (left["toward"], right["toward"], straight["toward"]) == ("uphill", "downhill", None)
    assert left["tilt_deg"] == pytest.approx(np.degrees(0.4))
    # at the CoM: (0.25, -0.01) + 0.1 rad/s x (0.06, 0) = (0.25, -0.004), less (0.25, 0)
    assert left["mujoco"]["downhill"] == pytest.approx(0.004)
    level = MeasuredTwist(np.array([0.25, 0.0]), 0.1, np.array([0.0, 0.0, -9.81]))
    assert _case(1.0, (0, 0, 0), "arc_left", (0.25, 0.2), level, model, c)["toward"] is None


def test_route_poses_are_spaced_along_the_path():
    from mmstab.core.problem import load_problem

    problem = load_problem(ROOT / "problems" / "rough.yaml")
    s, poses = route_poses(problem, 2.0)
    assert s[0] == 0.0 and np.all(np.diff(s) == pytest.approx(2.0, abs=0.01))
    steps = np.linalg.norm(np.diff(poses[:, :2], axis=0), axis=1)
    assert np.all(steps <= np.diff(s) + 1e-9) and np.all(steps > 1.5)  # a chord <= its arc


def _small_settings(tmp_path: Path, rough: dict) -> Path:
    settings = yaml.safe_load((ROOT / "problems" / "skid.yaml").read_text())
    settings |= {"problem": str(ROOT / "problems" / "rough.yaml"), "slopes_deg": [20.0],
                 "headings_deg": [0.0], "sim": {"settle": 0.5, "transient": 0.5, "duration": 1.0},
                 "commands": {"arc_left": [0.25, 0.3]}, "rough_ground": rough}  # fmt: skip
    path = tmp_path / "skid.yaml"
    path.write_text(yaml.safe_dump(settings))
    return path


def _run(path: Path, out: Path) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "experiments.skid", str(path), "-o", str(out)]
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)


@pytest.mark.slow
def test_make_skid_rough_ground_small(tmp_path, robot):
    rough = {"problem": str(ROOT / "problems" / "rough.yaml"), "spacing": 6.0,
             "commands": {"straight": [0.25, 0.0], "arc_left": [0.25, 0.3]}}  # fmt: skip
    done = _run(_small_settings(tmp_path, rough), tmp_path / "out")
    assert done.returncode == 0, done.stderr
    assert "rough ground: 6 cases" in done.stdout
    assert (tmp_path / "out" / "rough.png").stat().st_size > 10_000
    r = json.loads((tmp_path / "out" / "summary.json").read_text())["rough_ground"]
    cases = r["all_cases"]
    assert r["cases"] == len(cases) == 6 and [c["s_m"] for c in cases[::2]] == pytest.approx(
        [0.0, 6.0, 12.0], abs=0.01
    )
    com = robot.overall_com(robot.arm_com(robot.stowed))
    b = robot.base.tracks.separation
    for c in cases:  # the model's side, again from the case's own gravity
        v, w = c["speed"], c["yaw_rate_commanded"]
        p = skid_twist(track_patch(robot), c["gravity_body"], com, (v - w * b / 2, v + w * b / 2),
                       0.7, SECTION_DEFAULTS["physics"]["shear_modulus"])  # fmt: skip
        assert c["model"]["holds"] == bool(p.holds[0])
        if c["model"]["holds"]:
            assert c["model"]["yaw_rate"] == pytest.approx(float(p.yaw_rate[0]), abs=1e-12)
    held_straight = [c for c in cases if c["command"] == "straight" and c["model"]["holds"]]
    assert r["straight"]["poses"] == len(held_straight)
    assert r["straight"]["mujoco_downhill_max_m_s"] == pytest.approx(
        max(c["mujoco"]["downhill"] for c in held_straight)
    )
    turning = [c for c in cases if c["toward"] and c["model"]["holds"]
               and abs(c["mujoco"]["yaw_rate"]) >= 0.05]  # fmt: skip

    def per_rad(t):
        return t["downhill"] / abs(t["yaw_rate"])

    ratios = [per_rad(c["model"]) / per_rad(c["mujoco"]) for c in turning]
    per_radian = r["slide_per_radian_model_over_mujoco"]
    assert per_radian["cases"] == len(turning) > 0
    assert per_radian["median"] == pytest.approx(float(np.median(ratios)))


def test_a_bad_rough_ground_section_exits_2_naming_it(tmp_path):
    rough = {"problem": "rough.yaml", "spacing": -1.0, "commands": {"straight": [0.25, 0.0]}}
    done = _run(_small_settings(tmp_path, rough), tmp_path / "out")
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "rough_ground.spacing" in lines[0] and "skid.yaml" in lines[0]
    assert not (tmp_path / "out").exists()
