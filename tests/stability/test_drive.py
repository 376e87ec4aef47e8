"""The skid-steer drive layer (mmstab.stability.drive) and ``physics.turn_ratio``.

The layer commands the belts ``v ∓ ω b / (2 η)`` for the twist the controller's sprocket
rates mean. Checked: ``auto`` is the skid model's level pivot ratio; belts clipped at the
track limit keep their ratio; in MuJoCo on level ground a pivot and an arc driven through
the layer with MuJoCo's own ratio (measured here from a kinematic pivot) reach the
commanded yaw rate, where the kinematic belts reach about half; bad settings exit 2.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import write_problem

from mmstab.stability.drive import DriveLayer, pivot_turn_ratio, resolve_turn_ratio
from mmstab.stability.skid import skid_twist, track_patch, turn_slide


def test_auto_is_the_skid_models_level_pivot_ratio(robot):
    """Independently: a faster pivot on another friction (the model scales with both)."""
    t = robot.base.tracks
    com = robot.overall_com(robot.arm_com(robot.stowed))
    tw = skid_twist(track_patch(robot), [0.0, 0.0, -9.81], com, (-0.45, 0.45), 0.6)
    expected = float(tw.yaw_rate[0]) / (0.9 / t.separation)
    assert resolve_turn_ratio(robot, "auto") == pytest.approx(expected, abs=1e-6)
    assert pivot_turn_ratio(robot) == pytest.approx(0.617, abs=0.005)  # docs/skid.md
    assert resolve_turn_ratio(robot, 0.8) == 0.8


def test_belts_for_the_twist_and_clipped_with_their_ratio(robot):
    t = robot.base.tracks
    r, b = t.sprocket_radius, t.separation
    kinematic = DriveLayer.of(robot, 1.0).belts([[-2.0, 3.0], [1.0, 1.0]])
    assert np.array_equal(
        kinematic, r * np.array([[-2.0, 3.0], [1.0, 1.0]])
    )  # today's, bit for bit
    eta = 0.6
    drive = DriveLayer.of(robot, eta)
    u = drive.belts([2.0, 4.0])  # v = 0.27 m/s, ω = 0.18 / 0.42 rad/s: below the limit
    v, w = r * 3.0, r * 2.0 / b
    np.testing.assert_allclose(u, [v - w * b / (2 * eta), v + w * b / (2 * eta)], atol=1e-12)
    assert u.mean() == pytest.approx(v) and (u[1] - u[0]) / b == pytest.approx(w / eta)
    # near the limit the widened differential passes it: both scale down together
    fast = np.array([-0.5, 1.0]) * t.velocity_limit
    free = DriveLayer(r, b, eta, np.inf).belts(fast)
    clipped = drive.belts(fast)
    assert np.max(np.abs(free)) > drive.limit
    assert np.max(np.abs(clipped)) == pytest.approx(drive.limit, rel=1e-12)
    assert clipped[0] / clipped[1] == pytest.approx(free[0] / free[1], rel=1e-12)


def test_turn_slide_prices_the_belts_the_drive_commands(robot):
    """The slide per radian of a turn is the model's at the drive layer's belts."""
    patch = track_patch(robot)
    g = np.array([[0.0, -9.81 * np.sin(0.1), -9.81 * np.cos(0.1)]])  # 5.7° side slope
    com = robot.overall_com(robot.arm_com(robot.stowed))
    eta, v, w = 0.6, 0.2, 0.5
    ts = turn_slide(patch, g, com, [v], [w], 0.8, turn_ratio=eta)
    half = w * patch.separation / (2 * eta)
    belts = [[v - half, v + half]]
    slope = skid_twist(patch, g, com, belts, 0.8)
    # measured at the CoM's foot c: B's velocity plus ω × c, beyond the command
    at_c = slope.velocity_body[0] + slope.yaw_rate[0] * np.r_[-com[1], com[0]]
    down = np.sum((at_c - [v, 0.0]) * [0.0, -1.0])
    assert ts.turn_ratio[0] == pytest.approx(slope.yaw_rate[0] / w)
    assert ts.per_radian[0] == pytest.approx(max(down, 0.0) / abs(slope.yaw_rate[0]))
    assert ts.turn_ratio[0] > 0.9  # the widened differential turns at about the path's rate
    kinematic = turn_slide(patch, g, com, [v], [w], 0.8)
    assert kinematic.turn_ratio[0] < 0.7


def _yaw_rate(robot, belts, spin_up=1.0, duration=2.0):
    """Mean yaw rate [rad/s] on level ground in MuJoCo over ``duration`` after ``spin_up``."""
    from mmstab.physics.robot_sim import RobotSim

    sim = RobotSim(robot)
    sim.step((0.0, 0.0), None, 0.5)
    a = sim.step(belts, None, spin_up)
    b = sim.step(belts, None, duration)
    return np.angle(np.exp(1j * (b.yaw - a.yaw))) / duration


@pytest.mark.mujoco
def test_mujoco_turns_at_the_commanded_rate_through_the_drive(robot):
    """Pivot and arc: 0.45-0.6 of the commanded yaw rate at η = 1; within 5 % at MuJoCo's η."""
    pytest.importorskip("mujoco")
    t = robot.base.tracks
    kinematic = DriveLayer.of(robot, 1.0)
    pivot, arc = np.array([-3.0, 3.0]), np.array([2.0, 4.0])  # sprocket rates [rad/s]

    def commanded(rates):
        return t.sprocket_radius * (rates[1] - rates[0]) / t.separation

    eta = _yaw_rate(robot, kinematic.belts(pivot)) / commanded(pivot)  # MuJoCo's own ratio
    assert 0.45 < eta < 0.6  # docs/skid.md: 0.534
    assert 0.45 < _yaw_rate(robot, kinematic.belts(arc)) / commanded(arc) < 0.6
    drive = DriveLayer.of(robot, eta)
    for rates in (pivot, arc):
        got = _yaw_rate(robot, drive.belts(rates))
        assert got == pytest.approx(commanded(rates), rel=0.05)


@pytest.mark.parametrize("bad", [0.0, 1.5, -0.2, "fast", None])
def test_bad_turn_ratio_exits_2_naming_file_and_field(tmp_path, capsys, bad):
    from mmstab.cli import main

    path = write_problem(tmp_path, lambda p, r: p.setdefault("physics", {}).update(turn_ratio=bad))
    assert main(["simulate", str(path), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and str(path) in err and "physics.turn_ratio" in err
