"""The IK after the planner (mmstab.workspace.ik.PostureSolver) builds its seeds' k-d tree
and its NLP at the first solve: a plan over the roadmap, whose postures are its nodes,
solves none and builds neither (the tree alone took 65 ms of every such plan)."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from conftest import ROOT

from mmstab.core.problem import load_problem
from mmstab.planner import plan_problem
from mmstab.workspace import build_workspace, ik, load_or_build_workspace


def test_the_seeds_are_the_nearest_valid_postures_once_asked(robot):
    ws = build_workspace(robot, (10, 8, 8, 8), progress=False)
    solver = ik.PostureSolver(robot, ws)
    assert "_tree" not in solver.__dict__ and "_nlp" not in solver.__dict__
    com = np.asarray(ws.valid_com)
    target = com[123] + np.array([0.004, -0.003, 0.002])
    seeds = solver.seeds(target, robot.stowed)
    nearest = np.argsort(np.linalg.norm(com - target, axis=1))[: solver.n_seeds]  # by hand
    np.testing.assert_array_equal(np.asarray(seeds[1:]), np.asarray(ws.valid_q)[nearest])
    q, free = solver.realise(com[123], robot.stowed)
    assert free and np.linalg.norm(robot.arm_com(q) - com[123]) <= ik.COM_TOLERANCE
    assert "_tree" in solver.__dict__ and "_nlp" in solver.__dict__


@pytest.mark.slow
def test_a_roadmap_plan_builds_neither(tmp_path, monkeypatch):
    sys.path.insert(0, str(ROOT / "tests" / "runs"))
    from test_random_routes import pair_problem

    problem = load_problem(pair_problem(0, tmp_path, [10, 8, 8, 8]))
    ws = load_or_build_workspace(problem, progress=False)

    def refuse(*args, **kwargs):  # type: ignore[no-untyped-def]
        raise AssertionError("the IK's k-d tree was built")

    monkeypatch.setattr(ik, "cKDTree", refuse)
    plan = plan_problem(problem, ws)
    assert len(plan.s) >= 10 and np.isfinite(plan.mu_planned).all()
