"""One loader builds every stage's settings: from a problem file, or defaults in code."""

from __future__ import annotations

import dataclasses

import pytest
import yaml
from conftest import PROBLEMS, RAMP_YAML

from mmstab.app.settings import Settings
from mmstab.core.defaults import DEFAULT_SECTIONS, SECTION_DEFAULTS
from mmstab.core.problem import load_problem, problem_from_dict


def test_settings_of_the_default_problem_file_are_its_sections():
    problem = load_problem(RAMP_YAML)
    settings = Settings.from_problem(problem)
    raw = yaml.safe_load(RAMP_YAML.read_text())
    assert settings.planner.method == raw["planner"]["method"] == "sequence"
    assert settings.planner.poses == raw["planner"]["poses"]
    assert settings.workspace.grid == tuple(raw["workspace"]["grid"])
    assert settings.controller.dt == raw["controller"]["dt"]
    assert settings.controller.kp == tuple(raw["controller"]["kp"])
    assert settings.codegen.plugin == raw["codegen"]["plugin"]
    assert settings.verdicts.margin == raw["planner"].get("margin", 0.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        settings.spacing = 1.0  # type: ignore[misc]


def test_settings_in_code_equal_a_file_that_names_none(tmp_path):
    """``Settings()``: the sections a problem file that names only robot/terrain/path gets."""
    minimal = {
        "robot": str(PROBLEMS / "robots" / "cameleon.yaml"),
        "terrain": {"slope": 0.2},
        "path": {"center": [0.0, 0.0], "radius": 1.0, "start_angle": 0.0, "direction": "ccw"},
    }
    problem = problem_from_dict(minimal, tmp_path / "p.yaml")
    assert Settings() == Settings.from_problem(problem)
    assert Settings().planner.method == SECTION_DEFAULTS["planner"]["method"] == "cmaes"
    assert Settings().workspace.grid == tuple(DEFAULT_SECTIONS["workspace"]["grid"])
    assert Settings().controller.arm_com_frame == "body"


def test_defaults_follow_the_path_and_the_terrain():
    kerb = load_problem(PROBLEMS / "kerb.yaml")  # a route over a generated heightmap
    assert kerb.route is not None
    d = Settings.defaults(kerb.robot, kerb.terrain, kerb.base_path)
    assert d.planner.method == "roadmap"  # a route that names no method
    assert d.planner.ground_clearance == 0.05 and d.planner.attitude_margin == 0.21
    ramp = load_problem(RAMP_YAML)
    assert Settings.defaults(ramp.robot, ramp.terrain, ramp.base_path) == Settings()
    # a circle over the map plans as a route there; on the ramp's plane as the paper does
    lap = Settings.defaults(kerb.robot, kerb.terrain, ramp.base_path).planner
    assert (lap.method, lap.ground_clearance, lap.attitude_margin) == ("roadmap", 0.05, 0.21)
    assert Settings.defaults(kerb.robot, ramp.terrain, ramp.base_path).planner.method == "cmaes"


def test_old_problem_files_load_into_settings():
    """Every shipped problem with the sections a plan needs loads into one Settings."""
    for name in ("ramp", "ramp_paper", "ramp_reliable", "rough", "kerb", "ramp_6dof"):
        problem = load_problem(PROBLEMS / f"{name}.yaml")
        s = Settings.from_problem(problem)
        assert len(s.workspace.grid) == problem.robot.arm_joints
        assert len(s.controller.posture_gain) == problem.robot.arm_joints
