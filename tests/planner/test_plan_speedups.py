"""The plan's speed-ups leave the plans unchanged: seeded random routes planned both ways.

``method: roadmap`` on two seeded random maps and routes (``tests/runs/test_random_routes.py``,
coarse grid, every default check on), planned with the speed-ups and with their reference
paths, must give the same plans to the last bit:

- each pose scores only the rows that may reach its own threshold
  (:func:`mmstab.planner.candidates.scored_rows`); reference: every pose scores the union
  over the route's poses;
- a move's clearance checks skip the pairs a turn floor or the capsules' own distances
  clear (:mod:`mmstab.model.collision_bounds`, :mod:`mmstab.model.collision_distance`);
  reference: FCL on every posture the bounding spheres leave;
- the ground under the arm's pieces from the C kernel; reference: its NumPy twin.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ROOT

from mmstab.core.problem import load_problem
from mmstab.model import collision_distance
from mmstab.model.collision import CollisionChecker
from mmstab.planner import candidates as candidates_module
from mmstab.planner import plan_problem
from mmstab.planner.ground import under_arm as under_arm_module
from mmstab.workspace import load_or_build_workspace

COARSE = [10, 8, 8, 8]
FIELDS = ("poses", "target_com", "postures", "mu_planned", "mu_stowed", "mu_search", "warm")


def _reference(monkeypatch: pytest.MonkeyPatch, used: dict[str, int]) -> None:
    """Every speed-up off: the union scored at every pose, FCL on every posture, NumPy."""
    scored_rows = candidates_module.scored_rows

    def union(*args, **kwargs):  # type: ignore[no-untyped-def]
        used["union"] = used.get("union", 0) + 1
        rows, tau, reaches = scored_rows(*args, **kwargs)
        return rows, tau, np.ones_like(reaches)

    monkeypatch.setattr(candidates_module, "scored_rows", union)
    monkeypatch.setattr(CollisionChecker, "turn_floors", lambda self: {})
    monkeypatch.setattr(collision_distance, "available", lambda: False)
    init = under_arm_module.GroundUnderArm.__init__

    def numpy_backend(self, *args, **kwargs):  # type: ignore[no-untyped-def]
        used["numpy"] = used.get("numpy", 0) + 1
        init(self, *args, **{**kwargs, "backend": "numpy"})

    monkeypatch.setattr(under_arm_module.GroundUnderArm, "__init__", numpy_backend)


@pytest.mark.slow
@pytest.mark.parametrize("pair", [0, 1])
def test_the_speed_ups_give_the_reference_plans_on_seeded_random_routes(
    pair, tmp_path, monkeypatch
):
    import sys

    sys.path.insert(0, str(ROOT / "tests" / "runs"))
    from test_random_routes import pair_problem

    problem = load_problem(pair_problem(pair, tmp_path, COARSE))
    ws = load_or_build_workspace(problem, progress=False)
    fast = plan_problem(problem, ws)
    used: dict[str, int] = {}
    with monkeypatch.context() as m:
        _reference(m, used)
        slow = plan_problem(problem, ws)
    assert used.get("union", 0) > 0 and used.get("numpy", 0) > 0  # the reference ran
    assert len(fast.s) >= 10
    for field in FIELDS:
        np.testing.assert_array_equal(getattr(fast, field), getattr(slow, field), err_msg=field)
    assert len(fast.moves) == len(slow.moves)
    for a, b in zip(fast.moves, slow.moves, strict=True):
        np.testing.assert_array_equal(a, b)
