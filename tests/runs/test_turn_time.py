"""A turn faster than the closed loop turns is priced over the time it takes (runs.verdict)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import ROOT

from mmstab.control.limits.yaw_rate import YAW_MARGIN
from mmstab.runs.verdict import TRACKS_TIME_MARGIN, TurnCheck, turn_slip, turn_time
from mmstab.stability.skid import TURN_FLOOR, track_patch, turn_slide
from mmstab.stability.slip import terrain_friction
from mmstab.terrain import Ramp


def test_turn_time_by_hand():
    """1 rad in 0.5 s (2 rad/s): the heading turns at min(2, share (2 + margin))."""
    turn = np.array([1.0, 1.0, 1.0, 1.0, 0.0, -1.0, 1.0])
    dt = np.full(7, 0.5)
    ratio = np.array([0.6, 0.3, 1.2, np.nan, np.nan, -0.8, 0.6])
    bounded = np.array([True] * 6 + [False])
    took = turn_time(turn, dt, ratio, bounded)
    up = 2.0 + YAW_MARGIN
    assert took == pytest.approx([
        1 / (0.6 * up),  # the model's share of the controller's most
        1 / (TURN_FLOOR * up),  # at least the floor's share
        0.5,  # the tracks keep up: the path's time
        0.5,  # no twist (beyond the cone): the path's
        0.5,  # no turn
        1 / (0.8 * up),  # either way
        0.5,  # below the limit's slope: the path's
    ])  # fmt: skip


def test_a_slow_turn_keeps_the_path_s_time():
    """Up to margin x floor / (1 - floor) the loop keeps up whatever the model's share."""
    rate = np.linspace(0.01, YAW_MARGIN * TURN_FLOOR / (1 - TURN_FLOOR), 20)
    for ratio in (0.0, 0.2, 0.6, 1.5):
        took = turn_time(rate * 0.1, np.full(20, 0.1), np.full(20, ratio))
        assert took == pytest.approx(np.full(20, 0.1), rel=1e-9)
    # just past it a floor-share turn is stretched
    assert turn_time(np.array([0.1 * 0.3]), np.array([0.1]), np.array([0.0]))[0] > 0.1


def test_a_fast_pivot_slides_at_the_achieved_rate(robot, monkeypatch):
    """A 90 deg pivot at 2 rad/s on a 20 deg ramp: the path's law would put it all in 0.8 s.

    The heading turns at min(2, share (2 + margin)) rad/s: the pivot lasts longer and its
    worst second holds less than the path's law gives it (the whole turn's slide), at least
    the achieved rate's share of it with the margin.
    """
    import mmstab.runs.verdict as verdict

    ramp = Ramp(np.radians(20.0))
    com = robot.arm_com(robot.stowed)
    t = np.linspace(0.0, np.pi / 4, 200)
    poses = np.c_[np.zeros((200, 2)), 2.0 * t]
    check = TurnCheck(robot, com, t, 0.05, 1.0, shear_modulus=0.0041)
    out = turn_slip(ramp, poses, check)
    g, mu = ramp.gravity_body(poses), terrain_friction(ramp)
    ts = turn_slide(track_patch(robot), g, robot.overall_com(com), np.zeros(200),
                    np.full(200, 2.0), mu, 1.0, 0.0041)  # fmt: skip
    share = np.maximum(np.abs(ts.turn_ratio), TURN_FLOOR)
    achieved = np.minimum(2.0, share * (2.0 + YAW_MARGIN))
    assert achieved.max() < 2.0 * 0.95  # the loop turns slower than the path asks
    monkeypatch.setattr(verdict, "turn_time", lambda turn, dt, ratio, bounded=True: dt)
    path_law = turn_slip(ramp, poses, check)
    worst, whole = (x["sliding_turns"][0]["slide_in_window_m"] for x in (out, path_law))
    assert out["sliding_turns"][0]["last"] == path_law["sliding_turns"][0]["last"] == 199
    assert worst < whole  # spread over more than the path's 0.8 s
    # at least the slowest second's share of the whole, with the margin
    assert worst >= TRACKS_TIME_MARGIN * whole * achieved.min() / (np.pi / 2) * 0.999


def test_the_margin_covers_make_skid_rates_fast_pivots():
    """The committed grid's largest slide-per-second ratio, MuJoCo over the model, is covered."""
    s = json.loads((ROOT / "results" / "skid_rates" / "summary.json").read_text())
    fast = [x for x in s["rated"] if x["yaw_rate"] > s["slow"]["yaw_rate_max"]]
    assert s["fast"]["per_second_ratio_max"] == pytest.approx(
        max(x["per_second_ratio"] for x in fast))  # fmt: skip
    assert TRACKS_TIME_MARGIN >= s["fast"]["per_second_ratio_max"]
