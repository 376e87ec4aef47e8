"""Verdicts against MuJoCo: the classifier, mmstab's side, a coarse grid.

The full grid (``make verdicts``, ``problems/verdicts.yaml``) is in ``docs/verdicts.md``,
"Verdicts against MuJoCo"; here a coarse grid of it on the rigid-wheel model, in < 60 s.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import PROBLEMS

pytestmark = pytest.mark.mujoco
pytest.importorskip("mujoco")

from experiments.verdicts import confusion, load_settings, sim_settings  # noqa: E402
from mmstab.model.robot import load_robot  # noqa: E402
from mmstab.physics.edge_cases import (  # noqa: E402
    ArmPostures,
    Config,
    arm_ground_clearance,
    bisect_tip,
    build_cases,
    case_sim,
    configs,
    predict,
    predicted_verdict,
)
from mmstab.physics.verdict_sim import (  # noqa: E402
    Thresholds,
    Trajectory,
    classify,
    first_crossing,
)
from mmstab.workspace.build import build_workspace  # noqa: E402

#: The loaded arm stretched out to the right (turret at 270 deg), a little raised.
REACH = np.array([1.5 * np.pi, 0.3, -0.3, 0.0])
PAYLOAD_COM = np.array([0.05, 0.01, 0.0])
THRESHOLDS = Thresholds(tip_deg=10.0, slide_m=0.10)


@pytest.fixture(scope="module")
def cameleon():
    return load_robot(PROBLEMS / "robots" / "cameleon.yaml")


@pytest.fixture(scope="module")
def postures(cameleon):
    """Planned postures from a coarse workspace (12 x 8 x 8 x 8 postures)."""
    ws = build_workspace(cameleon, (12, 8, 8, 8), progress=False)
    return ArmPostures(cameleon, PAYLOAD_COM, ws.valid_q, {"reach": REACH}, 0.02)


@pytest.fixture(scope="module")
def settings():
    return load_settings(PROBLEMS / "verdicts.yaml")


# ------------------------------------------------------------------- the classifier
def trajectory(tilt, slip, arm=None):
    t = 0.05 * np.arange(1, len(tilt) + 1)
    arm = np.zeros(len(tilt), bool) if arm is None else np.asarray(arm, bool)
    return Trajectory(t, np.asarray(tilt, float), np.asarray(slip, float), arm)


def test_classifier_on_hand_made_trajectories():
    still = trajectory([0.2, 0.3, 0.3, 0.2], [0.0, 0.01, 0.02, 0.03])
    v = classify(still, THRESHOLDS)
    assert (v.verdict, v.time, v.tilt_deg, v.slip_m) == ("holds", 0.2, 0.3, 0.03)
    # tilt passes 10 deg at the 3rd sample, slip 0.1 m at the 4th: it tipped first
    v = classify(trajectory([1, 5, 12, 40], [0, 0.05, 0.08, 0.2]), THRESHOLDS)
    assert v.verdict == "tips" and v.time == pytest.approx(0.15) and v.tilt_deg == 40
    # the slip passes first: it slid (and tipped later)
    v = classify(trajectory([0.1, 0.1, 3, 15], [0.02, 0.11, 0.3, 0.6]), THRESHOLDS)
    assert v.verdict == "slides" and v.time == pytest.approx(0.10)
    # exactly at a threshold is not past it
    assert classify(trajectory([10.0], [0.10]), THRESHOLDS).verdict == "holds"
    # the arm on the ground counts only before the verdict
    late = trajectory([0, 20, 30], [0, 0, 0], arm=[False, False, True])
    early = trajectory([0, 20, 30], [0, 0, 0], arm=[False, True, False])
    assert not classify(late, THRESHOLDS).arm_ground and classify(early, THRESHOLDS).arm_ground
    assert first_crossing(np.arange(3.0), np.zeros(3), 1.0) == float("inf")


def test_confusion_counts():
    out = confusion(["holds", "tips", "tips", "slides"], ["holds", "tips", "holds", "tips"])
    assert out["holds"] == {"holds": 1, "slides": 0, "tips": 0}
    assert out["tips"] == {"holds": 1, "slides": 0, "tips": 1}
    assert out["slides"]["tips"] == 1


# ------------------------------------------------------------------------ mmstab's side
def test_predictions(postures):
    """Slip binds at atan(mu) for the stowed arm; the reach posture tips at 32.43 deg."""
    stowed = predict(postures, Config(0.0, 0.0, "stowed", 0.7, 0.0))
    assert stowed.binds == "slip" and stowed.critical == pytest.approx(np.arctan(0.7))
    assert np.degrees(stowed.tip_slope) == pytest.approx(57.55, abs=0.01)
    reach = predict(postures, Config(0.0, 3.0, "reach", 1.5, 0.0))
    assert reach.binds == "tip" and np.degrees(reach.critical) == pytest.approx(32.43, abs=0.01)
    planned = predict(postures, Config(0.0, 0.0, "planned", 4.0, 0.0))
    assert planned.tip_slope > stowed.tip_slope + np.radians(5.0)
    slope = planned.critical + np.radians(0.5)
    q, mu = postures.at(Config(0.0, 0.0, "planned", 4.0, 0.0), slope)
    assert mu < 0 and predicted_verdict(slope, mu, planned) == "tips"
    assert predicted_verdict(stowed.critical + 0.01, -1.0, stowed) == "slides"
    assert predicted_verdict(stowed.critical - 0.01, 5.0, stowed) == "holds"


def test_planned_postures_clear_the_ground(cameleon, postures):
    assert arm_ground_clearance(cameleon, cameleon.stowed)[0] > 0.02
    down = np.array([0.0, -1.2, 0.0, 0.0])  # the shoulder pointing the arm into the ground
    assert arm_ground_clearance(cameleon, down)[0] < 0.0
    assert np.all(arm_ground_clearance(cameleon, postures.candidates) >= 0.02)


# ------------------------------------------------------------------ the coarse grid
@pytest.mark.slow
def test_coarse_grid_agrees_with_mujoco(postures, settings):
    """72 cases on the rigid-wheel model: roll and pitch, slip- and tip-bound, braked and
    driven, each arm, -1.5, -0.5 and +1.5 deg around mmstab's critical slope.

    The -0.5 deg cases facing uphill hold the brakes' fix (``integrator: discrete``): on
    ``implicitfast`` the load along the tracks made the rigid wheels hop and slide there
    (65 of these 72 cases agreed; docs/verdicts.md).
    """
    arms = ["stowed", "planned", "reach"]
    grid = configs(np.radians([0.0, 90.0]), [3.0], arms, [0.7, 4.0], [0.0, 0.05])
    predictions, cases = build_cases(postures, grid, np.radians([-1.5, -0.5, 1.5]))
    assert {p.binds for p in predictions} == {"tip", "slip"}
    assert {c.verdict for c in cases} == {"holds", "tips", "slides"}
    sim = sim_settings(settings)["rigid"]
    simulated = [case_sim(postures, sim, THRESHOLDS, c.config, c.angle) for c in cases]
    wrong = [
        (c.config, c.verdict, s.verdict)
        for s, c in zip(simulated, cases, strict=True)
        if s.verdict != c.verdict
    ]
    assert 1 - len(wrong) / len(cases) >= 0.95, wrong


@pytest.mark.parametrize("heading", [0.0, 0.5 * np.pi])
def test_tip_slope_within_a_degree(postures, settings, heading):
    """No slip (friction 4): the bisected MuJoCo tip slope within 1 deg of mmstab's.

    Heading 0 tips over the downhill track (roll), heading 90 deg over the rear (pitch).
    """
    config = Config(heading, 0.0, "stowed", 4.0, 0.0)
    predicted = predict(postures, config)
    assert predicted.binds == "tip"
    sim = sim_settings(settings)["rigid"]
    found = bisect_tip(postures, sim, THRESHOLDS, config, predicted.tip_slope, 0.02, 4)
    assert found.lo < found.simulated < found.hi
    assert abs(found.simulated - predicted.tip_slope) < np.radians(1.0)


def test_bad_settings_file_is_one_line_exit_2(tmp_path):
    """``make verdicts`` on a bad settings file: one ``mmstab: error:`` line naming it, exit 2."""
    import subprocess
    import sys

    bad = tmp_path / "verdicts.yaml"
    bad.write_text("cases: 3\n")
    cmd = [sys.executable, "-m", "experiments.verdicts", str(bad), "-o", str(tmp_path / "o")]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert r.returncode == 2
    assert r.stderr.startswith(f"mmstab: error: {bad}: missing") and r.stderr.count("\n") == 1
    assert not (tmp_path / "o").exists()
