"""The route's verdicts between its planned poses (``mmstab.runs.along``), and the rim rest.

A ditch or a kerb between two planned poses is found by the samples every few cm; the
stretch says where, which limit and by how much. The ditch of a user's map (a 20 cm deep,
0.6 m wide ditch across a 15 deg side slope, written with NumPy) gives a rest that cycles
between two triangles on the far rim: it is carried by both.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import ditch_ground

from mmstab.runs.along import (
    acceleration_margin,
    along_path,
    bracket,
    dense_verdicts,
    sample_spacing,
)
from mmstab.stability.stance import stance
from mmstab.stability.support import loaded_support
from mmstab.terrain import HeightmapTerrain
from mmstab.terrain.heightmap import Heightmap
from mmstab.terrain.rest import RestSettings

ROBOT = Path(__file__).resolve().parents[2] / "problems" / "robots" / "cameleon.yaml"


def test_acceleration_margin_by_hand():
    # 58.5 kg at 0.2 m/s^2: |f| = 58.5 * hypot(9.81, 0.2), tilted by atan(0.2 / 9.81)
    want = 58.5 * np.sqrt(9.81**2 + 0.04) * np.arctan(0.2 / 9.81)
    assert acceleration_margin(58.5, 0.2) == pytest.approx(want, rel=1e-12)
    assert acceleration_margin(58.5, 0.0) == 0.0


def test_bracket_names_the_poses_before_and_after():
    before, after = bracket([0.0, 0.5, 1.0], [0.0, 0.2, 0.5, 0.7, 1.0])
    assert before.tolist() == [0, 0, 1, 1, 2]
    assert after.tolist() == [1, 1, 2, 2, 2]


def test_a_ditch_between_two_planned_poses_is_found(robot):
    terrain = HeightmapTerrain(ditch_ground(np.random.default_rng(7))).with_robot(robot)
    assert sample_spacing(terrain) == pytest.approx(0.05)
    # two planned poses 1.6 m apart, either side of the ditch, both on flat ground
    stowed = robot.arm_com(robot.stowed)
    s_plan = np.array([0.0, 1.6])
    s = np.arange(0.0, 1.6 + 1e-9, 0.05)
    poses = np.c_[-0.8 + s, np.full_like(s, -0.8), np.zeros_like(s)]
    along = along_path(robot, terrain, poses, s, s_plan, np.tile(stowed, (2, 1)))
    ends = loaded_support(robot, terrain, poses[[0, -1]], stowed)
    assert (ends.mu > 300).all()  # the planned poses see nothing
    # the samples: the same μ as rest at each, and the ditch's nose-down pitch
    rest = [stance(terrain, robot, p).mu for p in poses]
    np.testing.assert_allclose(along.mu, rest, rtol=0, atol=1e-9)
    assert np.nanmax(along.tilt) > np.radians(25)  # the nose in the ditch, on a 15 deg slope
    found = dense_verdicts(terrain, along, margin=400.0)
    tip = found["tip"]
    assert tip["binds"] and tip["threshold"] == 400.0
    over = [x for x in tip["stretches"] if x["start_s"] <= 0.8 <= x["end_s"] + 0.3]
    assert over, tip["stretches"]  # a stretch over the ditch (x = -0.3..0.3 m)
    for x in tip["stretches"]:
        inside = (s >= x["start_s"] - 1e-9) & (s <= x["end_s"] + 1e-9)
        assert x["worst"] == pytest.approx(np.min(along.mu[inside]))
        assert x["by"] == pytest.approx(400.0 - x["worst"])
    # the slip limit at friction 0.3 (16.7 deg): the nose-down pitch slides, flat ground not
    slippery = HeightmapTerrain(terrain.heightmap, friction=0.3).with_robot(robot)
    slide = dense_verdicts(slippery, along, margin=0.0)["slide"]
    assert slide["binds"]
    assert all(x["worst"] > np.arctan(0.3) for x in slide["stretches"])
    assert 0.0 not in [x["start_s"] for x in slide["stretches"]]


def test_the_arms_move_between_two_postures_is_checked(robot):
    """Both planned postures stowed; on the move between them the arm's CoM swings 0.5 m out
    downhill (a roadmap move through the side, as ``mmstab track`` commands it): there μ is the
    state's own, far below both postures', and the tip verdict binds on those samples only."""
    from mmstab.runs.along import rock_samples

    terrain = HeightmapTerrain(ditch_ground(np.random.default_rng(7))).with_robot(robot)
    stowed = robot.arm_com(robot.stowed)
    s = np.arange(0.0, 1.6 + 1e-9, 0.05)
    poses = np.c_[-3.6 + s, np.full_like(s, -0.8), np.zeros_like(s)]  # before the ditch
    swing = (s > 0.5) & (s < 1.0)
    reference = np.tile(stowed, (len(s), 1))
    reference[swing] += [0.0, -0.5, 0.0]  # -y is downhill on the 15 deg side slope
    postures = along_path(robot, terrain, poses, s, np.array([0.0, 1.6]), np.tile(stowed, (2, 1)))
    moving = along_path(robot, terrain, poses, s, np.array([0.0, 1.6]), np.tile(stowed, (2, 1)),
                        reference)  # fmt: skip
    assert postures.arm_com.shape == (2, len(s), 3) and moving.arm_com.shape == (3, len(s), 3)
    np.testing.assert_array_equal(moving.mu[~swing], postures.mu[~swing])
    own = loaded_support(robot, terrain, poses[swing], reference[swing]).mu
    np.testing.assert_allclose(moving.mu[swing], own, rtol=0, atol=1e-9)
    assert (own < postures.mu[swing] - 100).all()
    margin = float(np.max(own)) + 10.0  # between the swing's μ and the postures'
    assert margin < float(np.min(postures.mu))
    assert not dense_verdicts(terrain, postures, margin)["tip"]["binds"]
    (stretch,) = dense_verdicts(terrain, moving, margin)["tip"]["stretches"]
    assert (stretch["start_s"], stretch["end_s"]) == (s[swing][0], s[swing][-1])
    # the rock check pushes every arm CoM of a low sample: the swing's too
    rocks = rock_samples(robot, terrain, moving, margin, 0.0, 1.0)
    assert rocks.checked.tolist() == swing.tolist()


def test_the_ditchs_nose_down_sample_is_priced_at_the_time_law(robot):
    """At friction 0.7 one sample (s = 0.70 m) pitches 40.6 deg nose down: beyond the cone
    (35.0 deg) by 5.6 deg, 1.17 m/s^2 of excess. Passed at 0.25 m/s it costs 2.3 cm while on it
    and a 0.7 cm coast on the 15 deg slope after: it holds; at 0.1 m/s it slides."""
    from mmstab.runs.along import ConeTiming

    terrain = HeightmapTerrain(ditch_ground(np.random.default_rng(7))).with_robot(robot)
    stowed = robot.arm_com(robot.stowed)
    s = np.arange(0.0, 1.6 + 1e-9, 0.05)
    poses = np.c_[-0.8 + s, np.full_like(s, -0.8), np.zeros_like(s)]
    along = along_path(robot, terrain, poses, s, np.array([0.0, 1.6]), np.tile(stowed, (2, 1)))
    beyond = np.flatnonzero(along.tilt > np.arctan(0.7))
    assert beyond.tolist() == [14] and np.degrees(along.tilt[14]) == pytest.approx(40.59, abs=0.01)
    g, th, nxt = 9.81, along.tilt[14], along.tilt[15]
    a, d = g * (np.sin(th) - 0.7 * np.cos(th)), g * (0.7 * np.cos(nxt) - np.sin(nxt))
    fast = dense_verdicts(terrain, along, 0.0, timing=ConeTiming(s / 0.25, 0.05, 1.0))["slide"]
    assert not fast["binds"] and fast["stretches"] == []
    (passed,) = fast["passed"]
    assert passed["start_s"] == passed["end_s"] == pytest.approx(0.70)
    assert passed["duration_s"] == pytest.approx(0.2)
    want = 0.5 * a * 0.2**2 + (a * 0.2) ** 2 / (2 * d)  # the pass, then its coast to a stop
    assert passed["slide_m"] == pytest.approx(want, rel=1e-9)
    assert 0.029 < want < 0.05
    slow = dense_verdicts(terrain, along, 0.0, timing=ConeTiming(s / 0.1, 0.05, 1.0))["slide"]
    assert slow["binds"] and slow["passed"] == []
    (stretch,) = slow["stretches"]
    assert stretch["slide_m"] > 0.5 * a * 0.5**2 > 0.14 and stretch["duration_s"] == pytest.approx(
        0.5
    )
    # stopped on it (the route's end there): it slides however fast it came
    end = along._replace(s=s[:15], poses=poses[:15], mu=along.mu[:15], tilt=along.tilt[:15],
                         high_centred=along.high_centred[:15])  # fmt: skip
    stop = dense_verdicts(terrain, end, 0.0, timing=ConeTiming(s[:15] / 0.25, 0.05, 1.0))["slide"]
    assert stop["binds"] and stop["stretches"][0]["slide_m"] is None  # at rest: no bound


def test_a_rest_that_cycles_on_the_rim_settles_at_the_energy_minimum(robot):
    """The track run's state at the far rim: the Newton rounds cycle between two triangles;
    the polish settles it at the CoM's lowest attitude, standing on both rims."""
    from mmstab.terrain.rest.polish import energy

    terrain = HeightmapTerrain(ditch_ground(np.random.default_rng(7))).with_robot(robot)
    pose = np.array([-0.05145186, -0.81029017, 0.19739475])
    q = np.array([1.48695085, -0.19979983, 0.24162407, -0.25352201])
    com = robot.overall_com(robot.arm_com(q))
    for backend in ("c", "numpy"):
        rounds, polished = (
            HeightmapTerrain(
                terrain.heightmap, settings=RestSettings(backend=backend, polish=polish)
            ).with_robot(robot)
            for polish in (False, True)
        )
        r0, r = rounds.rest(pose, com_body=com), polished.rest(pose, com_body=com)
        assert not r0.converged[0] and not r0.tips_over[0]  # the rounds cycle
        assert r.converged[0] and not r.tips_over[0]
        front = r.bearing[0] & (polished.candidates.points[:, 0] > 0.2)
        assert front.any()  # the far rim carries load, not only the near rim's wheels
        hm, c = terrain.heightmap, polished.candidates.points
        v0, v = (
            float(energy(hm, c, com, pose, np.array([[x.roll[0], x.pitch[0]]]))[0]) for x in (r0, r)
        )
        assert v < v0  # lower than where the rounds stopped
        mu = loaded_support(robot, polished, pose, robot.arm_com(q)).mu[0]
        assert mu > 100  # held on both rims
        # where the rounds stop, the cycle's contacts balance it (small, positive); without
        # them the near rim alone would say it tips (a false verdict)
        assert 0 < loaded_support(robot, rounds, pose, robot.arm_com(q)).mu[0] < 100
    rigid = HeightmapTerrain(
        terrain.heightmap, settings=RestSettings(cycle_tol=0.0, polish=False)
    ).with_robot(robot)
    assert loaded_support(robot, rigid, pose, robot.arm_com(q)).mu[0] < 0


def turn_problem(tmp_path, slowed: bool = False):
    """A 68 deg pivot on a 10 deg plane map at friction 0.35: the poses hold, the turn slides.

    ``slowed``: the plan slows the pivot to its slide budget (``physics.slide_budget: 0.8``);
    else it turns at the tracks' speed (``slide_budget: null``, the default) and slides.
    """
    import yaml

    problem = {
        "robot": str(ROBOT),
        "terrain": {
            "generate": {"kind": "plane", "seed": 0, "size": [8.0, 8.0], "resolution": 0.05,
                         "slope": 0.17, "azimuth": float(np.pi / 2)},
            "friction": 0.35,
        },
        "path": {"waypoints": [[-2.5, -1.0], [0.5, -1.0], [1.5, 1.5]], "speed": 0.25,
                 "turn_radius": 0.0},
        "workspace": {"grid": [10, 8, 8, 8]},
        "planner": {"spacing": 0.5},
    }  # fmt: skip
    problem["physics"] = {"slide_budget": 0.8 if slowed else None}
    path = tmp_path / "turn.yaml"
    path.write_text(yaml.safe_dump(problem))
    return path


def test_a_sliding_turn_is_one_verdict_in_text_json_and_exit_status(tmp_path, capsys, monkeypatch):
    """A 68 deg pivot on a 10 deg plane map, friction 0.35: the poses hold, the turn slides."""
    import json

    from mmstab.cli import main

    path = turn_problem(tmp_path)
    monkeypatch.chdir(tmp_path)
    assert main(["plan", str(path), "-o", str(tmp_path / "out")]) == 4
    captured = capsys.readouterr()
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["slip"]["sliding_poses"] == [] and s["along_path"]["slide"]["stretches"] == []
    (turn,) = s["slip"]["turns"]["sliding_turns"]
    # the same stretch in risk, in the verdicts, in the text
    (slide,) = s["risk"]["slides"]
    assert [slide["start_s"], slide["end_s"]] == [turn["start_s"], turn["end_s"]]
    # priced along the path's time law: the stretch is the pivot (3 m along, 1.19 rad of
    # the tracks' run of 0.2 m per radian), not the planned poses' half-metre segments
    assert 2.9 <= slide["start_s"] <= 3.25 and 3.0 <= slide["end_s"] <= 3.35
    assert s["verdicts"]["slide"] == {
        "verdict": "slides",
        "unsafe": True,
        "where": [[slide["start_s"], slide["end_s"]]],
    }
    assert f"slide: slides at s = {slide['start_s']:.2f}-{slide['end_s']:.2f} m" in captured.out
    assert "tip: holds" in captured.out and s["verdicts"]["tip"]["verdict"] == "holds"
    # the turn named with the part of the corner (68 deg) where a second's slide passes 5 cm
    (corner,) = (c["turn_deg"] for c in s["route"]["corners"] if c["waypoint"] == 1)
    named = float(np.degrees(turn["turn_rad"]))
    assert 0.5 * corner < named <= corner + 1e-6
    assert f"turning {round(named)} deg there" in captured.err


def test_the_sliding_pivot_slowed_to_its_budget_holds(tmp_path, capsys, monkeypatch):
    """The same pivot with a slide budget of 0.8: turned slower, the same verdict passes."""
    import json

    from mmstab.cli import main

    path = turn_problem(tmp_path, slowed=True)
    monkeypatch.chdir(tmp_path)
    assert main(["plan", str(path), "-o", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert (
        s["slip"]["turns"]["sliding_turns"] == [] and s["verdicts"]["slide"]["verdict"] == "holds"
    )
    law = s["route"]["time_law"]
    (corner,) = law["corners"]
    assert corner["slowed"] and corner["waypoint"] == 1 and corner["kind"] == "pivot"
    # the cap is the budget (0.8 x 5 cm in 1 s) over the corner's slide per radian
    assert corner["yaw_rate_after"] == pytest.approx(0.04 / corner["slide_per_rad_m"], rel=1e-6)
    assert corner["yaw_rate_after"] < 0.5 * corner["yaw_rate_before"]
    assert law["duration_s"] > law["duration_before_s"] and law["budget_m"] == pytest.approx(0.04)
    assert s["route"]["duration_s"] == law["duration_s"]
    (line,) = s["route"]["slowed_turns"]
    assert f"plan: {line}" in out.splitlines() and line.startswith("corner 1 at (0.50, -1.00) m")


def test_stretches_are_merged_and_a_tip_below_the_margin_is_named_so():
    from mmstab.runs.along import limit_verdicts, merged

    assert merged([[4.29, 4.84], [0.0, 0.49], [0.0, 0.55], [4.42, 4.91]]) == [
        [0.0, 0.55], [4.29, 4.91]
    ]  # fmt: skip
    summary = {
        "s": [0.0, 0.5, 1.0],
        "stability": {"stable": False, "mu_min": 300.0, "unstable_poses": [],
                      "stretches": [{"start_s": 0.6, "end_s": 0.7, "worst": 29.3}]},
        "slip": {"slides": False},
        "risk": {"slides": []},
        "climb": {"stalls": False, "steps": []},
        "high_centred": {"high_centred": False, "stretches": []},
        "poses": [{"collision_free": True}] * 3,
    }  # fmt: skip
    v = limit_verdicts(summary)
    assert v["tip"] == {"verdict": "below_margin", "unsafe": True, "where": [[0.6, 0.7]],
                        "mu_min": 29.3}  # fmt: skip
    summary["stability"]["stretches"][0]["worst"] = -4.0
    assert limit_verdicts(summary)["tip"]["verdict"] == "tips"
    assert [v[k]["verdict"] for k in ("slide", "step", "high_centred", "arm_contact")] == [
        "holds"
    ] * 4


def test_verify_status_lets_physics_refuse_an_accepted_route(capsys):
    from mmstab.cli.status import EXIT_ARM_COLLISION, EXIT_SLIDES, EXIT_UNSTABLE
    from mmstab.cli.verdicts import verify_status

    def v(plan, mujoco, event=None):
        events = dict.fromkeys(("tipped", "left_map", "slid", "arm_ground_contact", "stalled"))
        if event == "arm_ground_contact":  # its time is the first contact's
            events[event] = {"first_time_s": 17.76, "fraction_of_checks": 0.003, "s_m": 3.6}
        elif event:
            events[event] = {"time_s": 3.0, "xy_m": [0.5, 0.1], "s_m": 1.25}
        agree = (plan == "accepted") == (mujoco == "holds")
        return {"plan": plan, "mujoco": mujoco, "agree": agree, "events": events,
                "mu_relative_difference_median": 0.02, "simulated_s": 9.0,
                "base_error_max_m": 0.05, "base_origin_error_max_m": 0.06, "run": "x"}  # fmt: skip

    assert verify_status(None, None) is None
    assert verify_status(v("accepted", "holds"), None) is None
    assert verify_status(v("accepted", "slides", "slid"), None) == EXIT_SLIDES
    assert verify_status(v("accepted", "leaves the map", "left_map"), None) == EXIT_SLIDES
    assert verify_status(v("accepted", "tips", "tipped"), None) == EXIT_UNSTABLE
    assert verify_status(v("accepted", "stalls", "stalled"), None) is None
    assert verify_status(v("slides", "holds"), EXIT_SLIDES) == EXIT_SLIDES  # its own status
    out = capsys.readouterr()
    assert "physics disagrees: mmstab accepted the route but in MuJoCo it tips" in out.err
    assert "DISAGREE" in out.out and "slides (slid at 3.00 s (s = 1.25 m))" in out.out
    touched = v("accepted", "touches the ground", "arm_ground_contact")
    assert verify_status(touched, None) == EXIT_ARM_COLLISION == 5  # as simulate's exit
    assert "in MuJoCo it touches the ground (arm_ground_contact at 17.76 s (s = 3.60 m))" in (
        capsys.readouterr().err
    )


@pytest.mark.mujoco
@pytest.mark.slow
def test_plan_verify_runs_the_route_in_mujoco(tmp_path, capsys, monkeypatch):
    """The sliding turn on a plane map, planned and run in MuJoCo: both say it slides."""
    import json

    from mmstab.cli import main
    from mmstab.outputs.verify import OUTCOMES

    path = turn_problem(tmp_path)
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "out"
    assert main(["plan", str(path), "-o", str(out), "--verify", "--allow-sliding"]) == 0
    s = json.loads((out / "summary.json").read_text())
    v = s["verify"]
    sim = json.loads((out / "verify" / "summary.json").read_text())
    assert v["plan"] == "slides" and v["mujoco"] in OUTCOMES
    assert v["mujoco"] == (
        "slides" if sim["slid"] is not None and sim["tipped"] is None else v["mujoco"]
    )
    assert v["agree"] == (v["mujoco"] != "holds")
    assert (out / "verify" / "physics.png").stat().st_size > 10_000
    assert f"verify in MuJoCo ({sim['duration_s']:.1f} s): {v['mujoco']}" in capsys.readouterr().out


def test_an_arm_on_the_ground_is_a_mujoco_outcome():
    """MuJoCo's outcome of a run summary: the arm on the ground after tips, slides, before
    a stall; with none of them it holds (simulate exits 5 on the same contact)."""
    from mmstab.outputs.verify import EVENTS, OUTCOMES, outcome_of

    none = dict.fromkeys(EVENTS)
    contact = {"first_time_s": 17.76, "fraction_of_checks": 0.003}
    assert outcome_of(none) == "holds"
    assert outcome_of(none | {"arm_ground_contact": contact}) == "touches the ground"
    both = none | {"arm_ground_contact": contact, "stalled": {"time_s": 30.0}}
    assert outcome_of(both) == "touches the ground"
    assert outcome_of(both | {"slid": {"time_s": 20.0}}) == "slides"
    assert OUTCOMES[: len(EVENTS)].index("touches the ground") == EVENTS.index("arm_ground_contact")


def test_a_physics_event_is_placed_on_the_route():
    """An event's body origin and its distance along the route, by hand on an L route."""
    from types import SimpleNamespace

    from mmstab.outputs.simulate import place_events
    from mmstab.paths import SpeedLimits, route_from_waypoints, speed_profile
    from mmstab.paths.route import RoutePath

    route = route_from_waypoints(np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.5]]), 0.3)
    limits = SpeedLimits(speed=0.25, acceleration=0.5, lateral_acceleration=0.5,
                         track_speed=1.13, track_separation=0.42)  # fmt: skip
    path = RoutePath(route=route, profile=speed_profile(route, limits))
    t = np.linspace(0.0, 10.0, 11)
    state = np.zeros((11, 7))
    state[:, :2] = [[0.4 * k, 0.0] for k in range(5)] + [[2.0, 0.2 * k] for k in range(6)]
    run = SimpleNamespace(t=t, state=state)
    summary = {"tipped": {"time_s": 2.0}, "slid": {"time_s": 8.0}, "left_map": None,
               "arm_ground_contact": {"first_time_s": 3.0, "fraction_of_checks": 0.1}}  # fmt: skip
    place_events(summary, run, path)
    assert summary["tipped"]["xy_m"] == [0.8, 0.0] and summary["left_map"] is None
    assert summary["arm_ground_contact"]["xy_m"] == pytest.approx([1.2, 0.0])  # its first, 3 s
    assert summary["arm_ground_contact"]["s_m"] == pytest.approx(1.2, abs=0.01)
    assert summary["tipped"]["s_m"] == pytest.approx(0.8, abs=0.01)  # on the first leg
    # (2.0, 0.6) on the second leg: 1.7 m to the arc, a quarter circle of 0.3 m, 0.3 m on
    assert summary["slid"]["xy_m"] == pytest.approx([2.0, 0.6])
    assert summary["slid"]["s_m"] == pytest.approx(1.7 + np.pi / 2 * 0.3 + 0.3, abs=0.01)


@pytest.fixture(scope="module")
def users_ditch(tmp_path_factory):
    """``mmstab plan problems/ditch.yaml --verify`` once: (exit status, stderr, summary)."""
    import json
    import subprocess
    import sys

    from conftest import ROOT

    out = tmp_path_factory.mktemp("ditch")
    r = subprocess.run(
        [sys.executable, "-m", "mmstab", "plan", str(ROOT / "problems" / "ditch.yaml"),
         "-o", str(out), "--verify"],
        capture_output=True, text=True, cwd=ROOT, timeout=900,
    )  # fmt: skip
    return r.returncode, r.stderr, json.loads((out / "summary.json").read_text())


@pytest.mark.mujoco
@pytest.mark.slow
def test_the_users_ditch_rocks_between_the_poses(users_ditch):
    """problems/ditch.yaml: the poses straddle the ditch; the dense check finds μ low where the
    arm's move between two poses swings its CoM 0.30 m behind B as the robot climbs out
    (s = 3.65 m: 10.5 N rad; the two postures there 77.5 and 301.0), below what the route's
    accelerations need (17.6), but the push rocks it onto a support that holds, so no tip
    (MuJoCo crosses without tipping); its one sample beyond the friction cone (s = 3.15 m,
    37.7 deg against 35.0) is passed in 0.2 s at 0.25 m/s: 1.8 cm within the window, under
    5 cm: the plan holds."""
    from conftest import ROOT

    from mmstab.core.problem import load_problem

    _, _, s = users_ditch
    assert s["verify"]["plan"] == "accepted"  # the plan's own verdicts: it holds (exit 0)
    assert s["verdicts"]["tip"]["verdict"] == "holds"
    assert s["verdicts"]["slide"]["verdict"] == "holds"
    (passed,) = s["along_path"]["slide"]["passed"]
    assert passed["start_s"] == passed["end_s"] == pytest.approx(3.15, abs=0.01)
    assert np.degrees(passed["worst"]) == pytest.approx(37.67, abs=0.01)
    assert passed["duration_s"] == pytest.approx(0.05 / 0.25, rel=1e-3)  # 5 cm at 0.25 m/s
    a = 9.81 * (np.sin(passed["worst"]) - 0.7 * np.cos(passed["worst"]))  # 0.56 m/s^2
    assert 0.5 * a * 0.2**2 < passed["slide_m"] < 0.05
    # the ditch's low μ: between the poses (every planning pose is well clear: the poses miss
    # it), on the arm's move, below what the accelerations need: a rock that holds
    threshold = s["stability"]["along_threshold"]
    (rock,) = s["along_path"]["tip"]["rocks"]
    assert rock["start_s"] == rock["end_s"] == pytest.approx(3.65, abs=0.01)
    assert rock["worst"] == s["along_path"]["mu_min"] == pytest.approx(10.48, abs=0.01)
    assert 0 < rock["worst"] < threshold < rock["mu_rocked"]
    assert s["along_path"]["tip"]["stretches"] == [] and 400 < min(s["mu_planned"])
    planner = load_problem(ROOT / "problems" / "ditch.yaml").section("planner")
    assert planner["attitude_margin"] == 0.21


def test_a_low_mu_about_a_diagonal_rocks_a_low_mu_at_a_track_edge_tips(robot):
    """The dense tip verdict with the rock check (:func:`rock_samples`), by construction.

    On the saddle ``z = 0.2 x y`` the base rests on its high diagonal (front-left, rear-right)
    with the CoM moved near it: μ there is below the threshold, and pushed across it (at
    1 m/s^2) the base turns onto the opposite corner, which holds it. On flat ground with
    the CoM 5 mm inside the right track's outer edge nothing is beyond that edge: it tips.
    """
    from mmstab.runs.along import rock_samples
    from mmstab.terrain.rest import RestSettings

    x = np.arange(-1.5, 1.5 + 1e-9, 0.01)
    X, Y = np.meshgrid(x, x)
    m_arm = robot.total_mass - robot.base.mass

    def arm_for(y_overall):  # the arm CoM in B that puts the overall CoM at y [m]
        arm = np.array(robot.arm_com(robot.stowed), dtype=float)
        arm[1] = (robot.total_mass * y_overall - robot.base.mass * robot.base.com[1]) / m_arm
        return arm

    def verdict(z, arm, compliance):
        hm = Heightmap.build(z, 0.01, [x[0], x[0]], "test")
        terrain = HeightmapTerrain(hm, settings=RestSettings(compliance=compliance))
        terrain = terrain.with_robot(robot)
        s = np.array([0.0, 0.05])
        poses = np.zeros((2, 3))
        along = along_path(robot, terrain, poses, s, s, np.tile(arm, (2, 1)))
        rocks = rock_samples(robot, terrain, along, 60.0, 0.0, 1.0)
        return along, rocks, dense_verdicts(terrain, along, 0.0, 60.0, rocks)["tip"]

    along, rocks, tip = verdict(0.2 * X * Y, arm_for(0.038), 0.0)
    assert (along.mu < 60).all() and rocks.checked.all() and rocks.holds.all()
    assert not tip["binds"] and tip["stretches"] == []
    (rocked,) = tip["rocks"]
    assert [rocked["start_s"], rocked["end_s"]] == [0.0, 0.05]
    assert rocked["worst"] == pytest.approx(np.min(along.mu))
    assert rocked["mu_rocked"] > 0 and rocked["work_m"] < rocked["barrier_m"]
    assert 0 < rocked["rock_rad"] < np.radians(10.5)  # at most onto the far corner
    # without the rock check the same samples tip
    hm = Heightmap.build(0.2 * X * Y, 0.01, [x[0], x[0]], "test")
    assert dense_verdicts(HeightmapTerrain(hm), along, 0.0, 60.0)["tip"]["binds"]
    along, rocks, tip = verdict(0.0 * X, arm_for(-0.255), 0.02)
    assert (along.mu < 60).all() and rocks.checked.all() and not rocks.holds.any()
    assert tip["binds"] and tip["rocks"] == [] and (rocks.mu == -np.inf).all()


def test_a_routes_cone_check_at_its_planned_poses_counts_at_its_ends_only():
    """The path passes its interior planned poses (the dense samples price them); it rests
    at the first and the last."""
    from mmstab.runs.plan_verdicts import passed_poses

    bad = [{"index": k, "pose": [0.0, 0.0, 0.0], "tilt": 0.7} for k in (1, 2)]
    inner = passed_poses({"slides": True, "sliding_poses": bad}, (0, 3))
    assert not inner["slides"] and inner["sliding_poses"] == []
    assert [b["index"] for b in inner["passed_poses"]] == [1, 2]
    ends = passed_poses({"slides": True, "sliding_poses": [*bad, {**bad[0], "index": 3}]}, (0, 3))
    assert ends["slides"] and [b["index"] for b in ends["sliding_poses"]] == [3]


@pytest.mark.mujoco
@pytest.mark.slow
def test_the_users_ditch_in_mujoco_on_the_support_mmstab_assumes(users_ditch):
    """problems/ditch.yaml with --verify: the plan accepts it, and MuJoCo's robot, its wheels
    free to drop the terrain's compliance (the support mmstab's μ counts), neither tips nor
    slides, its μ within 5 % of mmstab's. Climbing out of the ditch it pitches and rolls up
    to ~30 deg past the rest mmstab predicts (a dynamic climb the quasi-static rest does not
    model: docs/verdicts.md); whether the wrist then grazes the slope depends on the
    processor's rounding (it does on some, 0.1 % of the checks). The test holds what does
    not: no tip nor slide, and an arm contact, if any, only where the body is past the
    disagreement angle off its predicted rest, and --verify then says so (exit 5)."""
    returncode, stderr, s = users_ditch
    v = s["verify"]
    assert v["plan"] == "accepted" and v["mujoco"] in ("holds", "touches the ground")
    events = v["events"]
    assert all(events[e] is None for e in ("tipped", "slid", "left_map", "stalled"))
    contact = events["arm_ground_contact"]
    if contact is None:
        assert returncode == 0 and v["agree"], stderr
    else:
        angle = s["verify"]["disagreement"]["tilt_off_rest_max_rad"]
        assert contact["tilt_off_rest_rad"] > 0.35 and angle > 0.35  # physics.disagreement_angle
        assert contact["fraction_of_checks"] < 0.01
        assert returncode == 5 and not v["agree"] and "touches the ground" in stderr
    assert v["mu_relative_difference_median"] < 0.05
