"""The defaults that keep a route's arm off the ground in MuJoCo (docs/physics.md).

``controller.arm_com_frame`` defaults to ``body``; a path (route or circle) over a heightmap
that names no ``planner.ground_clearance`` / ``planner.attitude_margin`` gets 0.05 m / 0.21
rad (12 deg), and the roadmap search where it names none
(:data:`mmstab.core.defaults.HEIGHTMAP_ROUTE_PLANNER`); the shipped problems name what
their committed numbers were made with. The MuJoCo test runs two of the tests' seeded
random routes (``tests/runs/test_random_routes.py``, coarse grid) whole: with the defaults of
before (map frame, 0.02 m, no margin) pair 0 tipped at 54.7 s and the arm touched the ground
on 5.0 % (pair 0) and 3.8 % (pair 1) of the checks.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import ROOT
from test_random_routes import COARSE, pair_problem

from mmstab import app
from mmstab.control.controller import build_controller
from mmstab.control.pivot import pivoting
from mmstab.control.reference import initial_state
from mmstab.core.defaults import HEIGHTMAP_ROUTE_PLANNER, with_defaults
from mmstab.core.problem import load_problem
from mmstab.outputs.simulate import controller_settings, loop_settings
from mmstab.physics.closed_loop import run_closed_loop

ROUTE = {"waypoints": [[0.0, 0.0], [3.0, 0.0]], "speed": 0.2}
HEIGHTMAP = {"generate": {"kind": "rough", "seed": 1, "size": [8.0, 6.0], "resolution": 0.05}}


def _planner(terrain: dict, path: dict, planner: dict | None = None) -> dict:
    data = {"robot": "r.yaml", "terrain": terrain, "path": path}
    if planner is not None:
        data["planner"] = planner
    return with_defaults(data)["planner"]


def test_the_arm_com_frame_defaults_to_body_and_the_ramp_keeps_map():
    data = {"robot": "r.yaml", "terrain": {"slope": 0.1}, "path": ROUTE}
    assert with_defaults(data)["controller"]["arm_com_frame"] == "body"
    ramp = load_problem(ROOT / "problems" / "ramp.yaml")
    assert ramp.section("controller")["arm_com_frame"] == "map"
    # every shipped problem with a controller names its frame: its committed runs' numbers
    for f in sorted((ROOT / "problems").glob("*.yaml")):
        raw = yaml.safe_load(f.read_text())
        if "controller" in raw:
            frame = "body" if f.name in ("rough.yaml", "dem.yaml") else "map"
            assert raw["controller"]["arm_com_frame"] == frame, f.name


def test_a_route_over_a_heightmap_keeps_the_arm_higher():
    assert HEIGHTMAP_ROUTE_PLANNER == {"ground_clearance": 0.05, "attitude_margin": 0.21}
    on_map = _planner(HEIGHTMAP, ROUTE)
    assert (on_map["ground_clearance"], on_map["attitude_margin"]) == (0.05, 0.21)
    assert on_map["method"] == "roadmap"
    assert _planner({"file": "dem.tif"}, ROUTE, {"margin": 5.0})["attitude_margin"] == 0.21
    # what the file names wins, null (off) included
    named = _planner(HEIGHTMAP, ROUTE, {"ground_clearance": 0.08, "attitude_margin": None})
    assert (named["ground_clearance"], named["attitude_margin"]) == (0.08, None)
    # a circle over a heightmap plans as a route there: the roadmap checks the map under the
    # arm (cmaes knows the support plane only), unless the file names its search
    circle = {"radius": 1.0, "center": [0.0, 0.0]}
    lap = _planner(HEIGHTMAP, circle)
    assert (lap["ground_clearance"], lap["attitude_margin"]) == (0.05, 0.21)
    assert lap["method"] == "roadmap"
    assert _planner({"file": "dem.tif"}, circle, {"method": "cmaes"})["method"] == "cmaes"
    # a plane keeps 0.02 m and no margin; a circle there the paper's cmaes
    for path, method in ((ROUTE, "roadmap"), (circle, "cmaes")):
        p = _planner({"slope": 0.2}, path)
        assert (p["ground_clearance"], p["attitude_margin"], p["method"]) == (0.02, None, method)
    # rough.yaml plans as its committed runs did: no margin
    rough = load_problem(ROOT / "problems" / "rough.yaml").section("planner")
    assert (rough["ground_clearance"], rough["attitude_margin"]) == (0.05, None)


@pytest.fixture(scope="module")
def cache(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("route_defaults_cache")


@pytest.mark.parametrize("k", (0, 1))
@pytest.mark.slow
@pytest.mark.mujoco
def test_a_random_route_in_mujoco_does_not_tip_nor_touch_the_ground(k, tmp_path, cache):
    """Whole route, controller in the loop: no tip, no arm link on the ground, no QP failure."""
    problem = load_problem(pair_problem(k, tmp_path, COARSE))
    planner = problem.section("planner")
    assert problem.section("controller")["arm_com_frame"] == "body"
    assert (planner["ground_clearance"], planner["attitude_margin"]) == (0.05, 0.21)
    plan = app.plan(problem, ws=app.workspace(problem, progress=False, cache_dir=cache))
    cs, loop = controller_settings(problem), loop_settings(problem)
    state0 = initial_state(problem.base_path, problem.robot.stowed)
    run = run_closed_loop(problem, plan, build_controller(problem.robot, cs).step, cs, loop, state0)
    driven = pivoting(problem, plan, loop.pivot_centre).route  # its pivots about their centres
    assert driven is not None  # the whole route: no tip stopped the run
    added = 0.0 if run.timing is None else run.timing["run_time_added_s"]  # the arm's time law
    waited = run.reference_wait_s  # the governor's (route 1: 12 ms, its base 25 cm behind)
    assert run.t[-1] == pytest.approx(driven.duration + added + waited, abs=2 * loop.control_dt)
    assert run.tipped is None and run.disagreement is None
    assert np.nanmax(run.tilt_error) < loop.disagreement_angle
    assert run.arm_ground is not None and np.isfinite(run.arm_ground).sum() > 1000
    assert np.nansum(run.arm_ground == 1) == 0
    assert int(np.sum(run.status != 0)) == 0
    # the base lags (10.4 and 25.8 cm at worst: route 1 slides on its second pivot's slope,
    # 19.8 cm in a second; 18.1 cm and 9.8 cm with its pivots about B's origin), the arm
    # keeps its planned posture
    assert run.base_error.max() < 0.3
