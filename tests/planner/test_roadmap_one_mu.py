"""On a heightmap the route search does not keep a posture whose one μ falls below its rank.

The roadmap search ranks each pose's candidates on the support the robot stands on with
the arm stowed; the chosen posture rests on its own loaded support, where the plan reports
μ. Where that is below both its rank and the stowed arm's μ, the pose is ranked again on the
one μ. Ground we did not write: route 20 of ``make validate-routes`` (a seeded side slope with a
ditch and a kerb across it), where the stowed arm's support ranked a posture that tips on
its own (-174.5 N rad at pose 3, with +192.4 for the stowed arm).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import validation_route_file

import mmstab.planner.searches.roadmap.rounds as roadmap_search
from mmstab.app import plan as make_plan
from mmstab.core.problem import load_problem
from mmstab.stability.support import loaded_mu


@pytest.fixture(scope="module")
def route20(tmp_path_factory):
    return load_problem(validation_route_file(20, tmp_path_factory.mktemp("route20")))


def test_no_chosen_posture_falls_below_its_rank_and_the_stowed_arm(route20) -> None:
    plan = make_plan(route20)
    one, ranked = np.asarray(plan.mu_planned), np.asarray(plan.mu_search)
    robot = route20.robot
    stowed = loaded_mu(robot, route20.terrain, plan.poses, robot.arm_com(robot.stowed))
    floor = np.minimum(ranked, stowed) - roadmap_search.ONE_MU_SLACK
    assert np.all(one >= floor - 1e-9)
    assert abs(one[3] - ranked[3]) < 1e-6  # pose 3 was ranked on the one μ
    assert one[3] > 0 < stowed[3]  # the tipping posture is gone


def test_without_the_one_mu_the_ranking_chose_a_tipping_posture(route20, monkeypatch) -> None:
    monkeypatch.setattr(roadmap_search, "ONE_MU_SLACK", np.inf)  # never ranked again
    plan = make_plan(route20)
    one, ranked = np.asarray(plan.mu_planned), np.asarray(plan.mu_search)
    robot = route20.robot
    stowed = loaded_mu(robot, route20.terrain, plan.poses, robot.arm_com(robot.stowed))
    assert one[3] < 0 < min(ranked[3], stowed[3])  # a tipping posture, ranked stable
