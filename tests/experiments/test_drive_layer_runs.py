"""The drive layer in MuJoCo (``make drive``): its settings, problem copies and one small run."""

from __future__ import annotations

import json

import pytest
import yaml
from conftest import ROOT

from experiments.drive import _key, _problem_copy, load_settings, main


def test_the_settings_are_checked_at_the_boundary(tmp_path, capsys) -> None:
    settings = load_settings(ROOT / "problems" / "drive.yaml")
    assert [_key(r) for r in settings["turn_ratios"]] == ["1.0", "auto", "0.54"]
    bad = yaml.safe_load((ROOT / "problems" / "drive.yaml").read_text())
    bad["turn_ratios"] = [1.0, 1.5]  # a ratio in (0, 1] or auto
    (tmp_path / "bad.yaml").write_text(yaml.safe_dump(bad))
    assert main([str(tmp_path / "bad.yaml"), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bad.yaml" in err[0] and "turn_ratios" in err[0]
    assert not (tmp_path / "out").exists()


def test_a_problem_copy_keeps_its_robot_and_sets_the_ratio(tmp_path) -> None:
    source = ROOT / "problems" / "ditch.yaml"  # a robot and a terrain file, both relative
    data = yaml.safe_load(source.read_text())
    path = _problem_copy(data, source, tmp_path / "a" / "b", "auto")
    copy = yaml.safe_load(path.read_text())
    assert copy["physics"]["turn_ratio"] == "auto" and "physics" not in data
    assert (path.parent / copy["robot"]).resolve() == (
        ROOT / "problems" / "robots" / "cameleon.yaml"
    )
    assert (path.parent / copy["terrain"]["file"]).resolve() == (
        ROOT / "problems" / "terrains" / "ditch.npz"
    )


@pytest.mark.mujoco
@pytest.mark.slow
def test_a_small_run_records_the_level_pivot_and_a_route(tmp_path) -> None:
    """η = 1 and the skid model's: MuJoCo's level pivot turns at about half the kinematic
    rate with the belts at r θ̇, and faster through the layer; the ramp lap holds."""
    settings = yaml.safe_load((ROOT / "problems" / "drive.yaml").read_text())
    settings.update(turn_ratios=[1.0, "auto"], pairs=0, workers=2)
    settings["routes"] = {"ramp_planned": {"problem": str(ROOT / "problems" / "ramp.yaml"),
                                           "arm": "planned"}}  # fmt: skip
    settings["level"]["turns"] = {"pivot": [-3.0, 3.0]}
    (tmp_path / "drive.yaml").write_text(yaml.safe_dump(settings))
    assert main([str(tmp_path / "drive.yaml"), "-o", str(tmp_path / "out")]) == 0
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    plain, layer = s["level"]["cases"]
    assert plain["turn_ratio"] == 1.0 and plain["belts_m_s"] == pytest.approx([-0.27, 0.27])
    assert layer["turn_ratio"] == pytest.approx(s["auto_turn_ratio"])
    assert 0.45 < plain["yaw_rate_over_commanded"] < 0.6  # the turn deficit
    assert layer["yaw_rate_over_commanded"] > 1.4 * plain["yaw_rate_over_commanded"]
    for variant in ("1.0", "auto"):
        ramp = s["routes"][variant]["ramp_planned"]
        assert ramp["exit"] == 0 and ramp["slid_s"] is None and ramp["tipped_s"] is None
        assert ramp["base_error_max_m"] < 0.05
    assert s["counts"]["1.0"]["pairs"] == 0
