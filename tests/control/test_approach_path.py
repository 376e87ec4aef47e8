"""A roadmap plan's approach: its pieces' timing (mmstab.control.approach_path)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from mmstab.control.approach_path import (
    APPROACH_PEAK_SPEED,
    approach_duration,
    eased_polyline,
    move_duration,
    roadmap_approach_knots,
)


class Lap:
    """A lap's posture reference: straight between knots at ``fractions`` (enough here)."""

    def __init__(self, fractions: np.ndarray, postures: np.ndarray):
        self.fractions, self.postures = fractions, postures

    def __call__(self, s: float) -> SimpleNamespace:
        q = np.array([np.interp(s, self.fractions, self.postures[:, j]) for j in range(4)])
        return SimpleNamespace(value=q[None, :])


def random_walk(rng: np.random.Generator, n: int, start: np.ndarray) -> np.ndarray:
    """n straight pieces from ``start``, each on one or two joints, 0.02-1.5 rad long."""
    q = [start]
    for _ in range(n):
        step = np.zeros(4)
        joints = rng.choice(4, size=rng.integers(1, 3), replace=False)
        step[joints] = rng.choice([-1, 1], size=len(joints)) * rng.uniform(0.02, 1.5, len(joints))
        q.append(q[-1] + step)
    return np.array(q)


def sampled_speed_share(robot, knots, q, duration) -> float:
    """The path's largest joint speed over its limit [-], sampled finely."""
    path = eased_polyline(knots, q)
    u = np.linspace(0.0, 1.0, 200_001)
    return float((np.abs(path(u, 1)) / duration / robot.joint_velocity).max())


@pytest.mark.parametrize("seed", range(6))
def test_every_piece_keeps_the_peak_speed_and_they_share_one_acceleration(robot, seed):
    rng = np.random.default_rng(900 + seed)
    move = random_walk(rng, int(rng.integers(1, 5)), robot.stowed)
    # the lap starts where the move ends and moves its arm over its first seconds
    lap_q = random_walk(rng, 12, move[-1])
    lap = Lap(np.r_[0.0, np.sort(rng.uniform(0.0, 0.2, 11)), 1.0], lap_q)
    lap_time, least = 60.0, 1.0
    duration, base_wait = approach_duration(robot, move, lap, least, lap_time)
    assert base_wait == 0.0
    assert duration >= max(least, move_duration(robot, move)) - 1e-12
    knots, q = roadmap_approach_knots(robot, move, lap, duration / lap_time)
    assert len(q) > len(move)  # the lap's pieces are in it, and were timed with the move's
    # the longest piece runs at the peak speed allowed, none faster
    assert sampled_speed_share(robot, knots, q, duration) == pytest.approx(
        APPROACH_PEAK_SPEED, rel=1e-3
    )
    # smoothstep pieces: peak acceleration 6 a / h² (a: time at the limits), the same for all
    a = (np.abs(np.diff(q, axis=0)) / robot.joint_velocity).max(axis=1)
    h = np.diff(knots) * duration
    accel = 6 * a / h**2
    np.testing.assert_allclose(accel, accel[0], rtol=1e-9)


def test_the_move_alone_sets_the_time_when_the_lap_stands_still(robot):
    move = np.array(
        [robot.stowed, robot.stowed + [0.0, 0.0, -1.2, 0.0], robot.stowed + [0.3, 0.0, -1.2, 0.0]]
    )
    lap = Lap(np.array([0.0, 1.0]), np.vstack([move[-1], move[-1]]))
    a = np.array([1.2 / robot.joint_velocity[2], 0.3 / robot.joint_velocity[0]])
    expected = 1.5 * np.sqrt(a).max() * np.sqrt(a).sum() / APPROACH_PEAK_SPEED  # by hand
    assert move_duration(robot, move) == pytest.approx(expected, rel=1e-12)
    timed = approach_duration(robot, move, lap, 0.1, 30.0)
    assert timed.duration == pytest.approx(expected, rel=1e-12) and timed.base_wait == 0.0
    assert approach_duration(robot, move, lap, 5.0, 30.0) == (5.0, 0.0)  # a floor
    # the base would reach the plan's second pose before the move is done: the base waits
    # at the start for the whole move, and the lap starts from its first posture
    waits = approach_duration(robot, move, lap, 0.1, 30.0, latest=0.9 * expected)
    assert waits.duration == pytest.approx(expected, rel=1e-12)
    assert waits.base_wait == waits.duration and waits.meets == 0.0
    assert approach_duration(robot, move, lap, 0.1, 30.0, latest=1.1 * expected).base_wait == 0
    # approach_time is the user's: the base drives through it, whatever the second pose
    assert approach_duration(robot, move, lap, 5.0, 30.0, latest=1.0) == (5.0, 0.0)


def test_a_lap_that_keeps_the_arm_moving_is_met_at_its_second_pose_and_the_base_waits(robot):
    """The lap swings the elbow 3.8 rad every 0.6 s (half its speed limit) all along: the
    approach, at rest at each knot and at most 0.3 of the limit, never catches it on the
    move. It takes the plan's move and the step onto the lap's start alone instead, and the
    base waits at the start meanwhile (the run says so); a lap whose arm stands still is met
    on the move, and nothing is noted."""
    from mmstab.control.approach_path import base_wait_note

    lap_time = 30.0
    swing = 0.5 * robot.joint_velocity[2] * 0.6  # [rad] per 0.6 s piece
    fractions = np.linspace(0.0, 1.0, 51)  # a knot every 0.6 s
    lap_q = np.tile(robot.stowed, (51, 1))
    lap_q[1::2, 2] -= swing
    move = np.array([robot.stowed, robot.stowed + [0.0, 0.0, -0.3, 0.0]])
    lap = Lap(fractions, lap_q)
    timed = approach_duration(robot, move, lap, 0.1, lap_time, latest=0.6)
    # by hand: the move's 0.3 rad on the elbow out, and 0.3 rad back to the lap's start
    a = 0.3 / robot.joint_velocity[2]
    expected = 1.5 * np.sqrt(a) * 2 * np.sqrt(a) / APPROACH_PEAK_SPEED
    assert timed.duration == pytest.approx(expected, rel=1e-12)
    assert timed.base_wait == timed.duration and timed.meets == 0.0
    said = base_wait_note(timed)
    assert said is not None and f"waits {timed.base_wait:.1f} s" in said
    still = Lap(np.array([0.0, 1.0]), np.vstack([move[-1], move[-1]]))
    caught = approach_duration(robot, move, still, 1.0, lap_time, latest=0.6)
    assert caught.duration < 5.0 and caught.base_wait == 0.0 and base_wait_note(caught) is None


def test_while_the_base_waits_the_references_hold_the_start_then_run_the_lap_late(
    problem,
):
    """A run whose base waits 1.5 s of its 2 s approach: until then the base reference
    stays on the path's start pose at zero rate; from then on the base's references are the
    lap's, 1.5 s late, and from the approach's end, where the arm meets the lap, all of
    them; the run needs 1.5 s more."""
    from mmstab.control.approach import ArmReferences, build_approach, run_reference
    from mmstab.control.controller import ControllerSettings
    from mmstab.control.posture import build_posture_reference, posture_samples

    settings = ControllerSettings.from_section(problem.section("controller"))
    robot = problem.robot
    s = np.arange(8) / 8  # the turret swinging about 2 rad, the upper arm nodding
    q = np.column_stack([2.0 + 0.4 * np.sin(2 * np.pi * s), 0.2 + 0.1 * np.cos(2 * np.pi * s)])
    q = np.column_stack([q, np.full(8, -0.3), np.zeros(8)])
    plan = SimpleNamespace(fractions=s, target_com=robot.arm_com(q), postures=q)
    dt, lap = settings.dt, settings.lap_time
    posture = build_posture_reference(robot, plan, posture_samples(lap, dt))
    approach = build_approach(robot, robot.stowed, posture, 2.0, lap, dt, base_wait=1.5)
    waits = ArmReferences(posture, approach)
    assert waits.hold == 1.5 and waits.real_time(10.0) == 11.5
    np.testing.assert_allclose(approach.posture([2.0]).value[0], posture(0.5 / lap).value[0])
    t = np.arange(0.0, 6.0 + 0.5 * dt, dt)
    ref = run_reference(robot, problem.circle, problem.terrain, plan, robot.stowed,
                        settings, t, arm=waits).step  # fmt: skip
    still, arm_on_lap = t < 1.5, t >= 2.0
    np.testing.assert_array_equal(ref.xi_des[still, :3] - ref.xi_des[0, :3], 0.0)
    np.testing.assert_array_equal(ref.xi_dot_ref[still, :3], 0.0)
    np.testing.assert_allclose(ref.q_ref[~arm_on_lap], approach.posture(t[~arm_on_lap]).value)
    # the arm-CoM feed-forward is d/dt of its reference, the base still and then driving
    # (the samples beside the base's start, where its speed steps, left out)
    fd = np.gradient(ref.xi_des[~arm_on_lap, 3:], dt, axis=0)
    away = np.abs(t[~arm_on_lap] - 1.5) > 1.5 * dt
    away[[0, -1]] = False
    np.testing.assert_allclose(ref.xi_dot_ref[~arm_on_lap, 3:][away], fd[away], atol=2e-3)
    lap_only = run_reference(robot, problem.circle, problem.terrain, plan, robot.stowed,
                             settings, t - 1.5, arm=ArmReferences(posture, None)).step  # fmt: skip
    for name, rows in (("xi_des", ~still), ("xi_dot_ref", ~still), ("ground", ~still),
                       ("q_ref", arm_on_lap), ("q_dot_ref", arm_on_lap)):  # fmt: skip
        got, want = getattr(ref, name)[rows], getattr(lap_only, name)[rows]
        cols = slice(None) if name in ("ground", "q_ref", "q_dot_ref") else slice(0, 3)
        np.testing.assert_allclose(got[:, cols], want[:, cols], atol=1e-12, err_msg=name)
        if name.startswith("xi"):  # the arm-CoM rows, from the approach's end
            np.testing.assert_allclose(
                getattr(ref, name)[arm_on_lap, 3:], getattr(lap_only, name)[arm_on_lap, 3:],
                atol=1e-12, err_msg=name,
            )  # fmt: skip
