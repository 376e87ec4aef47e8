"""``make validate-routes``: random routes over user-like ground, mmstab's verdicts vs MuJoCo.

The generator lays its ditch and kerb across the route (checked on the map's cells); a coarse
subset of the experiment (a flat route and the settings' route 1, which crosses a 15 cm
ditch on an 18 deg slope) runs whole: the confusion table is recounted from the per-route
records, the flat route is accepted by ``mmstab plan`` (its exit status, by the command
itself) and holds in MuJoCo, tracked within the bar.
"""

from __future__ import annotations

import copy
import subprocess
import sys
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
import yaml

from experiments.validate_routes import (
    OUTCOMES,
    PLAN_VERDICTS,
    bars,
    event_place,
    load_settings,
    route_problem,
    run_routes,
)
from mmstab.terrain.generators import generate

ROOT = Path(__file__).resolve().parents[2]
SETTINGS = ROOT / "problems" / "validate_routes.yaml"


def _flat(settings: dict) -> dict:
    """The settings with a flat, featureless map (no slope, roughness, bump or feature)."""
    s = copy.deepcopy(settings)
    g = s["ground"]
    g["slope_deg"] = g["roughness_m"] = g["hill_m"] = [0.0, 0.0]
    for f in ("ditch", "kerb", "bumps"):
        g[f]["probability"] = 0.0
    return s


def test_ditch_and_kerb_lie_across_the_route() -> None:
    """On a map with only a ditch and a kerb, the route's cells reach both levels.

    Route cells (nearest cell centres along the polyline, every 1 cm): some at the ditch's
    floor -depth (or -depth + height where the two overlap), some at the kerb's top +height
    (or the kerb's floor where it drops: then the start is at +height); so both features cut
    the route, whatever the drawn azimuths.
    """
    base = load_settings(SETTINGS)
    s = _flat(base)
    s["ground"]["ditch"]["probability"] = s["ground"]["kerb"]["probability"] = 1.0
    for k in range(6):
        data = route_problem(s, k)
        g = data["terrain"]["generate"]
        depth, height = g["features"]["ditch"]["depth"], g["features"]["kerb"]["height"]
        assert 0.08 <= depth <= 0.20 and 0.4 <= g["features"]["ditch"]["width"] <= 0.8
        assert 0.04 <= height <= 0.10
        hm = generate(g)
        wp = np.asarray(data["path"]["waypoints"])
        pts = np.vstack([np.linspace(a, b, int(np.linalg.norm(b - a) / 0.01))
                         for a, b in zip(wp[:-1], wp[1:], strict=True)])  # fmt: skip
        ij = np.round((pts - hm.origin) / hm.resolution).astype(int)
        e = np.asarray(hm.elevation)[ij[:, 1], ij[:, 0]]
        levels = np.unique(np.round(e, 9))
        assert any(np.isclose(levels, -depth)) or any(np.isclose(levels, height - depth))
        assert any(np.isclose(levels, height)) and any(np.isclose(levels, 0.0))


def test_bad_settings_name_the_field(tmp_path, capsys) -> None:
    """A bad settings file: one line naming the file and the field, exit 2, nothing written."""
    from experiments.validate_routes import main

    bad = tmp_path / "bad.yaml"
    data = yaml.safe_load(SETTINGS.read_text())
    data["routes"] = 0
    bad.write_text(yaml.safe_dump(data))
    assert main([str(bad), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "bad.yaml" in err and "routes" in err
    assert not (tmp_path / "out").exists()


def test_event_place_by_hand() -> None:
    """Distances to a 0.5 m ditch band at x = 1, a kerb along y = 2 and the corner (3, 0)."""
    data = {
        "terrain": {"generate": {"features": {
            "ditch": {"depth": 0.1, "width": 0.5, "distance": 1.0, "azimuth": 0.0},
            "kerb": {"height": 0.05, "distance": -2.0, "azimuth": -np.pi / 2}}}},
        "path": {"waypoints": [[0.0, 0.0], [3.0, 0.0], [3.0, 3.0]]},
    }  # fmt: skip
    assert event_place(data, [1.1, 0.0]) == pytest.approx(
        {"to_ditch_m": 0.0, "to_kerb_m": 2.0, "to_corner_m": 1.9}
    )
    assert event_place(data, [2.0, 1.5]) == pytest.approx(
        {"to_ditch_m": 0.75, "to_kerb_m": 0.5, "to_corner_m": np.hypot(1.0, 1.5)}
    )
    data["terrain"]["generate"]["features"] = {}
    assert event_place(data, [0.0, 0.0])["to_ditch_m"] is None


def _record(k: int, plan: str, mujoco: str, error_m: float, slope: float = 10.0) -> dict:
    return {"route": k, "plan": plan, "mujoco": mujoco, "base_origin_error_max_m": error_m,
            "slope_deg": slope, "mu_relative_difference_median": 0.01,
            "mu_predicted_median": 500.0, "mu_simulated_median": 500.0 - k}  # fmt: skip


def test_worst_window_turn_by_hand() -> None:
    from experiments.validate_routes import worst_window_turn

    t = np.arange(0.0, 6.0, 0.01)
    # 0.5 rad/s for 2 s from t = 1 s, across +-pi: 0.5 rad in the worst second
    heading = np.angle(np.exp(1j * (np.pi - 0.3 + 0.5 * np.clip(t - 1.0, 0.0, 2.0))))
    assert worst_window_turn(t, heading, 1.0) == pytest.approx(0.5, abs=1e-9)
    assert worst_window_turn(t, heading, 3.0) == pytest.approx(1.0, abs=1e-9)  # all of it
    assert worst_window_turn(t, np.zeros_like(t), 1.0) == 0.0


def test_bars_count_a_forced_route_off_the_path_as_failing() -> None:
    """Refused routes: 1 slides, 1 holds 30 cm off its path, 2 hold on it -> 2 of 4 fail.

    The accepted route that holds 30 cm off breaks the tracking bar instead (it is not a
    refusal's fail); the events-only share is 1 of 4. Up to 20 deg, the routes MuJoCo holds on
    their path (2 and 3) are the drivable ones.
    """
    b = load_settings(SETTINGS)["bars"]
    records = [
        _record(0, "slides", "slides", 0.4),
        _record(1, "slides", "holds", 0.3),
        _record(2, "slides", "holds", 0.05),
        _record(3, "tips", "holds", b["tracking_m"]),  # at the bar: on the path
        _record(4, "accepted", "holds", 0.3, slope=25.0),
    ]
    got = bars(records, b)
    refused = got["refused_fail_when_forced"]
    assert (refused["refused"], refused["fail_in_mujoco"], refused["off_path"]) == (4, 1, [1])
    assert refused["share"] == pytest.approx(0.5) and refused["share_events"] == pytest.approx(0.25)
    assert got["tracking_body_origin"]["over"] == [4] and not got["tracking_body_origin"]["holds"]
    slopes = got["accepted_on_slopes"]
    assert (slopes["routes"], slopes["accepted"], slopes["drivable"]) == (4, 0, 2)  # 2 and 3
    mu = got["mu_median_relative"]  # the accepted route: medians 500 and 496
    assert mu["over"] == [] and mu["of_medians_max"] == pytest.approx(4 / 500)


def test_track_agreement_counts_by_hand() -> None:
    """Three routes with a track verdict (one off the plan's), one without: counted."""
    from experiments.validate_routes import track_agreement

    records = [
        {"route": 0, "plan": "accepted", "track": "accepted", "mujoco": "holds"},
        {"route": 1, "plan": "slides", "track": "tips", "mujoco": "holds"},
        {"route": 2, "plan": "tips", "track": "tips", "mujoco": "tips"},
        {"route": 3, "plan": "no plan", "mujoco": None},
    ]
    got = track_agreement(records)
    assert got["routes"] == 3 and got["agrees_with_plan"] == 2
    assert got["verdicts"] == {"accepted": 1, "tips": 2, "slides": 0, "arm collision": 0}
    assert got["tips_where_mujoco_tips"] == 1
    assert got["disagrees"] == [{"route": 1, "plan": "slides", "track": "tips", "mujoco": "holds"}]


@pytest.mark.mujoco
@pytest.mark.slow
def test_a_coarse_subset_plans_and_runs_in_mujoco(tmp_path) -> None:
    pytest.importorskip("mujoco")
    settings = load_settings(SETTINGS)
    runs = tmp_path / "flat" / "runs"
    runs.mkdir(parents=True)
    for name in ("route00.png", "route05.png"):  # an earlier run's figures
        (runs / name).write_bytes(b"")
    flat = run_routes(_flat(settings), tmp_path / "flat", [0])
    # route 0 run again without a disagreement: its old figure goes; route 5's stays
    assert not (runs / "route00.png").exists() and (runs / "route05.png").exists()
    ditch = run_routes({**settings, "track": False}, tmp_path / "ditch", [1])
    records = flat["records"] + ditch["records"]
    # the confusion table, recounted from the records
    for s in (flat, ditch):
        counts = Counter((r["plan"], r["mujoco"] or "not simulated") for r in s["records"])
        for v in PLAN_VERDICTS:
            for o in [*OUTCOMES, "not simulated"]:
                assert s["confusion"][v][o] == counts[(v, o)]
        assert sum(map(sum, (row.values() for row in s["confusion"].values()))) == 1
    f = flat["records"][0]
    assert f["slope_deg"] == 0.0 and f["ditch"] is None and f["kerb"] is None
    assert (f["plan"], f["plan_exit"], f["mujoco"]) == ("accepted", 0, "holds")
    assert f["events"] == {"tipped": None, "left_map": None, "slid": None,
                           "arm_ground_contact": None, "stalled": None}  # fmt: skip
    assert f["disagreement"] is None and f["qp_failures"] == 0
    assert f["base_origin_error_max_m"] < 0.10 and f["base_error_max_m"] < 0.10
    assert f["simulated_s"] >= f["route_duration_s"] - 0.01  # the whole route driven
    assert flat["bars"]["accepted_never_fail"]["holds"]
    assert f["track"] == "accepted"  # mmstab track on the same plan: one answer
    assert flat["track"]["agrees_with_plan"] == 1 and flat["track"]["disagrees"] == []
    assert "track" not in ditch["records"][0] and "track" not in ditch
    # the route's plan by `mmstab plan` itself: the same exit status
    problem = tmp_path / "flat" / f["problem"]
    cmd = [sys.executable, "-m", "mmstab", "plan", str(problem), "-o", str(tmp_path / "plan")]
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert r.returncode == f["plan_exit"], r.stderr
    d = ditch["records"][0]
    assert d["ditch"] is not None and d["plan"] in PLAN_VERDICTS
    assert d["plan_exit"] == PLAN_VERDICTS[d["plan"]] and d["mujoco"] in OUTCOMES
    if d["mujoco"] == "tips":  # the physics' own event: the contacts' mu went <= 0
        assert d["events"]["tipped"]["cause"] in ("support lost", "overturned")
        assert d["mu_simulated_min"] <= 0 or d["events"]["tipped"]["cause"] == "overturned"
    assert all((tmp_path / x).exists() for x in ("flat/summary.json", "ditch/validate_routes.png"))
    assert len(records) == 2


def test_track_verdict_checks_a_given_plan_as_the_command_checks_its_own(monkeypatch) -> None:
    """``mmstab track`` refuses an unstable plan before driving it (exit 3); the verdict of a
    plan handed in is the same, and nothing is tracked."""
    import mmstab.app
    import mmstab.runs.verdict as verdict
    from mmstab.outputs.tracking import track_verdict

    class Given:
        poses = np.zeros((4, 3))

    monkeypatch.setattr(verdict, "plan_stability", lambda problem, plan: {"stable": False})
    monkeypatch.setattr(verdict, "describe_plan_verdict", lambda v, total: "unstable")

    def never(*args, **kwargs):
        raise AssertionError("an unstable plan was tracked")

    monkeypatch.setattr(mmstab.outputs.tracking, "track", never)
    monkeypatch.setattr(mmstab.app, "plan", never)
    assert track_verdict(object(), Given()) == "tips"  # type: ignore[arg-type]
