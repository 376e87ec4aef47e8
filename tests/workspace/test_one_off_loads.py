"""What a one-off command loads: only what it uses, read fast.

The IK after the planner (mmstab.workspace.ik.PostureSolver) builds its seeds' k-d tree and
its NLP at the first solve: a plan over the roadmap, whose postures are its nodes, solves
none and builds neither (the tree alone took 65 ms of every such plan). A workspace's
arrays are kept uncompressed beside its cache file and read back equal.
"""

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


def test_a_workspace_read_back_from_its_kept_arrays_equals_the_one_written(robot, tmp_path):
    """load_workspace keeps the .npz's arrays uncompressed beside it: the second read maps
    them, and both equal what was written; a file of another version is still refused."""
    import dataclasses

    from mmstab.core.files import write_npz
    from mmstab.workspace.cache import WORKSPACE_VERSION, load_workspace, save_workspace

    ws = build_workspace(robot, (10, 8, 8, 8), progress=False)
    path = save_workspace(tmp_path / "ws.npz", ws)
    first, second = load_workspace(path), load_workspace(path)
    assert (tmp_path / "ws" / "arrays" / "valid_com.npy").is_file()
    for f in dataclasses.fields(ws):
        for got in (first, second):
            np.testing.assert_array_equal(getattr(got, f.name), getattr(ws, f.name))
    arrays = {f.name: getattr(ws, f.name) for f in dataclasses.fields(ws)}
    old = write_npz(tmp_path / "old.npz", version=WORKSPACE_VERSION - 1, **arrays)
    with pytest.raises(ValueError, match="workspace cache version"):
        load_workspace(old)
