"""On a heightmap the per-pose search never answers below the previous arm CoM's one μ.

The search ranks arm CoMs on the support the robot stands on with the arm stowed; the chosen
CoM rests on its own. On steep generated rough ground (46 deg, make atlas-rough's first
seed) the search's answer can stand on a support with less μ than the stowed arm has: the
planner then keeps the previous CoM (here the stowed arm's).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from mmstab.app import workspace
from mmstab.app.settings import Settings
from mmstab.core.problem import load_problem
from mmstab.planner import planning_region, solve_pose
from mmstab.stability.support import loaded_mu
from mmstab.terrain import HeightmapTerrain
from mmstab.terrain.generators import generate

ROOT = Path(__file__).resolve().parents[2]


def test_the_answer_is_never_below_the_previous_arm_on_the_one_mu() -> None:
    path = ROOT / "problems" / "rough_atlas.yaml"
    problem = load_problem(path)
    robot = problem.robot
    spec = yaml.safe_load(path.read_text())["terrain"]["generate"]
    terrain = HeightmapTerrain(generate({**spec, "slope": 0.8})).with_robot(robot)
    every = Settings.from_problem(problem)
    region = planning_region(workspace(problem), every.workspace.method)
    stowed = robot.arm_com(robot.stowed)
    kept = 0
    for yaw in np.linspace(0.0, 2 * np.pi, 12, endpoint=False):
        pose = np.array([0.0, 0.0, yaw])
        rng = np.random.default_rng(0)
        target = solve_pose(robot, terrain, region, pose, stowed, every.planner, rng)
        mu = loaded_mu(
            robot, terrain, np.tile(pose, (2, 1)), np.vstack([target.target_com, stowed])
        )
        assert mu[0] >= mu[1]
        if np.array_equal(target.target_com, stowed):  # the search's own answer was below
            kept += 1
            assert np.isfinite(target.mu)  # reported on the search's basis
    assert kept >= 1  # the rule was exercised on this ground
