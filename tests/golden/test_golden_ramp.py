"""Golden numbers of the ramp (tests/golden/ramp.json): a refactor must not change them.

The file was written by ``tests/golden/make_golden.py`` on the code before the terrain
refactor; :func:`make_golden.compute` recomputes the same quantities with the
current code. Everything here is deterministic (fixed seeds, fixed states), so the
tolerance is 1e-9.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent / "golden"))
import make_golden  # noqa: E402

TOL = 1e-9
GOLDEN = json.loads(make_golden.GOLDEN.read_text())


@pytest.fixture(scope="module")
def golden_problem(tmp_path_factory):
    return make_golden.golden_problem(tmp_path_factory.mktemp("golden"))


def close(actual, expected, tol: float = TOL) -> None:
    a, e = np.asarray(actual, dtype=float), np.asarray(expected, dtype=float)
    assert a.shape == e.shape
    np.testing.assert_allclose(a, e, rtol=0, atol=tol)


@pytest.mark.parametrize("fig", ["fig5", "fig6"])
def test_sweep_maxima_and_mu_unchanged(golden_problem, fig):
    got = make_golden.compute_sweeps(golden_problem)[fig]
    want = GOLDEN["sweeps"][fig]
    close(got["poses"], want["poses"])
    close(got["mu"], want["mu"])
    close(got["mu_max"], want["mu_max"])
    assert got["maxima_index"] == want["maxima_index"]
    close(got["mu_arm_removed"], want["mu_arm_removed"])
    close(got["mu_stowed"], want["mu_stowed"])
    # the sweep is not trivial: several maxima, stability above the stowed arm's somewhere
    assert max(len(m) for m in want["maxima_index"]) >= 2
    assert np.max(want["mu_max"]) > np.min(want["mu_stowed"])


def test_plan_targets_and_mu_unchanged(golden_problem, tmp_path):
    got = make_golden.compute_plan(golden_problem, tmp_path / "cache")
    want = GOLDEN["plan"]
    for key in ("poses", "target_com", "mu", "fitness"):
        close(got[key], want[key])
    close(got["postures"], want["postures"], 1e-7)  # IPOPT's answer


def test_tracking_run_unchanged(golden_problem):
    got = make_golden.compute_tracking(golden_problem)
    want = GOLDEN["tracking"]
    assert got["steps"] == want["steps"] and got["failures"] == want["failures"]
    for key, value in want.items():
        if key in ("steps", "failures"):
            continue
        if key == "mu_min":
            for name, v in value.items():
                assert abs(got[key][name] - v) <= TOL
            continue
        close(got[key], value)


def test_step_interpreted_unchanged(golden_problem):
    got = make_golden.compute_step(golden_problem)
    want = GOLDEN["step"]
    close(got["states"], want["states"], 0)
    close(got["refs"], want["refs"], 0)
    for key in ("qdot", "status", "objective"):
        close(got[key], want[key])
    assert 0.0 in want["status"]  # the fixed states reach successful steps


@pytest.mark.slow
@pytest.mark.parametrize("plugin", ["qrqp", "box"])
def test_step_generated_c_unchanged(golden_problem, tmp_path, plugin):
    from mmstab.codegen import STEP_NAME, generate
    from mmstab.control.controller import ControllerParams, ControllerSettings

    gen = generate(golden_problem, tmp_path / plugin, plugin)
    ext = gen.load(STEP_NAME)
    settings = ControllerSettings.from_section(golden_problem.section("controller"))
    p = ControllerParams.from_settings(golden_problem.robot, settings).pack()
    want = GOLDEN["step"]
    for k, (s, r) in enumerate(zip(want["states"], want["refs"], strict=True)):
        r = make_golden.full_reference(golden_problem, np.asarray(s), np.asarray(r))
        qdot, status, objective = (np.asarray(v).ravel() for v in ext(s, r, p))
        close(qdot, want["qdot"][k])
        assert status[0] == want["status"][k]
        assert abs(objective[0] - want["objective"][k]) <= TOL
