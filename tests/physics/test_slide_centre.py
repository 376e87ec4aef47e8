"""The slide measured at the pivot centre: MuJoCo's side (downhill_drift) against the plan's.

One definition of a slide (docs/skid.md, "In the verdicts"): the pivot centre's motion down
the slope beyond a command that pivots about it. The plan prices it with the skid-steer
model (:func:`mmstab.stability.skid.turn_slide`), the run measures it on the simulated
states (:func:`mmstab.physics.loop_checks.downhill_drift`).
"""

from __future__ import annotations

import numpy as np
import pytest

from mmstab.control.plant import build_plant
from mmstab.physics.loop_checks import downhill_drift, pivot_centres
from mmstab.stability.skid import pivot_centre, skid_twist, track_patch, turn_slide

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


def test_a_pivot_about_its_centre_is_no_drift_and_about_b_it_was(robot) -> None:
    """B's origin swings about the centre through 90°: the centre stays, no drift."""
    n = 200
    centre = pivot_centres(robot, np.atleast_2d(robot.stowed))[0]
    heading = np.linspace(0.0, np.pi / 2, n + 1)  # 90° in 2 s, about the centre at (1, 2)
    rot = np.stack([np.cos(heading), -np.sin(heading), np.sin(heading), np.cos(heading)], 1)
    xy = np.array([1.0, 2.0]) - (rot.reshape(-1, 2, 2) @ centre)
    states = _states(robot, xy, heading)
    qd = _pivot_qdots(robot, 0.8, n)
    plant = build_plant(robot)
    worst = 0.0
    for azimuth in np.radians(np.arange(0.0, 360.0, 45.0)):  # a 1° tilt, any direction
        g = np.array([side_slope(np.radians(1.0), h - azimuth) for h in heading[:n]])
        at_centre = downhill_drift(plant, g, states, qd, 2 * DT, 100, np.tile(centre, (n, 1)))
        assert np.abs(at_centre).max() < 1e-12
        worst = max(worst, downhill_drift(plant, g, states, qd, 2 * DT, 100, [0.0, 0.0]).max())
    # B's origin sweeps a chord 2 c sin(θ / 2) per window of θ = 45° (4.8 cm), the chord
    # turning 45° over the run: one of the 8 downhills within 22.5° of some window's chord
    chord = 2 * np.hypot(*centre) * np.sin(np.pi / 8)
    assert chord * np.cos(np.pi / 8) - 1e-9 < worst < chord + 1e-9


def test_the_run_measures_the_slide_the_plan_prices(robot) -> None:
    """A pivot on a 15° side slope, B moved by the model's own twist: the two sides agree.

    The trajectory integrates the rigid skid model's twist (its gravity in B turning with
    the heading); :func:`downhill_drift` on it over the whole turn equals the plan's slide per
    radian (:func:`turn_slide`) times the heading it turned, step by step.
    """
    patch, alpha, w, n = track_patch(robot), np.radians(15.0), 0.5, 150
    com = robot.overall_com(robot.arm_com(robot.stowed))
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
    centre = pivot_centre(patch, com)
    run = downhill_drift(build_plant(robot), np.array(g), states, _pivot_qdots(robot, w, n), DT,
                         n, centre)  # fmt: skip
    assert heading[-1] > 0.4 and plan > 0.04  # 0.46 rad, 5.8 cm
    assert run[-1] == pytest.approx(plan, rel=0.01)
    # at B's origin the run saw the swing too: B is carried by -R(θ) c about the centre, so
    # the downhill (-y in M) difference is the y of R(θ) c - c, c_x sin θ + c_y (cos θ - 1)
    at_b = downhill_drift(build_plant(robot), np.array(g), states, _pivot_qdots(robot, w, n), DT,
                          n, [0.0, 0.0])  # fmt: skip
    (cx, cy), turned = centre[0], heading[-1]
    swing = cx * np.sin(turned) + cy * (np.cos(turned) - 1)
    assert at_b[-1] - run[-1] == pytest.approx(swing, abs=1e-9)


@pytest.mark.mujoco
def test_mujoco_s_level_pivot_leaves_its_centre_where_it_was(robot) -> None:
    """A 95° pivot on a level plane in MuJoCo: 0.2 cm a second at the centre, 2.5 at B.

    The simulated states every 20 ms; the downhill a 1° tilt in any of 8 directions (the
    plane's own is none: the bumps of rough ground set it). MuJoCo's robot pivots about a
    point 0.5 cm ahead of the model's centre (docs/skid.md), so the centre moves 0.5 cm per
    radian; B's origin sweeps its 6-7 cm chord.
    """
    from mmstab.physics.robot_sim import RobotSim
    from mmstab.terrain.factory import planar_terrain

    sim = RobotSim(robot, planar_terrain(0.0, MU))
    w, dt, n = 0.7, 0.02, 225  # commanded 0.7 rad/s: MuJoCo turns at about half of it
    b = robot.base.tracks.separation
    belts = (-w * b / 2, w * b / 2)
    sim.step((0.0, 0.0), None, 0.5)
    rows = []
    for _ in range(n + 1):
        s = sim.step(belts, None, dt)
        rows.append([s.G_T_B[0, 3], s.G_T_B[1, 3], s.yaw])
    pose = np.array(rows)
    pose[:, 2] = np.unwrap(pose[:, 2])
    assert 1.3 < pose[-1, 2] - pose[0, 2] < 1.9  # 1.66 rad measured
    states = _states(robot, pose[:, :2], pose[:, 2])
    qd, plant = _pivot_qdots(robot, w, n), build_plant(robot)
    centre = pivot_centres(robot, np.atleast_2d(robot.stowed))
    window = int(round(1.0 / dt))
    at_centre, at_b = [], []
    for azimuth in np.radians(np.arange(0.0, 360.0, 45.0)):
        g = np.array([side_slope(np.radians(1.0), h - azimuth) for h in pose[:n, 2]])
        at_centre.append(downhill_drift(plant, g, states, qd, dt, window, centre).max())
        at_b.append(downhill_drift(plant, g, states, qd, dt, window, [0.0, 0.0]).max())
    assert max(at_centre) < 0.005  # 1.7 mm measured
    assert max(at_b) > 0.02  # 2.5 cm measured
