"""What holds a robot that stalls in MuJoCo: its chassis on the ground, or its tracks.

The ground is a user's map written with NumPy (a 12° slope, egg-box bumps, a 12 cm deep and
0.5 m wide ditch across the route), the robot the user's scout with 6 cm flippers (its
slow joints: the base waits at the start while the arm unfolds). Its 0.6 m tracks dip nose
first into the ditch and its chassis (3 cm above the tracks' bottom, 0.55 m long) comes
down on the rims with the tracks hanging between.
"""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest
import yaml
from conftest import SCOUT

from mmstab.cli import main


def _user_ditch(folder) -> None:
    """The map (seeded bumps' noise), the robot and its route, as files."""
    rng = np.random.default_rng(20261130)
    res = 0.05
    x, y = np.arange(200) * res - 2.0, np.arange(140) * res - 3.5
    X, Y = np.meshgrid(x, y)
    z = np.tan(np.radians(12)) * (0.6 * X + 0.8 * Y)
    z += 0.03 * np.sin(2 * np.pi * X / 1.1) * np.sin(2 * np.pi * Y / 0.9)
    z += 0.004 * rng.standard_normal(z.shape)
    z -= 0.12 * ((X > 2.0) & (X < 2.5))
    z += 0.06 * (X > 5.0)
    np.savez(folder / "ground.npz", elevation=z, resolution=res, origin=np.array([x[0], y[0]]))
    robot = copy.deepcopy(SCOUT)
    robot["base"]["flippers"]["length"] = 0.06
    (folder / "scout.yaml").write_text(yaml.safe_dump(robot))
    # the reference gives up after 2 s of waiting (10 s by default): the same stall, sooner
    route = {"robot": "scout.yaml", "terrain": {"file": "ground.npz"},
             "path": {"waypoints": [[0.0, 0.0], [4.0, 0.0], [6.0, 1.5]], "speed": 0.25,
                      "turn_radius": 0},
             "physics": {"governor": {"slow": 0.25, "stop": 0.5, "wait_limit": 2.0}}}  # fmt: skip
    (folder / "route.yaml").write_text(yaml.safe_dump(route))


@pytest.mark.mujoco
def test_a_robot_high_centred_on_a_ditch_stalls_high_centred(tmp_path, capsys) -> None:
    _user_ditch(tmp_path)
    out = tmp_path / "out"
    status = main(["simulate", str(tmp_path / "route.yaml"), "-o", str(out)])
    stall = json.loads((out / "summary.json").read_text())["stalled"]
    assert stall is not None and stall["cause"] == "high-centred"
    assert 2.0 < stall["s_m"] < 2.5  # the body origin over the ditch
    assert stall["chassis_resting"] >= 0.5 and stall["touching"]["chassis"] >= 0.5
    assert stall["touching"]["arm"] == 0.0
    err = capsys.readouterr().err
    assert f"stalled, high-centred at s = {stall['s_m']:.2f} m" in err
    # the arm on its plan, the robot does not slide downhill on the way; a stall alone is a
    # warning, not an unsafe verdict (docs/cli.md)
    summary = json.loads((out / "summary.json").read_text())
    assert not summary["slid"] and summary["downhill_drift_max_m"] < 0.05
    # one record: the plan's (the path rested every 5 cm with the planned arm), which does
    # not see this stall: MuJoCo's robot yaws 19 deg off its heading in the ditch first
    import mmstab

    planned = mmstab.plan(mmstab.load_problem(tmp_path / "route.yaml")).high_centred
    assert summary["high_centred"] == json.loads(json.dumps(planned))
    assert "planned arm" in planned["criterion"] and not planned["high_centred"]
    wait = summary["approach"]["base_wait_s"]  # the summary has the note's wait
    assert wait > 5.0 and f"the base waits {wait:.1f} s" in err and status == 0
