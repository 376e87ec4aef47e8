"""A circle's lap is checked as a route is: every few cm, the lap closing on its first pose."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ditch_ground

from mmstab.paths.circle import CirclePath
from mmstab.planner import Plan, PlannerSettings
from mmstab.runs.along import along_path, bracket
from mmstab.runs.arm_ground import arm_heights
from mmstab.runs.high_centred import path_samples
from mmstab.runs.plan_verdicts import lap_acceleration, lap_verdicts, slide_stretches
from mmstab.runs.verdict_settings import VerdictSettings
from mmstab.stability.stance import stance
from mmstab.stability.support import loaded_mu
from mmstab.terrain import HeightmapTerrain

#: The lap: 3 m about the map's centre, its 10 planned poses 18 deg off the ditch's crossings.
LAP = CirclePath((0.0, 0.0), 3.0, -np.pi / 2 + np.pi / 10)
K = 10


def test_a_closed_bracket_joins_the_last_pose_to_the_first():
    before, after = bracket([0.0, 1.0, 2.0], [0.0, 0.5, 1.9, 2.0, 2.9], closed=True)
    assert before.tolist() == [0, 0, 1, 2, 2]
    assert after.tolist() == [1, 1, 2, 0, 0]


def test_a_laps_acceleration_is_its_centripetal_one_at_least_the_routes(robot):
    assert lap_acceleration(LAP, 30.0) == pytest.approx(0.3)  # 0.39 m/s on 3 m: 0.05 m/s^2
    fast = (LAP.length / 5.0) ** 2 / 3.0
    assert lap_acceleration(LAP, 5.0) == pytest.approx(fast) and fast > 0.3


def ditch_map(rng: np.random.Generator):
    """A 10 m map: 10 deg side slope (uphill +y), a 0.6 m, 20 cm ditch across x = 0, bumps."""
    return ditch_ground(rng, slope_deg=10.0, bump_m=0.05)


def test_the_laps_arm_closes_on_the_first_poses_posture(robot):
    """Past the last planned pose the samples carry the last pose's and the first pose's arm."""
    terrain = HeightmapTerrain(ditch_map(np.random.default_rng(3))).with_robot(robot)
    poses, s = path_samples(LAP)
    s_plan = LAP.length * np.arange(K) / K
    arm = np.tile(robot.arm_com(robot.stowed), (K, 1))
    arm[0] += [0.1, 0.0, 0.0]  # the first pose's arm reaches forward
    along = along_path(robot, terrain, poses, s, s_plan, arm, closed=True)
    last = s > s_plan[-1]
    assert last.sum() > 5
    np.testing.assert_array_equal(along.arm_com[0][last], np.tile(arm[-1], (last.sum(), 1)))
    np.testing.assert_array_equal(along.arm_com[1][last], np.tile(arm[0], (last.sum(), 1)))
    route_like = along_path(robot, terrain, poses, s, s_plan, arm)  # a route ends at its last
    assert not np.array_equal(route_like.arm_com[1][last], along.arm_com[1][last])


def test_a_ditch_the_laps_planned_poses_step_over_is_found(robot, problem):
    """The lap crosses the ditch twice, between planned poses: μ there is each sample's own
    (mmstab's one support), and the lap's verdicts name the crossings, as a route's would."""
    terrain = HeightmapTerrain(ditch_map(np.random.default_rng(3))).with_robot(robot)
    stowed = robot.stowed
    fractions = np.arange(K) / K
    P = LAP.pose_at(fractions)
    com = np.tile(robot.arm_com(stowed), (K, 1))
    plan = Plan(P, fractions, com, np.tile(stowed, (K, 1)), np.zeros(K), np.ones(K, dtype=bool),
                (), PlannerSettings.from_section(problem.section("planner")))  # fmt: skip
    mu = loaded_mu(robot, terrain, P, com)
    records = [
        {"pose": P[k], "fraction": fractions[k], "target_com": com[k], "mu_planned": mu[k],
         "mu_realised": mu[k], "collision_free": True}
        for k in range(K)
    ]  # fmt: skip
    margin = 350.0
    assert np.min(mu) > margin + 50.0  # every planned pose passes, bumps and all
    settings = VerdictSettings(margin=margin)
    v = lap_verdicts(robot, terrain, LAP, plan, records, settings, 30.0)
    dense = v["along_path"]
    assert dense["samples"] == len(path_samples(LAP)[0]) and dense["spacing_m"] < 0.05
    assert v["stability"]["unstable_poses"] == []  # the planned poses see nothing
    # the dense μ is the one support's at each sample (all postures stowed)
    poses, s = path_samples(LAP)
    in_ditch = np.abs(poses[:, 0]) < 0.3
    own = [stance(terrain, robot, p).mu for p in poses[in_ditch]]
    assert dense["mu_min"] == pytest.approx(min(own), abs=1e-9)
    assert dense["mu_min"] < margin - 200.0
    # the tip stretches lie on the two crossings, and the verdict names them
    tip = v["verdicts"]["tip"]
    assert tip["unsafe"] and not v["stability"]["stable"]
    crossings = [s[in_ditch & (s < LAP.length / 2)], s[in_ditch & (s > LAP.length / 2)]]
    for c in crossings:
        assert any(a - 0.5 <= c.mean() <= b + 0.5 for a, b in tip["where"]), (c, tip["where"])
    for a, b in tip["where"]:
        assert any(c.min() - 0.5 <= a and b <= c.max() + 0.5 for c in crossings)
    assert {"tip", "slide", "high_centred", "arm_contact"} <= set(v["verdicts"])
    # the arm: the stowed arm is 22 cm above the support plane and clears the slope and its
    # bumps; where the rest pitches nose-down into the ditch (35 deg as the CoM passes its
    # rim) it meets the far wall: the arm's stretches in the ground lie on a crossing and are
    # the arm-contact verdict's
    arm = dense["arm_in_ground"]
    assert arm["contact"] and arm["unknown_samples"] == 0
    for x in arm["stretches"]:
        assert any(c.min() - 0.5 <= x["start_s"] and x["end_s"] <= c.max() + 0.5
                   for c in crossings)  # fmt: skip
    outside = np.abs(poses[:, 0]) > 1.0
    T = terrain.rest(poses[outside], strict=False).G_T_B
    away = arm_heights(robot, terrain, T, np.tile(stowed, (outside.sum(), 1)))
    assert away.min() > 0.1  # bumps of 5 cm under an arm 22 cm up
    contact = v["verdicts"]["arm_contact"]
    assert contact["unsafe"] and contact["where"] == [[x["start_s"], x["end_s"]]
                                                      for x in arm["stretches"]]  # fmt: skip


def test_a_laps_turn_across_its_start_is_named_to_the_end_and_from_zero():
    s = [0.0, 1.0, 2.0, 3.0]
    turn = {"slide_in_window_m": 0.08, "turn_rad": 0.5}
    slip = {"sliding_poses": [], "turns": {"sliding_turns": [
        {**turn, "first": 2, "last": 0}, {**turn, "first": 3, "last": 1}]}}  # fmt: skip
    got = [(x["start_s"], x["end_s"]) for x in slide_stretches(slip, s, 4.0)]
    assert got == [(0.0, 1.0), (2.0, 4.0), (3.0, 4.0)]
    route = [(x["start_s"], x["end_s"]) for x in slide_stretches(slip, s)]
    assert route == [(2.0, 0.0), (3.0, 1.0)]  # a route has no start to cross
