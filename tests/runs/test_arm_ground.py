"""The arm against the ground where the body see-saws over a crest (mmstab.runs.arm_ground).

A roof ridge across the path, ``z = -k |x|``: a rigid base straddling it lies along the
slope its CoM is over (its bottom run along ``z = -k x`` on the far side, or ``z = k x``
on the near side), so between the samples either side of the CoM's crossing its rest turns
by ``2 atan(k)`` (a flip). Turned over the ridge (its weakest support edge) the base is
caught when its front meets the far slope: ``2 atan(k)`` again, the far side's rest.
"""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from conftest import ROOT

from mmstab.runs.arm_ground import FLIP, ArmGround, arm_ground_along, arm_ground_verdict
from mmstab.stability.rock import STEP
from mmstab.terrain import HeightmapTerrain
from mmstab.terrain.heightmap import Heightmap
from mmstab.terrain.rest import RestSettings

K = 0.1  # the ridge's slopes [-]: the rest flips by 2 atan(0.1) = 0.199 rad


def ridge(robot) -> HeightmapTerrain:
    res = 0.01
    x = np.arange(-1.5, 1.5 + 1e-9, res)
    X, _ = np.meshgrid(x, x)
    hm = Heightmap.build(-K * np.abs(X), res, [x[0], x[0]], "ridge")
    return HeightmapTerrain(hm, settings=RestSettings(compliance=0.0)).with_robot(robot)


def test_the_rest_flips_over_a_ridge_and_rocks_onto_the_far_slope(robot):
    terrain = ridge(robot)
    x = np.arange(-0.30, 0.301, 0.05)
    poses = np.c_[x, np.zeros_like(x), np.zeros_like(x)]
    q = np.broadcast_to(robot.stowed, (len(x), len(robot.stowed)))
    arm = arm_ground_along(robot, terrain, poses, q, FLIP)
    flip = 2 * np.arctan(K)
    # one pair of neighbours flips, by 2 atan(k); elsewhere the rest lies on one slope
    big = np.flatnonzero(arm.flip > FLIP)
    assert len(big) == 2 and big[1] == big[0] + 1, arm.flip
    assert arm.flip[big] == pytest.approx(flip, abs=0.01)
    assert np.delete(arm.flip, big).max() < 0.01
    # turned over the ridge: caught on the far slope, 2 atan(k) later (the near side's
    # sample; the far side's is turned back to the near slope)
    assert np.isfinite(arm.turn[big]).all()
    assert arm.turn[big] == pytest.approx(flip, abs=STEP)  # measured 0.1990, 0.2007 rad
    assert np.isnan(arm.rocked[np.delete(np.arange(len(x)), big)]).all()
    # on a plane slope the arm is as high over the ground as on the other: the rocked
    # attitude lies on the far slope, its height the rest's (22.1 cm, the stowed arm)
    assert arm.rocked[big] == pytest.approx(arm.rest[big], abs=0.001)
    assert np.ptp(arm.rest) < 1e-6 and arm.rest[0] > 0.05


def test_a_contact_is_where_the_arm_is_below_the_ground():
    s = np.arange(6) * 0.05
    rest = np.array([0.10, 0.08, 0.06, 0.07, 0.09, 0.10])
    rocked = np.array([np.nan, -0.01, -0.02, 0.03, np.nan, np.nan])
    turn = np.array([np.nan, 0.2, 0.3, 0.25, np.nan, np.nan])
    v = arm_ground_verdict(ArmGround(rest, rocked, turn, np.full(6, 0.1)), s, FLIP)
    assert v["contact"] and v["flips"] == 6 and v["rocked_samples"] == 3
    assert v["height_min_m"] == 0.06 and v["rocked_height_min_m"] == -0.02
    (x,) = v["stretches"]
    assert (x["start_s"], x["end_s"], x["at_s"]) == (0.05, 0.10, 0.10)
    assert x["worst"] == -0.02 and x["by"] == 0.02
    assert x["attitude"] == "rocked" and x["turn_rad"] == 0.3


@pytest.mark.slow
def test_route29_arm_meets_the_ground_where_the_body_rocks_over_a_crest(tmp_path):
    # route 29 of make validate-routes (12.4 deg slope, 3.5 cm bumps) planned with a 3 deg
    # attitude margin (the default before 12 deg): MuJoCo's forearm touches the ground at
    # 4.96 s, the body 0.2 rad off its rest over a crest

    from experiments.validate_routes import load_settings, route_problem
    from mmstab.app.api import plan as make_plan
    from mmstab.core.problem import load_problem
    from mmstab.runs.along import sample_spacing
    from mmstab.runs.arm_ground import arm_ground_record
    from mmstab.runs.high_centred import path_samples

    settings = load_settings(ROOT / "problems" / "validate_routes.yaml")
    path = tmp_path / "route29.yaml"
    data = route_problem(settings, 29)
    data["planner"] = {**data.get("planner", {}), "attitude_margin": 0.0524}
    path.write_text(yaml.safe_dump(data))
    problem = load_problem(path)
    plan = make_plan(problem)
    assert plan.accepted
    poses, s = path_samples(plan.path, sample_spacing(plan.terrain))
    record = arm_ground_record(plan.robot, plan.terrain, plan.path, plan.stage, poses, s)
    # with the planned postures: the rest flips by 0.149 rad at s 1.09 (16.4 -> 8.1 deg
    # of tilt); turned over the crest 0.32 rad, the arm is 2.1 cm in the ground there
    planned = record["planned"]
    assert planned["contact"]
    first = planned["stretches"][0]
    assert first["at_s"] == pytest.approx(1.09, abs=0.03)
    assert first["attitude"] == "rocked"
    assert -0.035 < first["worst"] < -0.01  # measured -0.021 m
    assert first["turn_rad"] == pytest.approx(0.32, abs=0.03)
    assert planned["height_min_m"] > 0.02  # at the rests: 3.2 cm (the planner's 5 at its poses)
    # the plan's posture reference has the arm elsewhere there: clear by 6.8 cm at worst
    assert not record["reference"]["contact"]
    assert record["reference"]["rocked_height_min_m"] > 0.05


@pytest.mark.slow
def test_route29_default_margin_keeps_the_arm_clear_turned_over_the_crests(tmp_path):
    # the same route with the default 12 deg attitude margin: the record's own rocking (the
    # body turned over each crest, up to 0.32 rad above) leaves the planned arm clear
    from experiments.validate_routes import load_settings, route_problem
    from mmstab.app.api import plan as make_plan
    from mmstab.core.problem import load_problem
    from mmstab.runs.along import sample_spacing
    from mmstab.runs.arm_ground import arm_ground_record
    from mmstab.runs.high_centred import path_samples

    settings = load_settings(ROOT / "problems" / "validate_routes.yaml")
    path = tmp_path / "route29.yaml"
    path.write_text(yaml.safe_dump(route_problem(settings, 29)))
    problem = load_problem(path)
    assert problem.section("planner")["attitude_margin"] == 0.21
    plan = make_plan(problem)
    assert plan.accepted
    poses, s = path_samples(plan.path, sample_spacing(plan.terrain))
    record = arm_ground_record(plan.robot, plan.terrain, plan.path, plan.stage, poses, s)
    planned = record["planned"]
    assert not planned["contact"] and planned["stretches"] == []
    assert planned["rocked_height_min_m"] > 0.1  # measured 11.8 cm (3 deg: -2.1 cm)
    assert planned["height_min_m"] > 0.1  # at the rests: 11.4 cm (3 deg: 3.2 cm)


def test_the_record_is_opt_in(tmp_path) -> None:
    import subprocess
    import sys

    from mmstab.core.defaults import SECTION_DEFAULTS
    from mmstab.runs.verdict_settings import VerdictSettings

    assert SECTION_DEFAULTS["physics"]["arm_over_crests"] is False
    assert VerdictSettings.from_sections({}, {}).arm_over_crests is False
    assert VerdictSettings.from_sections({}, {"arm_over_crests": True}).arm_over_crests is True
    data = yaml.safe_load((ROOT / "problems" / "rough.yaml").read_text())
    data["robot"] = str(ROOT / "problems" / "robots" / "cameleon.yaml")
    data.setdefault("physics", {})["arm_over_crests"] = 1.0
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data))
    proc = subprocess.run([sys.executable, "-m", "mmstab", "plan", str(path)],
                          capture_output=True, text=True)  # fmt: skip
    assert proc.returncode == 2
    line = proc.stderr.strip()
    assert "\n" not in line and "physics.arm_over_crests" in line
