"""``plan --verify``: where MuJoCo's event came against where the plan flags its limit."""

from __future__ import annotations

import pytest

from mmstab.cli.verdicts import place_line
from mmstab.outputs.verify import SAME_PLACE_M, event_place

VERDICTS = {
    "tip": {"verdict": "holds", "where": []},
    "slide": {"verdict": "slides", "where": [[4.09, 4.14], [7.0, 7.5]]},
    "step": {"verdict": "holds", "where": []},
    "high_centred": {"verdict": "high-centred", "where": [[2.6, 2.8]]},
    "arm_contact": {"verdict": "holds", "where": []},
}


def _events(key: str, s: float) -> dict:
    events = dict.fromkeys(("tipped", "left_map", "slid", "arm_ground_contact", "stalled"))
    events[key] = {"time_s": 9.3, "xy_m": [s, 0.0], "s_m": s}
    return events


@pytest.mark.parametrize(
    "s,distance",
    [(2.19, 4.09 - 2.19), (4.1, 0.0), (4.6, 4.6 - 4.14), (6.0, 7.0 - 6.0), (9.0, 9.0 - 7.5)],
)
def test_a_slide_is_measured_from_the_nearest_flagged_stretch(s, distance):
    p = event_place(VERDICTS, "slides", _events("slid", s))
    assert p is not None and p["limits"] == ["slide"]
    assert p["flagged"] == [[4.09, 4.14], [7.0, 7.5]]
    assert p["distance_m"] == pytest.approx(distance, abs=1e-12)
    assert p["same_place"] is (distance <= SAME_PLACE_M)


def test_a_stall_is_placed_against_steps_and_high_centring():
    p = event_place(VERDICTS, "stalls", _events("stalled", 2.0))
    assert p is not None and p["limits"] == ["step", "high_centred"]
    assert p["flagged"] == [[2.6, 2.8]] and p["distance_m"] == pytest.approx(0.6)
    assert not p["same_place"]


def test_no_place_without_a_limit_or_an_event_place():
    assert event_place(VERDICTS, "holds", _events("slid", 1.0)) is None
    assert event_place(VERDICTS, "leaves the map", _events("left_map", 1.0)) is None
    events = _events("tipped", 1.0)
    del events["tipped"]["s_m"]  # a lap: no arc length
    assert event_place(VERDICTS, "tips", events) is None
    p = event_place(VERDICTS, "tips", _events("tipped", 1.0))
    assert p is not None and p["flagged"] == [] and p["distance_m"] is None


def test_the_line_says_where(capsys):
    for s, said in [
        (2.19, "plan: MuJoCo slides at s = 2.19 m, 1.90 m from where the plan flags it "
               "(s = 4.09-4.14, 7.00-7.50 m)"),
        (4.3, "plan: MuJoCo slides at s = 4.30 m, where the plan flags it "
              "(s = 4.09-4.14, 7.00-7.50 m)"),
    ]:  # fmt: skip
        place_line(
            {"mujoco": "slides", "place": event_place(VERDICTS, "slides", _events("slid", s))}
        )
        assert capsys.readouterr().out.strip() == said
    place_line({"mujoco": "tips", "place": event_place(VERDICTS, "tips", _events("tipped", 1.0))})
    assert capsys.readouterr().out.strip() == (
        "plan: MuJoCo tips at s = 1.00 m, the plan flags no tip anywhere"
    )
    place_line({"mujoco": "holds", "place": None})
    assert capsys.readouterr().out == ""
