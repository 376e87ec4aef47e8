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
    duration = approach_duration(robot, move, lap, least, lap_time)
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
    assert approach_duration(robot, move, lap, 0.1, 30.0) == pytest.approx(expected, rel=1e-12)
    assert approach_duration(robot, move, lap, 5.0, 30.0) == 5.0  # approach_time is a floor


def test_a_lap_that_keeps_the_arm_moving_is_not_caught_and_the_run_says_so(robot):
    """The lap swings the elbow 3.8 rad every 0.6 s (half its speed limit) all along: the
    approach, at rest at each knot and at most 0.3 of the limit, never meets it. Lengthened
    to the lap's time or more, it is noted (the arm follows the approach, not the plan); a
    lap whose arm stands still is caught within seconds, and nothing is noted."""
    from mmstab.control.approach_path import approach_outlasts

    lap_time = 30.0
    swing = 0.5 * robot.joint_velocity[2] * 0.6  # [rad] per 0.6 s piece
    fractions = np.linspace(0.0, 1.0, 51)  # a knot every 0.6 s
    lap_q = np.tile(robot.stowed, (51, 1))
    lap_q[1::2, 2] -= swing
    move = np.array([robot.stowed, robot.stowed + [0.0, 0.0, -0.3, 0.0]])
    duration = approach_duration(robot, move, Lap(fractions, lap_q), 1.0, lap_time)
    assert duration >= lap_time
    said = approach_outlasts(duration, lap_time)
    assert said is not None and f"takes {duration:.0f} s" in said
    assert "follows the approach, not the plan" in said
    still = Lap(np.array([0.0, 1.0]), np.vstack([move[-1], move[-1]]))
    caught = approach_duration(robot, move, still, 1.0, lap_time)
    assert caught < 5.0 and approach_outlasts(caught, lap_time) is None
