"""The loop's μ along the way: where its lowest was, and the same states on the true ground."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_online import problem_file

import mmstab
from mmstab.outputs.online import OfflinePlan, along_route
from mmstab.outputs.recording import record_route
from mmstab.runs.arm_ground import arm_heights_at_rest
from mmstab.runs.online.run import follow_recording, summarize
from mmstab.stability.support import loaded_mu


@pytest.mark.slow
def test_a_state_on_a_clean_map_has_its_true_grounds_mu_and_the_lowest_is_placed(
    tmp_path: Path,
) -> None:
    """A noise-free, fully seen map: each covered state's μ on it is its μ on the problem's
    own terrain (one state, one μ; the map is the terrain sampled at its cells, in float32).
    The summary places the lowest μ between the grid poses about it; the offline plan along
    the way is the worse of its two postures at each map's pose, on the true ground."""
    problem = mmstab.load_problem(problem_file(tmp_path, noise=0.0, unknown=0.0))
    record_route(problem, tmp_path / "clean.mcap", duration=8.0)
    run = follow_recording(problem, tmp_path / "clean.mcap")
    s = summarize(run)
    robot = problem.robot
    st = [x for x in run.steps if x.covered]
    poses, q = np.array([x.pose for x in st]), np.array([x.q for x in st])
    mu_true = loaded_mu(robot, problem.terrain, poses, robot.arm_com(q), q)
    mu_map = np.array([x.mu for x in st])
    assert len(st) == 81 and np.abs(mu_map - mu_true).max() < 1e-3  # N rad
    # and one measure of the arm against the ground: the map's at the state's rest on it is
    # the true ground's (float32 cells), the arm led along its planned moves clear of it
    h_true = arm_heights_at_rest(robot, problem.terrain, poses, q)
    h_map = np.array([x.arm_height for x in st])
    assert np.abs(h_map - h_true).max() < 1e-3  # m
    assert s["arm_in_ground"]["contact"] is False and h_true.min() > 0.02
    at = s["mu_min_at"]
    assert run.steps[at["map"]].mu == s["mu_min"] == mu_map.min()
    k0, k1 = at["between_poses"]
    assert k1 == k0 + 1 and run.s_grid[k0] <= at["s_m"] < run.s_grid[k1]
    # an offline plan holding two postures in turn: its μ along the way by hand
    K = len(run.s_grid)
    a, b = np.array(robot.stowed, dtype=float), np.array([2.5, -0.2, 0.0, 0.3])
    postures = np.array([a if k % 2 == 0 else b for k in range(K)])
    offline = OfflinePlan(run.s_grid, np.zeros((K, 3)), np.zeros(K), np.zeros(K), np.zeros(K),
                          postures)  # fmt: skip
    along = along_route(problem, run, offline)
    assert along is not None and along["maps"] == 81
    low = along["lowest_on_map"]
    assert low["mu_map"] == s["mu_min"] and low["s_m"] == at["s_m"]
    assert abs(low["mu_true_ground"] - low["mu_map"]) < 1e-3
    assert abs(along["map_minus_true_ground"]["median"]) < 1e-3
    worse = np.fmin(
        *(loaded_mu(robot, problem.terrain, poses, robot.arm_com(x), x) for x in (a, b))
    )
    assert along["offline_plan"]["mu_true_ground"] == pytest.approx(worse.min(), abs=1e-9)
    assert along["offline_plan"]["s_m"] == float(np.array([x.s for x in st])[np.argmin(worse)])
