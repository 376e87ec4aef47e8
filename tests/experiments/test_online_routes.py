"""The online loop on the validation's routes (``make online-routes``)."""

from __future__ import annotations

import json

import pytest
import yaml
from conftest import ROOT

from experiments.online_routes import load_settings, main, run_online_routes, summarize_routes

SETTINGS = ROOT / "problems" / "online_routes.yaml"


def test_bad_settings_name_the_field(tmp_path, capsys) -> None:
    """One line naming the file and the field, exit 2, nothing written."""
    bad = tmp_path / "bad.yaml"
    data = yaml.safe_load(SETTINGS.read_text())
    data["routes"] = 0
    data["generator"] = str(ROOT / "problems" / "validate_routes.yaml")
    bad.write_text(yaml.safe_dump(data))
    assert main([str(bad), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "bad.yaml" in err and "routes" in err
    assert not (tmp_path / "out").exists()


def record(k: int, ground: bool, true: bool, agree: int, known: int, by: float) -> dict:
    cut = [{"start_s": 1.0, "end_s": 1.2, "by": by}] if ground else []
    return {
        "route": k,
        "arm_in_ground": {"contact": ground, "intervals_s": cut},
        "arm_in_ground_true": {"contact": true},
        "verdict_agree_maps": agree,
        "verdict_known_maps": known,
        "tipped": {"time_s": 3.0} if k == 7 else None,
    }


def test_the_summary_by_hand() -> None:
    got = summarize_routes([record(3, True, True, 90, 100, 0.05), record(7, False, True, 48, 50, 0),
                            record(9, True, False, 10, 10, 0.12)])  # fmt: skip
    assert (
        got["routes"] == 3 and got["arm_in_ground"] == [3, 9] and got["arm_in_ground_routes"] == 2
    )
    assert got["arm_in_ground_true"] == [3, 7] and got["tipped"] == [7]
    assert got["deepest_m"] == 0.12 and got["verdict_agree_share"] == pytest.approx(148 / 160)


@pytest.mark.slow
def test_route_1_followed_keeps_its_arm_clear_of_both_grounds(tmp_path) -> None:
    """Validation route 1 (a 15 cm ditch and an 8 cm kerb on 18 deg): recorded, followed,
    the arm led along its planned moves is clear of the map's ground and the route's own,
    the two verdicts agreeing map by map (its arm went 9 cm into the ground at 0.5 s when
    the reference jumped from the stowed arm to the first planned posture)."""
    settings = {**load_settings(SETTINGS), "workers": 1}
    s = run_online_routes(settings, tmp_path, [1])
    (r,) = s["records"]
    assert r["route"] == 1 and r["maps"] > 200
    assert (tmp_path / "problems" / "route01.yaml").exists()
    assert not r["arm_in_ground"]["contact"] and not r["arm_in_ground_true"]["contact"]
    assert r["arm_in_ground"]["height_min_m"] > 0.05 and r["ditch"] and r["kerb"]
    assert r["arm_in_ground_true"]["samples"] == r["covered_maps"]
    assert r["verdict_agree_maps"] == r["verdict_known_maps"] > 200
    assert s["arm_in_ground"] == [] and r["tipped"] is None
    assert json.loads((tmp_path / "summary.json").read_text())["routes"] == 1
