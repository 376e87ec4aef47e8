"""Route 4 of ``make validate-routes``: a ditch's far wall climbed with the arm swung back.

Seed 5104: an 18 cm deep, 80 cm wide ditch crossed square on a 1.4° map. The plan used to
accept it (its poses and the samples between them all hold) and MuJoCo overturned the robot
backwards on the far wall while the arm's reference swung it over the rear.
"""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from conftest import ROOT

import mmstab
from experiments.validate_routes import load_settings, route_problem
from mmstab import app
from mmstab.outputs.routes import route_summary
from mmstab.outputs.verify import plan_verdict_of
from mmstab.planner import route_risk
from mmstab.runs.along import sample_spacing
from mmstab.runs.climb_out import climb_out_verdict, reference_coms
from mmstab.runs.high_centred import path_samples
from mmstab.stability.climb_out import climb_out, pivot_rest

#: The 3 deg attitude margin these routes were planned and refereed with (the default before
#: 12 deg): the plans whose physics this module checks.
THREE_DEG = {"attitude_margin": 0.0524}


@pytest.fixture(scope="module")
def route4(tmp_path_factory):
    settings = load_settings(ROOT / "problems" / "validate_routes.yaml")
    data = route_problem(settings, 4)
    data["planner"] = {**data.get("planner", {}), **THREE_DEG}
    assert data["terrain"]["generate"]["features"]["ditch"]["depth"] == pytest.approx(0.183, 1e-3)
    path = tmp_path_factory.mktemp("route4") / "route04.yaml"
    path.write_text(yaml.safe_dump(data))
    problem = mmstab.load_problem(path)
    return problem, app.plan(problem)


def test_route4_is_refused_where_it_climbs_the_far_wall(route4) -> None:
    problem, plan = route4
    summary = route_summary(problem, plan, route_risk(plan, 0.0))
    assert plan_verdict_of(summary) == "tips"  # was "accepted"
    v = summary["verdicts"]["tip"]
    assert v["verdict"] == "tips" and v["unsafe"]
    out = summary["stability"]["climb_out"]
    assert out["overturns"] and len(out["stretches"]) == 1
    where = out["stretches"][0]["start_s"]
    # the far wall: the rear axle 0.35 m behind the body origin, the ditch 1.04 m ahead of
    # the start along the route, its far edge 0.40 m past its centre
    assert 1.44 + 0.35 - 0.15 < where < 1.44 + 0.35 + 0.05
    assert [round(c["start_s"], 1) for c in out["climbs"]][0] == 1.1  # the nose up the wall


def test_route4_postures_alone_cross_the_edge_its_reference_does_not(route4) -> None:
    """With the planned postures alone (before and after each sample) the CoM passes the far
    edge; on the arm's reference it does not: the move from pose 3 to pose 4 turns the turret
    4.71 -> 0 rad the long way, over the rear, while the robot climbs the wall."""
    problem, plan = route4
    robot = problem.robot
    poses, s = path_samples(problem.route, sample_spacing(problem.terrain))
    rest = pivot_rest(robot, problem.terrain, poses)
    k = np.searchsorted(plan.s, s, side="left").clip(0, len(plan.s) - 1)
    ends = robot.overall_com(robot.arm_com(np.asarray(plan.postures)))
    both = np.stack([ends[np.maximum(k - 1, 0)], ends[k]], axis=1)
    assert not climb_out(robot, rest, both).overturns.any()
    coms = reference_coms(robot, plan, problem.route, s)
    assert climb_out(robot, rest, coms).overturns.any()
    # on the wall (s = 1.5-1.65 m) the reference's CoM is 7 cm behind both postures it joins
    wall = (s > 1.5) & (s < 1.65)
    assert coms[wall, 0].min() < min(ends[3, 0], ends[4, 0]) - 0.065
    # the reference at the planned poses is the planned postures
    np.testing.assert_allclose(reference_coms(robot, plan, problem.route, plan.s), ends, atol=1e-9)
    assert climb_out_verdict(robot, problem.terrain, problem.route, poses, s, plan)["overturns"]
