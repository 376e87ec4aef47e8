"""planner.ground_clearance: method roadmap keeps the arm above the plane the tracks rest on.

V and the roadmap check the arm against the robot's body only, and a low arm CoM maximises
the force-angle measure, so without the check the plans fold the arm into the ground.
Coarse grids throughout.
"""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from test_route_plan import ROOT

from mmstab.core.problem import problem_from_dict
from mmstab.model.plane_clearance import arm_ground_clearance
from mmstab.planner import PlannerSettings, plan_route
from mmstab.planner.searches.roadmap import solve_roadmap_sequence
from mmstab.stability.static import mu_max
from mmstab.workspace import build_workspace, load_or_build_workspace
from mmstab.workspace.roadmap import build_roadmap, load_or_build_roadmap

GRID = (10, 8, 8, 8)
KERB = ROOT / "problems" / "kerb.yaml"


@pytest.fixture(scope="module")
def small(robot):
    ws = build_workspace(robot, GRID, progress=False)
    return build_roadmap(robot, ws)


def _settings(ground: float | None) -> PlannerSettings:
    s = PlannerSettings.from_section(yaml.safe_load(KERB.read_text())["planner"])
    return s._replace(method="roadmap", ground_clearance=ground)


def test_the_lowest_arm_point_is_the_lowest_shape_point(robot):
    """Against a dense sampling of every link's shape surface (capsules' end spheres, boxes)."""
    from mmstab.model.parts import Box

    q = np.random.default_rng(5).uniform(robot.joint_lower, robot.joint_upper, (50, 4))
    frames = robot.kinematics.link_frames(q)
    low = np.full(len(q), np.inf)
    u = np.linspace(0.0, 1.0, 41)
    for i, link in enumerate(robot.links):
        g = link.geometry
        if isinstance(g, Box):
            pts, r = g.corners(), 0.0
        else:
            pts, r = g.p0 + u[:, None] * (g.p1 - g.p0), float(g.radius)
        world = np.einsum("nij,pj->npi", frames[:, i, :3, :3], pts) + frames[:, i, None, :3, 3]
        low = np.minimum(low, world[..., 2].min(axis=1) - r)
    np.testing.assert_allclose(arm_ground_clearance(robot, q), low, atol=1e-12)
    assert arm_ground_clearance(robot, robot.stowed)[0] > 0.02


def test_the_roadmap_keeps_each_nodes_com_ground_and_clearance(robot, small):
    from mmstab.model.collision import CollisionChecker
    from mmstab.workspace.roadmap import MOVE_CLEARANCE

    rm = small
    np.testing.assert_allclose(rm.node_com, robot.arm_com(rm.nodes_q), atol=1e-12)
    np.testing.assert_allclose(rm.node_ground, arm_ground_clearance(robot, rm.nodes_q))
    pick = np.random.default_rng(1).choice(len(rm.nodes_q), 300, replace=False)
    exact = CollisionChecker(robot).clearance(rm.nodes_q[pick])
    near = exact < MOVE_CLEARANCE
    np.testing.assert_array_equal(rm.node_clearance[pick][near], exact[near])
    assert np.all(rm.node_clearance[pick][~near] >= MOVE_CLEARANCE)


def test_on_random_gravities_every_chosen_node_clears_the_plane(robot, small):
    rng = np.random.default_rng(24)
    below_without = 0
    for _ in range(6):
        tilt = rng.uniform(0.0, 0.5, 5)
        az = rng.uniform(-np.pi, np.pi, 5)
        g = -9.81 * np.column_stack(
            [np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)]
        )
        poses = np.zeros((5, 3))
        on = solve_roadmap_sequence(robot, g, small, _settings(0.02), mu_max(robot), False, poses)
        assert np.all(arm_ground_clearance(robot, on.postures) >= 0.02)
        off = solve_roadmap_sequence(robot, g, small, _settings(None), mu_max(robot), False, poses)
        below_without += int((arm_ground_clearance(robot, off.postures) < 0.0).sum())
        assert np.all(on.total <= off.total + 1e-9)  # the check only removes candidates
    assert below_without > 0  # without the check the planner does reach into the ground


def test_kerb_plan_goes_below_the_plane_only_with_the_check_off(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the coarse workspace and roadmap are cached here
    data = yaml.safe_load(KERB.read_text())
    data["robot"] = str(ROOT / "problems" / "robots" / "cameleon.yaml")
    data["workspace"]["grid"] = list(GRID)
    data["planner"].update(method="roadmap", spacing=1.0)
    lowest = {}
    for ground in (None, 0.02):
        data["planner"]["ground_clearance"] = ground
        problem = problem_from_dict(data, tmp_path / "kerb.yaml")
        ws = load_or_build_workspace(problem, progress=False)
        plan = plan_route(problem, ws)
        lowest[ground] = arm_ground_clearance(problem.robot, plan.postures)
    assert lowest[None].min() < 0.0
    assert lowest[0.02].min() >= 0.02
    rm = load_or_build_roadmap(problem.robot, ws)
    assert (rm.node_ground < 0.02).any()


def _dense_lowest(robot, moves) -> float:
    """The arm's lowest point along the moves' straight pieces, 60 samples each [m]."""
    u = np.linspace(0.0, 1.0, 60)[:, None, None]
    low = np.inf
    for m in moves:
        if len(m) > 1:
            q = (m[:-1][None] + u * np.diff(m, axis=0)[None]).reshape(-1, m.shape[1])
            low = min(low, float(arm_ground_clearance(robot, q).min()))
    return low


def test_the_moves_between_chosen_nodes_stay_above_the_plane(robot, small):
    """The moves follow roadmap paths through nodes above the plane, cuts that stay above."""
    rng = np.random.default_rng(7)
    low_on, low_off = np.inf, np.inf
    for _ in range(6):
        tilt, az = rng.uniform(0.0, 0.5, 6), rng.uniform(-np.pi, np.pi, 6)
        g = -9.81 * np.column_stack(
            [np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)]
        )
        poses = np.zeros((6, 3))
        for ground in (0.02, None):
            seq = solve_roadmap_sequence(
                robot, g, small, _settings(ground), mu_max(robot), False, poses
            )
            if ground is None:
                low_off = min(low_off, _dense_lowest(robot, seq.moves))
            else:
                low_on = min(low_on, _dense_lowest(robot, seq.moves))
    # a lattice step between two nodes above 2 cm may dip a few mm below them
    assert low_on >= 0.02 - 0.005
    assert low_off < 0.0  # without the check the arm moves through the ground


def test_no_plan_names_the_clearance_and_the_tilt_it_was_kept_through():
    """A robot drawn at random (a 4-joint arm, 1.0-1.7 m of links on a low mount) found no
    plan at a pose of a 5.7 deg bumpy route: only the 12 deg attitude margin bound (without
    it the route planned). Before, the error named the clearance and not the margin."""
    from mmstab.core.defaults import DEFAULT_SECTIONS
    from mmstab.planner.searches.roadmap.rounds import _no_plan

    settings = PlannerSettings.from_section(DEFAULT_SECTIONS["planner"])
    value = np.zeros((3, 4))
    value[1] = -np.inf  # no node of pose 1 is stable
    allowed = [np.ones((4, 4), dtype=bool)] * 2
    poses = np.array([[0.0, 0.0, 0.0], [0.5, -0.25, np.pi / 2], [1.0, 0.0, 0.0]])
    tilted = settings._replace(ground_clearance=0.05, attitude_margin=0.21, turret_window=None)
    e = _no_plan(value, allowed, poses, tilted)
    assert e.args[0] == (
        "planner: no plan on the posture roadmap: at pose 1 (x 0.50 m, y -0.25 m, heading "
        "90 deg) no stable posture reachable from the arm's start with the arm 0.05 m above "
        "the ground through 12 deg of body tilt (planner.attitude_margin 0.21 rad)"
    )
    plane = _no_plan(value, allowed, poses, tilted._replace(attitude_margin=None)).args[0]
    assert plane.endswith("with the arm 0.05 m above the ground")
