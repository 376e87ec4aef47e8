"""A user's 3-joint arm on a lap: the arm's path between planned postures, as tracked.

The robot is written as docs/robot.md tells a user to write one (a 32 kg robot, 0.6 m
tracks, flat 25 cm flippers, a 3-joint arm with 1-1.2 rad/s joints). Its postures are the
ones the lap's searches chose on ``terrain: {slope: 0.2}`` and the default circle before
these checks: ``method: sequence`` swung the turret 5.4 rad between two poses, a move that
passes 0.2 mm from the body between two of the 24 postures it was checked at; the spline
through its postures cut through the robot (1703 of 30000 samples); the run asked 2.7 times
the turret's speed limit of it. ``method: cmaes``'s spline touched a track and no IK
posture repaired it. ``plan`` exited 0 on both, ``track`` 5.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any, NamedTuple

import numpy as np
import pytest
import yaml
from conftest import SCOUT

from mmstab import load_robot
from mmstab.control.approach_path import QUINTIC_PEAK, straight_approach_duration
from mmstab.control.posture import build_posture_reference
from mmstab.control.timing import JOINT_SPEED_SHARE, build_time_law
from mmstab.model.collision import CollisionChecker
from mmstab.model.reach import joint_reach
from mmstab.paths.circle import CirclePath
from mmstab.planner.searches.sequence import MoveCheck, segments_collide
from mmstab.terrain import Ramp
from mmstab.workspace.roadmap import MOVE_CLEARANCE

#: ``method: sequence``'s postures at the lap's 10 poses (grid postures of the 3-joint V).
SEQUENCE = np.array([
    [1.4826086956521736, -0.2, -0.21666666666666679],
    [0.9434782608695653, -0.2, -0.21666666666666679],
    [0.13478260869565206, -0.2, 0.0],
    [-0.40434782608695663, -0.2, 0.0],
    [-1.2130434782608697, -0.2, -0.21666666666666679],
    [-1.7521739130434784, -0.2, -0.21666666666666679],
    [-2.2913043478260873, -0.2, -0.21666666666666679],
    [3.1, -0.2, 0.0],
    [2.560869565217391, -0.2, 0.0],
    [2.0217391304347827, -0.2, -0.21666666666666679],
])  # fmt: skip
#: ``method: cmaes``'s postures at the same poses.
CMAES = np.array([
    [1.731137710969185, -0.09365583087205248, -1.6559554477752392],
    [1.6176049068912126, -0.14561422974720786, -1.044581788587757],
    [1.7454109627030079, -0.19855220870912496, -1.5904998530986434],
    [1.8988155988026258, -0.11943348842458439, -1.488098691195261],
    [1.7539880548692437, -0.1905685421101264, -1.5683789305368647],
    [1.9950416269276736, -0.16592332471434093, -1.291346070278605],
    [1.941205903547437, -0.17869169092029444, -1.1639846450195297],
    [2.2046220469283253, -0.1678406373830228, -1.0397026249135324],
    [2.1619008357621765, -0.18922120357301542, -1.138041807261523],
    [1.9245731379702515, -0.14273843229272307, -1.1721588216117402],
])  # fmt: skip
FRACTIONS = np.arange(10) / 10.0
LAP_TIME = 30.0
SAMPLES = 3000  # the reference checked every 10 ms (a run checks every control period)


class LapPlan(NamedTuple):
    """What the posture reference reads of a lap's plan."""

    fractions: np.ndarray
    target_com: np.ndarray
    postures: np.ndarray
    settings: Any


def write_robot(folder, data: dict[str, Any]):
    """The robot as a user's file, loaded as ``mmstab`` loads one (its allowed touches found)."""
    path = folder / "scout.yaml"
    path.write_text(yaml.safe_dump(data))
    return load_robot(path)


@pytest.fixture(scope="module")
def scout(tmp_path_factory):
    return write_robot(tmp_path_factory.mktemp("scout"), SCOUT)


def lap_plan(robot, postures: np.ndarray, method: str) -> LapPlan:
    return LapPlan(FRACTIONS, robot.arm_com(postures), postures, SimpleNamespace(method=method))


def fine_clearance(robot, qa: np.ndarray, qb: np.ndarray, n: int = 4000) -> float:
    """The least FCL clearance [m] of the straight move qa -> qb at n + 1 postures."""
    u = np.linspace(0.0, 1.0, n + 1)[:, None]
    return float(CollisionChecker(robot).clearance(qa + u * (qb - qa)).min())


def test_a_long_move_grazing_the_body_between_coarse_checks_is_refused(scout):
    checker = CollisionChecker(scout)
    qa, qb = SEQUENCE[[6]], SEQUENCE[[7]]  # the turret -2.29 -> 3.10 rad
    assert not segments_collide(checker, qa, qb).any()  # the 24-posture sieve passes it
    assert fine_clearance(scout, qa[0], qb[0]) < 0.5e-3  # it passes 0.2 mm from the body
    reach = joint_reach(scout, SEQUENCE)
    assert MoveCheck(checker, scout, reach).refused(qa, qb).tolist() == [True]
    # a short move that keeps its distance is still allowed, and keeps it at every posture
    qa, qb = SEQUENCE[[0]], SEQUENCE[[1]]
    assert MoveCheck(checker, scout, reach).refused(qa, qb).tolist() == [False]
    assert fine_clearance(scout, qa[0], qb[0]) >= MOVE_CLEARANCE


def test_a_sequence_plan_is_followed_on_its_moves_where_its_spline_touches(scout):
    spline = build_posture_reference(scout, lap_plan(scout, SEQUENCE, "cmaes"), SAMPLES,
                                     repair=False)  # fmt: skip
    assert spline.interpolation == "spline" and spline.check.colliding_samples > 100
    ref = build_posture_reference(scout, lap_plan(scout, SEQUENCE, "sequence"), SAMPLES)
    assert ref.interpolation == "moves" and ref.via == ()
    assert ref.planned_check.colliding_samples == spline.check.colliding_samples
    assert ref.check.colliding_samples == 0
    # on the straight move between consecutive postures, at rest at each
    s = np.array([0.6, 0.63, 0.65, 0.68, 0.7])
    q = ref(s).value
    u = (q[:, 0] - SEQUENCE[6, 0]) / (SEQUENCE[7, 0] - SEQUENCE[6, 0])
    np.testing.assert_allclose(q, SEQUENCE[6] + u[:, None] * (SEQUENCE[7] - SEQUENCE[6]),
                               atol=1e-12)  # fmt: skip
    np.testing.assert_allclose(ref(s[[0, -1]]).rate, 0.0, atol=1e-9)
    assert ref.summary(LAP_TIME)["interpolation"] == "moves"


def test_a_spline_no_ik_posture_repairs_is_repaired_on_the_straight_move(scout):
    ref = build_posture_reference(scout, lap_plan(scout, CMAES, "cmaes"), SAMPLES)
    assert ref.planned_check.colliding_samples > 50 and ref.check.colliding_samples == 0
    assert ref.interpolation == "spline" and len(ref.via) == 1
    via = ref.via[0]
    assert 0.2 < via.fraction < 0.3 and via.pairs == ("fore-track_left",)
    u = (via.fraction - 0.2) / 0.1  # on the straight move from pose 2 to pose 3
    np.testing.assert_allclose(via.posture, CMAES[2] + u * (CMAES[3] - CMAES[2]), atol=1e-12)
    assert not CollisionChecker(scout).collides(via.posture)


def test_the_time_law_keeps_the_joints_within_their_speed_limits(scout):
    ref = build_posture_reference(scout, lap_plan(scout, SEQUENCE, "sequence"), SAMPLES)
    lap = CirclePath(center=(0.0, 0.0), radius=1.5, start_angle=-np.pi / 2, direction="ccw")
    terrain = Ramp(0.2)
    rate = np.abs(ref(np.linspace(0.0, 1.0, 3001)).rate) / LAP_TIME / scout.joint_velocity
    assert rate.max() > 2.5  # the turret's swing asks 2.7 times its limit at the lap's speed
    law = build_time_law(scout, lap, terrain, ref, LAP_TIME, FRACTIONS, 0.5, (0.0, LAP_TIME))
    slowed = np.flatnonzero(law.factors < 1.0)
    assert slowed.tolist() == [6]  # the swing's stretch, 18-21 s
    speed = np.interp(np.linspace(0.0, LAP_TIME, 3001), law.tau, law.speed)
    timed = rate * speed[:, None]
    assert timed.max() <= JOINT_SPEED_SHARE * (1 + 1e-3)
    assert timed.max() >= 0.99 * JOINT_SPEED_SHARE  # and no slower than it needs
    assert law.t[-1] - LAP_TIME > 3 * (1 / law.factors[6] - 1)  # the lap takes longer


def test_a_straight_approach_keeps_the_joint_speed_limits(scout, tmp_path):
    ref = build_posture_reference(scout, lap_plan(scout, CMAES, "cmaes"), SAMPLES)
    q0 = scout.stowed
    duration, base_wait = straight_approach_duration(scout, q0, ref, 1.0, LAP_TIME)
    assert base_wait == 0.0  # met on the move (no second pose given)
    q_end = ref(duration / LAP_TIME).value[0]
    peak = QUINTIC_PEAK * np.abs(q_end - q0) / scout.joint_velocity / duration
    assert 3.7 < duration < 4.1 and 0.9 * JOINT_SPEED_SHARE < peak.max() <= JOINT_SPEED_SHARE
    # an approach within the limits keeps controller.approach_time
    slow = SCOUT | {"arm": SCOUT["arm"] | {"links": [
        link | {"limits": link["limits"] | {"velocity": 10.0}} for link in SCOUT["arm"]["links"]
    ]}}  # fmt: skip
    fast = write_robot(tmp_path, slow)
    assert straight_approach_duration(fast, q0, ref, 1.0, LAP_TIME) == (1.0, 0.0)


def test_the_api_loads_a_users_robot_as_a_problem_does(scout, tmp_path):
    """Its turret capsule meets the body at every angle: ``mmstab.load_robot`` left that pair
    checked, so every posture collided and ``mmstab.plan`` refused the lap for arm contact
    that ``mmstab plan`` accepts."""
    from mmstab.core.problem import load_problem
    from mmstab.model.robot import load_robot as load_robot_file

    write_robot(tmp_path, SCOUT)
    problem = tmp_path / "lap.yaml"
    problem.write_text(yaml.safe_dump({
        "robot": "scout.yaml", "terrain": {"slope": 0.2},
        "path": {"center": [0.0, 0.0], "radius": 1.5, "start_angle": -1.5708, "direction": "ccw"},
    }))  # fmt: skip
    allowed = load_problem(problem).robot.collision_allow
    assert scout.collision_allow == allowed and len(allowed) == 1
    assert not CollisionChecker(scout).collides(scout.stowed)
    raw = load_robot_file(tmp_path / "scout.yaml")
    assert raw.collision_allow == frozenset() and CollisionChecker(raw).collides(raw.stowed)


def test_a_route_names_where_its_arm_path_touches_in_metres(scout, tmp_path, monkeypatch):
    """The route's posture reference runs on its time fraction u; the verdict is in metres."""
    import mmstab
    import mmstab.app.api as api
    from mmstab.runs.plan_verdicts import EXIT_ARM_COLLISION

    write_robot(tmp_path, SCOUT)
    path = tmp_path / "route.yaml"
    path.write_text(yaml.safe_dump({
        "robot": "scout.yaml", "terrain": {"slope": 0.1},
        "path": {"waypoints": [[0.0, 0.0], [1.5, 0.0]], "speed": 0.3, "turn_radius": 0.0},
        "planner": {"method": "cmaes"}, "workspace": {"grid": [9, 9, 9]},
    }))  # fmt: skip
    problem = mmstab.load_problem(path)
    plan = mmstab.plan(problem)
    assert plan.exit_status == 0 and plan.verdicts["arm_contact"]["where"] == []
    seen = {}

    def touching(robot, stage, lap_time, dt):  # as if its reference touched over u in [0.25, 0.5]
        seen["lap_time"] = lap_time
        return {"reference": {"intervals_fraction": [[0.25, 0.5]], "pairs": {"fore-body": 9}}}

    monkeypatch.setattr(api, "arm_path_check", touching)
    plan = mmstab.plan(problem)
    route = plan.path
    assert seen["lap_time"] == route.lap_time  # the route's own time, as track runs it
    ((a, b),) = plan.verdicts["arm_contact"]["where"]
    assert (a, b) == pytest.approx(route.s_at([0.25, 0.5]).tolist(), abs=1e-12)
    assert 0.0 < a < b < 1.5 and plan.exit_status == EXIT_ARM_COLLISION


def test_the_api_plans_and_tracks_to_one_answer_on_arm_contact(scout, tmp_path):
    """A per-pose lap on a coarse V: its arm's path touches a track between poses, which
    ``mmstab.plan`` says (exit 5) and the tracked run confirms there, as ``mmstab track``
    judges it (``Tracked.verdicts``, ``exit_status``)."""
    import mmstab

    write_robot(tmp_path, SCOUT)
    path = tmp_path / "lap.yaml"
    path.write_text(yaml.safe_dump({
        "robot": "scout.yaml", "terrain": {"slope": 0.2},
        "path": {"center": [0.0, 0.0], "radius": 1.5, "start_angle": -1.5708, "direction": "ccw"},
        "planner": {"method": "cmaes"}, "workspace": {"grid": [9, 9, 9]},
    }))  # fmt: skip
    plan = mmstab.plan(mmstab.load_problem(path))
    assert plan.exit_status == 5 and plan.unsafe == ("arm_contact",)
    assert plan.collision_free.all()  # every planned posture is free: the path is not
    (a, b), *_ = plan.verdicts["arm_contact"]["where"]
    lap = 2 * np.pi * 1.5
    t_a, t_b = LAP_TIME * a / lap, LAP_TIME * b / lap  # the lap's time there (no move slowed)
    tracked = mmstab.track(plan, duration=t_b + 1.0)
    assert tracked.exit_status == 5 and tracked.verdicts["tip"]["verdict"] == "holds"
    record = tracked.verdicts["arm_contact"]["arm_self_collision"]
    first, _ = record["intervals_s"][0]
    # its 1 rad/s joints unfold the arm in more than approach_time, and later than the
    # base would reach the second pose: the base waits at the start for the difference
    approach = tracked.run.approach
    assert approach is not None and approach.duration > 1.0 and approach.base_wait > 0.0
    wait = approach.base_wait
    assert t_a - 0.2 + wait <= first <= t_b + wait and not tracked.accepted
