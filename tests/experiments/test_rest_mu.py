"""mmstab's μ at rest against MuJoCo's settled robot (``make rest-mu``)."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from conftest import ROOT

from experiments.rest_mu import compliance_table, load_settings, map_states

pytestmark = pytest.mark.mujoco


def test_on_a_smooth_slope_mujoco_settles_on_mmstabs_support(tmp_path) -> None:
    """A map with no roughness, hill or features (a 10-15 deg plane): both agree within 2 %."""
    settings = load_settings(ROOT / "problems" / "rest_mu.yaml")
    gen = copy.deepcopy(settings["generator_settings"])
    gen["ground"].update(slope_deg=[10.0, 15.0], roughness_m=[0.0, 0.0], hill_m=[0.0, 0.0])
    for name in ("ditch", "kerb", "bumps"):
        gen["ground"][name]["probability"] = 0.0
    settings = {**settings, "generator_settings": gen, "poses_per_map": 2, "settle_s": 1.0}
    (tmp_path / "problems").mkdir()
    records = map_states((settings, 0, str(tmp_path)))
    assert len(records) == 2 and 10.0 <= records[0]["slope_deg"] <= 15.0
    for r in records:
        assert r["off_rest_deg"] < 0.5 and r["speed_m_s"] < 0.01  # at rest, mmstab's attitude
        pred = np.array(r["mu_predicted"])
        # a plane: the whole bottom run touches, so no compliance changes the support
        assert np.ptp(pred) < 1e-6 * pred[0]
        assert pred[0] == pytest.approx(r["mu_simulated"], rel=0.02)
    table = compliance_table(settings, records)
    row = table["by_compliance_m"]["0.02"]["same_rest"]
    assert row["n"] == 2 and row["median_abs"] < 0.02 and row["optimistic_over_5pc"] == 0.0
