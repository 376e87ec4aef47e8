"""The slide measured at the CoM: MuJoCo's side (downhill_drift) against the plan's.

One definition of a slide (docs/skid.md, "In the verdicts"): the motion of the CoM's foot
(the overall CoM projected along z_B on the support plane) down the slope beyond a command
that pivots about it. The plan prices it with the skid-steer model
(:func:`mmstab.stability.skid.turn_slide`), the run measures it on the simulated states
(:func:`mmstab.physics.loop_checks.downhill_drift`).
"""

from __future__ import annotations

import numpy as np
import pytest

from mmstab.control.plant import build_plant
from mmstab.physics.loop_checks import downhill_drift
from mmstab.stability.skid import skid_twist, track_patch, turn_slide

MU, DT = 0.7, 0.01


def side_slope(alpha: float, heading: float) -> np.ndarray:
    """Gravity in B on a plane rising along M's +y at ``alpha`` [rad], the body at ``heading``."""
    g = 9.81 * np.array([0.0, -np.sin(alpha), -np.cos(alpha)])
    c, s = np.cos(heading), np.sin(heading)
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]]) @ g


def _pivot_qdots(robot, w: float, n: int) -> np.ndarray:
    """Sprocket rates of a pivot commanded at ``w`` [rad/s] (kinematic belts), arm still."""
    t = robot.base.tracks
    u = w * t.separation / 2 / t.sprocket_radius
    return np.tile(np.r_[-u, u, np.zeros(robot.arm_joints)], (n, 1))


def _states(robot, xy: np.ndarray, heading: np.ndarray) -> np.ndarray:
    states = np.zeros((len(xy), 5 + robot.arm_joints))
    states[:, :2], states[:, 2], states[:, 5:] = xy, heading, robot.stowed
    return states


def _stowed_com(robot) -> np.ndarray:
    return robot.overall_com(robot.arm_com(robot.stowed))


def test_a_pivot_about_the_com_is_no_drift_and_about_b_it_was(robot) -> None:
    """B's origin swings about the CoM through 90°: the CoM stays, no drift."""
    n, com = 200, _stowed_com(robot)
    heading = np.linspace(0.0, np.pi / 2, n + 1)  # 90° in 2 s, about the CoM at (1, 2)
    rot = np.stack([np.cos(heading), -np.sin(heading), np.sin(heading), np.cos(heading)], 1)
    xy = np.array([1.0, 2.0]) - (rot.reshape(-1, 2, 2) @ com[:2])
    states = _states(robot, xy, heading)
    qd = _pivot_qdots(robot, 0.8, n)
    plant = build_plant(robot)
    worst = 0.0
    for azimuth in np.radians(np.arange(0.0, 360.0, 45.0)):  # a 1° tilt, any direction
        g = np.array([side_slope(np.radians(1.0), h - azimuth) for h in heading[:n]])
        at_com = downhill_drift(plant, g, states, qd, 2 * DT, 100, np.tile(com, (n, 1)))
        assert np.abs(at_com).max() < 1e-12
        worst = max(worst, downhill_drift(plant, g, states, qd, 2 * DT, 100, [0.0, 0.0]).max())
    # B's origin sweeps a chord 2 |c| sin(θ / 2) per window of θ = 45° (3.7 cm), the chord
    # turning 45° over the run: one of the 8 downhills within 22.5° of some window's chord
    chord = 2 * np.hypot(*com[:2]) * np.sin(np.pi / 8)
    assert chord * np.cos(np.pi / 8) - 1e-9 < worst < chord + 1e-9


def test_the_run_measures_the_slide_the_plan_prices(robot) -> None:
    """A pivot on a 15° side slope, B moved by the model's own twist: the two sides agree.

    The trajectory integrates the rigid skid model's twist (its gravity in B turning with
    the heading); :func:`downhill_drift` on it over the whole turn equals the plan's slide per
    radian (:func:`turn_slide`) times the heading it turned, step by step.
    """
    patch, alpha, w, n = track_patch(robot), np.radians(15.0), 0.5, 150
    com = _stowed_com(robot)
    b = patch.separation
    xy, heading, g, plan = [np.zeros(2)], [0.0], [], 0.0
    for _ in range(n):
        gk = side_slope(alpha, heading[-1])
        tw = skid_twist(patch, gk, com, (-w * b / 2, w * b / 2), MU)
        omega = float(tw.yaw_rate[0])
        mid = heading[-1] + omega * DT / 2
        rot = np.array([[np.cos(mid), -np.sin(mid)], [np.sin(mid), np.cos(mid)]])
        xy.append(xy[-1] + rot @ tw.velocity_body[0] * DT)
        heading.append(heading[-1] + omega * DT)
        g.append(gk)
        plan += float(turn_slide(patch, [gk], com, [0.0], [w], MU).per_radian[0]) * omega * DT
    states = _states(robot, np.array(xy), np.array(heading))
    qd, plant = _pivot_qdots(robot, w, n), build_plant(robot)
    run = downhill_drift(plant, np.array(g), states, qd, DT, n, com)
    assert heading[-1] > 0.4 and plan > 0.04  # 0.46 rad, 6.6 cm
    assert run[-1] == pytest.approx(plan, rel=0.01)
    # at B's origin the run saw the swing too: B is carried by -R(θ) c about the CoM's foot,
    # so the downhill (-y in M) difference is the y of R(θ) c - c, c_x sin θ + c_y (cos θ - 1)
    at_b = downhill_drift(plant, np.array(g), states, qd, DT, n, [0.0, 0.0])
    (cx, cy), turned = com[:2], heading[-1]
    swing = cx * np.sin(turned) + cy * (np.cos(turned) - 1)
    assert at_b[-1] - run[-1] == pytest.approx(swing, abs=1e-9)


def _level_pivot(robot, arm_q, w: float, dt: float, n: int) -> np.ndarray:
    """MuJoCo's base pose (x, y, unwrapped yaw) every ``dt`` through a level pivot (n + 1)."""
    from mmstab.physics.robot_sim import RobotSim
    from mmstab.terrain.factory import planar_terrain

    sim = RobotSim(robot, planar_terrain(0.0, MU), arm_q=arm_q)
    b = robot.base.tracks.separation
    sim.step((0.0, 0.0), None, 0.5)
    rows = []
    for _ in range(n + 1):
        s = sim.step((-w * b / 2, w * b / 2), None, dt)
        rows.append([s.G_T_B[0, 3], s.G_T_B[1, 3], s.yaw])
    pose = np.array(rows)
    pose[:, 2] = np.unwrap(pose[:, 2])
    return pose


@pytest.mark.mujoco
def test_mujoco_s_level_pivot_barely_moves_the_com(robot) -> None:
    """A 95° pivot on a level plane in MuJoCo: 0.7 cm a second at the CoM, 2.5 at B.

    The simulated states every 20 ms; the downhill a 1° tilt in any of 8 directions (the
    plane's own is none: the bumps of rough ground set it). MuJoCo's robot pivots about a
    point 1.8 cm ahead of the CoM with the arm stowed, B's origin 6.7 cm behind it.
    """
    w, dt, n = 0.7, 0.02, 225  # commanded 0.7 rad/s: MuJoCo turns at about half of it
    pose = _level_pivot(robot, None, w, dt, n)
    assert 1.3 < pose[-1, 2] - pose[0, 2] < 1.9  # 1.66 rad measured
    states = _states(robot, pose[:, :2], pose[:, 2])
    qd, plant = _pivot_qdots(robot, w, n), build_plant(robot)
    window = int(round(1.0 / dt))
    at_com, at_b = [], []
    for azimuth in np.radians(np.arange(0.0, 360.0, 45.0)):
        g = np.array([side_slope(np.radians(1.0), h - azimuth) for h in pose[:n, 2]])
        at_com.append(downhill_drift(plant, g, states, qd, dt, window, _stowed_com(robot)).max())
        at_b.append(downhill_drift(plant, g, states, qd, dt, window, [0.0, 0.0]).max())
    assert max(at_com) < 0.01  # 0.68 cm measured
    assert max(at_b) > 0.02  # 2.5 cm measured
    assert max(at_b) > 3 * max(at_com)


@pytest.mark.mujoco
@pytest.mark.parametrize(
    "arm_q",
    [None, [1.57, 0.9, 0.8, 0.0], [1.64, -0.19, 0.25, -0.37]],
    ids=["stowed", "left", "out"],
)
def test_where_mujoco_pivots_the_com_and_the_model_s_pivot(robot, arm_q) -> None:
    """MuJoCo's level pivot centre against the CoM's foot and the rigid model's centre.

    Measured (cm, in B): stowed MuJoCo (6.7, 0.2), the model's centre (6.3, 0.3), the CoM
    (4.9, -0.2); the arm out to the left (3.4, -3.4), (3.0, -5.2), (2.4, 3.1); a planned
    posture of validation route 40 (2.3, -13.7), (2.0, -45.7), (1.8, 8.2). Along the belts
    MuJoCo turns about a point 1.3-1.4 times as far ahead as the CoM, as the model does;
    sideways away from the more loaded belt, 1.1-1.7 times the CoM's offset, where the
    model's rigid-plate loads put it 1.7-5.6 times: a point the plan cannot place.
    """
    from mmstab.physics.skid_sim import measure_twist

    q = robot.stowed if arm_q is None else np.asarray(arm_q)
    b = robot.base.tracks.separation
    m = measure_twist(robot, 0.0, 0.0, (-0.4 * b / 2, 0.4 * b / 2), MU, q)
    mujoco = np.array([-m.velocity_body[1], m.velocity_body[0]]) / m.yaw_rate
    com = robot.overall_com(robot.arm_com(q))
    level = skid_twist(track_patch(robot), [0.0, 0.0, -9.81], com, (-1.0, 1.0), 1.0)
    model = np.r_[-level.velocity_body[0, 1], level.velocity_body[0, 0]] / level.yaw_rate[0]
    # along the belts: both ahead of the CoM, MuJoCo within 0.6 cm of the model
    assert abs(mujoco[0] - model[0]) < 0.006 and mujoco[0] * com[0] > 0
    assert 1.1 < mujoco[0] / com[0] < 1.6
    # sideways: both on the far side from the CoM; the model twice as far or more out
    if abs(com[1]) > 0.01:
        assert mujoco[1] * com[1] < 0 and model[1] * com[1] < 0
        assert abs(model[1]) > 1.4 * abs(mujoco[1])
    # with the arm stowed MuJoCo turns within 2 cm of the CoM's foot: a level pivot moves
    # it at most 2 cm per radian
    if arm_q is None:
        assert np.linalg.norm(mujoco - com[:2]) < 0.02
