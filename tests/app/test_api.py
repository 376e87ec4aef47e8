"""The code-first API: plan and track on objects agree with the problem files and the CLI."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from conftest import RAMP_YAML, ROBOT_YAML, write_problem
from test_along import turn_problem

import mmstab
from mmstab.app.api import PathPlan, Tracked
from mmstab.app.settings import Settings
from mmstab.planner import Plan, RoutePlan, route_risk


@pytest.fixture(scope="module")
def ramp_plans():
    """ramp.yaml planned from the file and from objects built here from its numbers."""
    problem = mmstab.load_problem(RAMP_YAML)
    raw = yaml.safe_load(RAMP_YAML.read_text())
    c = raw["path"]
    robot = mmstab.load_robot(ROBOT_YAML)
    terrain = mmstab.Ramp(raw["terrain"]["slope"])
    circle = mmstab.CirclePath(tuple(c["center"]), c["radius"], c["start_angle"], c["direction"])
    settings = Settings.from_problem(problem)
    return mmstab.plan(problem), mmstab.plan(robot, terrain, circle, settings)


def test_a_circle_planned_in_code_is_the_problem_files_plan(ramp_plans):
    from_file, in_code = ramp_plans
    assert isinstance(in_code, PathPlan) and isinstance(in_code.stage, Plan)
    for key in ("poses", "target_com", "postures", "mu_planned", "mu_realised", "mu_stowed",
                "mu_removed", "s", "fractions"):  # fmt: skip
        np.testing.assert_allclose(getattr(in_code, key), getattr(from_file, key), atol=1e-12)
    assert in_code.verdicts == from_file.verdicts
    assert in_code.accepted and in_code.exit_status == 0
    # the arc lengths: the lap's fractions of the circle's circumference (2 pi 1.5 m)
    np.testing.assert_allclose(in_code.s, 2 * np.pi * 1.5 * in_code.fractions, atol=1e-12)
    # mu_realised recomputed independently from the posture (static force-angle, plane)
    g = in_code.terrain.gravity_body(in_code.poses)
    com = in_code.robot.arm_com(in_code.postures)
    mu = mmstab.robot_force_angle(in_code.robot, g, com).mu
    np.testing.assert_allclose(in_code.mu_realised, mu, atol=1e-9)


def test_plan_verdicts_match_the_cli_exit_status_on_a_steep_ramp(tmp_path, monkeypatch):
    """69 deg: poses tip (exit 3); with tipping allowed the tracks slide (exit 4)."""
    from mmstab.cli import main

    def edit(p, r):
        p["terrain"]["slope"] = 1.2
        p["workspace"]["grid"] = [8, 8, 8, 8]
        p["planner"]["poses"] = 4

    path = write_problem(tmp_path, edit)
    monkeypatch.chdir(tmp_path)
    plan = mmstab.plan(mmstab.load_problem(path))
    assert main(["plan", str(path), "-o", str(tmp_path / "o")]) == plan.exit_status == 3
    assert not plan.accepted and "tip" in plan.unsafe and "slide" in plan.unsafe
    assert plan.verdicts["tip"]["verdict"] == "tips" and plan.stability["mu_min"] <= 0
    assert main(["plan", str(path), "-o", str(tmp_path / "o"), "--allow-unstable"]) == 4


def test_a_route_in_code_slides_where_the_cli_exits_4(tmp_path, monkeypatch):
    """The sliding pivot of test_along: the API's verdict is the command's exit status."""
    from mmstab.cli import main

    path = turn_problem(tmp_path)
    problem = mmstab.load_problem(path)
    raw = yaml.safe_load(path.read_text())["path"]
    robot = mmstab.load_robot(ROBOT_YAML)
    route = mmstab.route_path(robot, problem.terrain, raw["waypoints"], speed=raw["speed"],
                              turn_radius=raw["turn_radius"])  # fmt: skip
    in_code = mmstab.plan(robot, problem.terrain, route, Settings.from_problem(problem))
    from_file = mmstab.plan(problem)
    assert isinstance(in_code.stage, RoutePlan)
    for key in ("s", "poses", "postures", "mu_planned", "mu_realised", "mu_stowed"):
        np.testing.assert_allclose(getattr(in_code, key), getattr(from_file, key), atol=1e-12)
    assert in_code.verdicts == from_file.verdicts
    monkeypatch.chdir(tmp_path)
    status = main(["plan", str(path), "-o", str(tmp_path / "out")])
    assert status == in_code.exit_status == 4 and not in_code.accepted
    assert in_code.verdicts["slide"]["verdict"] == "slides"
    assert in_code.verdicts["tip"]["verdict"] == "holds"
    # the summary's verdicts are the API's
    import json

    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["verdicts"] == json.loads(json.dumps(in_code.verdicts))
    # route_risk takes the plan's margin (planner.margin, 0 here) unless told
    assert route_risk(in_code) == route_risk(in_code, 0.0)
    assert route_risk(in_code, 1e9).below_margin  # every pose is below 1e9 N rad


def test_defaults_in_code_plan_a_route_with_the_roadmap(tmp_path):
    path = turn_problem(tmp_path)
    problem = mmstab.load_problem(path)
    s = Settings.defaults(problem.robot, problem.terrain, problem.base_path)
    assert s.planner.method == "roadmap" == Settings.from_problem(problem).planner.method
    assert s.planner.ground_clearance == 0.05  # a route over a heightmap: 5 cm


def test_track_on_a_plan_is_the_problems_run(ramp_plans):
    """track(plan) drives what track(problem, plan) drives: the same states."""
    from_file, in_code = ramp_plans
    tracked = mmstab.track(in_code, duration=0.2)
    assert isinstance(tracked, Tracked) and tracked.plan is in_code
    problem = mmstab.load_problem(RAMP_YAML)
    _, _, run = mmstab.track(problem, from_file.stage, duration=0.2, progress=False)
    assert tracked.run.tipped is None and len(tracked.run.state) == len(run.state)
    np.testing.assert_allclose(tracked.run.state, run.state, atol=1e-12)
    assert tracked.settings.dt == Settings.from_problem(problem).controller.dt


def test_plan_refuses_a_mixed_call():
    problem = mmstab.load_problem(RAMP_YAML)
    with pytest.raises(TypeError, match="no terrain or path"):
        mmstab.plan(problem, problem.terrain, problem.base_path)
    with pytest.raises(TypeError, match="give the terrain and the path"):
        mmstab.plan(problem.robot)


def test_exit_statuses_are_the_clis():
    from mmstab.cli.status import EXIT_SLIDES, EXIT_UNSTABLE
    from mmstab.runs import plan_verdicts

    assert (plan_verdicts.EXIT_UNSTABLE, plan_verdicts.EXIT_SLIDES) == (EXIT_UNSTABLE, EXIT_SLIDES)


@pytest.mark.slow
def test_track_on_the_generated_step_is_the_problems(ramp_plans):
    """backend="generated": the compiled step, as track(problem, plan) runs it."""
    from_file, in_code = ramp_plans
    tracked = mmstab.track(in_code, duration=0.2, backend="generated")
    problem = mmstab.load_problem(RAMP_YAML)
    assert tracked.settings.plugin == Settings.from_problem(problem).codegen.plugin == "box"
    old = mmstab.track(problem, from_file.stage, duration=0.2, backend="generated", progress=False)
    np.testing.assert_allclose(tracked.run.state, old.run.state, atol=1e-12)
    interpreted = mmstab.track(in_code, duration=0.2, plugin=tracked.settings.plugin)
    np.testing.assert_allclose(tracked.run.state, interpreted.run.state, atol=1e-9)
