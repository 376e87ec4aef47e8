"""make skid-rates: the slide per radian against the turn rate, MuJoCo over the model."""

from __future__ import annotations

import json

import pytest
import yaml
from conftest import ROOT

from experiments.skid_rates import MIN_SLIDE, load_settings, main, ratios, summarize
from mmstab.core.defaults import SECTION_DEFAULTS
from mmstab.core.files import ConfigError

SETTINGS = ROOT / "problems" / "skid_rates.yaml"


def _case(command, yaw_mj, down_mj, yaw_model, down_model, holds=True):
    return {"slope_deg": 20.0, "heading_deg": 0.0, "command": command,
            "mujoco": {"yaw_rate": yaw_mj, "downhill": down_mj},
            "model": {"yaw_rate": yaw_model, "downhill": down_model, "holds": holds}}  # fmt: skip


def test_ratios_by_hand():
    """Per radian = downhill / |yaw|; cases that do not turn, slide or hold are left out."""
    cases = [
        _case("slow", -0.1, 0.02, 0.12, 0.018),  # 0.2 m/rad against 0.15: ratio 4/3
        _case("fast", 0.6, 0.06, 0.8, 0.16),  # 0.1 against 0.2: 0.5
        _case("slow", 0.01, 0.02, 0.12, 0.02),  # MuJoCo does not turn
        _case("slow", 0.2, 0.2 * MIN_SLIDE / 2, 0.2, 0.01),  # nothing to slide
        _case("slow", 0.2, 0.02, 0.2, 0.02, holds=False),  # beyond the model's cone
    ]
    r = ratios(cases)
    assert [x["ratio"] for x in r] == pytest.approx([4 / 3, 0.5])
    settings = {"commands": {"slow": [0, 0.15], "fast": [0, 1.2]}, "slow_yaw_rate": 0.3}
    s = summarize(settings, cases)
    assert s["slow"]["cases"] == 1 and s["fast"]["cases"] == 1
    assert s["slow"]["ratio_max"] == pytest.approx(4 / 3)
    assert s["slow"]["budget_bound"] == pytest.approx(0.75)
    assert s["by_command"]["fast"]["ratio_median"] == pytest.approx(0.5)


def test_committed_run_bounds_the_default_budget():
    """The default slide budget is within 1 / (MuJoCo over model) of the committed slow turns."""
    s = json.loads((ROOT / "results" / "skid_rates" / "summary.json").read_text())
    assert s["slow"]["cases"] >= 10
    assert s["slow"]["budget_bound"] == pytest.approx(1.0 / s["slow"]["ratio_max"])
    assert s["slow"]["ratio_max"] == pytest.approx(max(
        x["ratio"] for x in s["rated"] if x["yaw_rate"] <= s["slow"]["yaw_rate_max"]))  # fmt: skip
    budget = SECTION_DEFAULTS["physics"]["slide_budget"]
    if budget is not None:
        assert budget <= s["slow"]["budget_bound"]


def test_bad_settings_name_the_field(tmp_path, capsys):
    data = yaml.safe_load(SETTINGS.read_text())
    data["slow_yaw_rate"] = 0
    path = tmp_path / "rates.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match="slow_yaw_rate"):
        load_settings(path)
    assert main([str(path), "-o", str(tmp_path / "out")]) == 2
    assert "slow_yaw_rate" in capsys.readouterr().err and not (tmp_path / "out").exists()
