"""The skid-steer model against the whole robot in MuJoCo (docs/skid.md).

The robot, arm stowed, driven at constant track speeds on a MuJoCo ramp (friction 0.7): its
mean twist against mmstab's steady twist for the same belt speeds, gravity and CoM. The model
is the Coulomb balance of the belts' sliding contacts; MuJoCo's tracks are rows of sphere
wheels on springs. The bounds are those of ``make skid``'s whole grid.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
import yaml
from conftest import ROOT

pytestmark = pytest.mark.mujoco
pytest.importorskip("mujoco")

from mmstab.physics.skid_sim import measure_twist  # noqa: E402
from mmstab.stability.skid import skid_twist, track_patch  # noqa: E402

MU = 0.7


def both(robot, slope_deg: float, heading_deg: float, v: float, w: float):
    b = robot.base.tracks.separation
    belts = (v - w * b / 2, v + w * b / 2)
    m = measure_twist(robot, np.radians(slope_deg), np.radians(heading_deg), belts, MU,
                      duration=1.5)  # fmt: skip
    com = robot.overall_com(robot.arm_com(robot.stowed))
    p = skid_twist(track_patch(robot), m.gravity_body, com, belts, MU)
    down = m.gravity_body[:2] / np.linalg.norm(m.gravity_body[:2])

    def downhill(velocity, yaw_rate):  # the CoM's velocity beyond the commanded (v, 0)
        at_com = np.asarray(velocity) + yaw_rate * np.r_[-com[1], com[0]]
        return float((at_com - [v, 0.0]) @ down)

    mj = (downhill(m.velocity_body, m.yaw_rate), m.yaw_rate)
    return mj, (downhill(p.velocity_body[0], p.yaw_rate[0]), p.yaw_rate[0])


@pytest.mark.parametrize("slope, heading, v, w", [(25.0, 0.0, 0.0, 0.4), (31.5, 0.0, 0.25, 0.3),
                                                  (20.0, 45.0, 0.25, -0.3)])  # fmt: skip
def test_slide_per_radian_and_turn_rate_match_mujoco(robot, slope, heading, v, w):
    (mj_down, mj_rate), (down, rate) = both(robot, slope, heading, v, w)
    assert mj_down > 0.02 and down > 0.02  # both slide downhill while they turn
    per_radian = (down / abs(rate)) / (mj_down / abs(mj_rate))
    assert 0.75 < per_radian < 1.35
    assert 0.8 < rate / mj_rate < 1.45  # make skid: 5-95 % 0.77-1.40, median 1.19


def test_nose_up_pivot_slides_without_turning(robot):
    (mj_down, mj_rate), (down, rate) = both(robot, 25.0, 90.0, 0.0, 0.4)
    assert abs(mj_rate) < 0.05 and abs(rate) < 0.01
    assert down == pytest.approx(mj_down, rel=0.15)  # the belts pull opposite ways: ~8 cm/s
    assert mj_down > 0.06


def test_straight_on_a_side_slope_does_not_slide(robot):
    (mj_down, mj_rate), (down, rate) = both(robot, 31.5, 0.0, 0.25, 0.0)
    assert abs(mj_down) < 0.005 and abs(down) < 1e-3
    assert abs(mj_rate) < 0.01 and abs(rate) < 1e-3


def test_make_skid_small_grid(tmp_path):
    settings = yaml.safe_load((ROOT / "problems" / "skid.yaml").read_text())
    settings.pop("rough_ground")  # the grid alone (test_skid_rough.py runs the section)
    settings |= {"problem": str(ROOT / "problems" / "rough.yaml"), "slopes_deg": [20.0],
                 "headings_deg": [0.0], "sim": {"settle": 0.5, "transient": 0.5, "duration": 1.0},
                 "commands": {"pivot_left": [0.0, 0.4], "straight": [0.25, 0.0]}}  # fmt: skip
    path = tmp_path / "skid.yaml"
    path.write_text(yaml.safe_dump(settings))
    env = {**os.environ, "MPLBACKEND": "Agg"}
    cmd = [sys.executable, "-m", "experiments.skid", str(path), "-o", str(tmp_path / "out")]
    done = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["cases"] == 2 and s["turning_cases"] == 1
    assert 0.75 < s["slide_per_radian_ratio_median"] < 1.35
    # driven straight at 20 deg the model's belts creep by their shear, a few mm/s
    assert 1e-3 < s["straight_downhill_max_m_s"]["model"] < 0.01
    assert (tmp_path / "out" / "skid.png").stat().st_size > 10_000


def test_make_skid_bad_settings_exit_2(tmp_path):
    path = tmp_path / "skid.yaml"
    path.write_text(yaml.safe_dump({"problem": "rough.yaml", "friction": 0.7, "slopes_deg": [],
                                    "headings_deg": [0], "commands": {}, "sim": {}}))  # fmt: skip
    cmd = [sys.executable, "-m", "experiments.skid", str(path), "-o", str(tmp_path / "o")]
    done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and "slopes_deg" in done.stderr and str(path) in done.stderr
    assert not (tmp_path / "o").exists()
