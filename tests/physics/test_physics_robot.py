"""The whole robot in MuJoCo: mass model, Coulomb friction, tip-over, driving.

The numbers quoted in docs/physics.md ("The whole robot in MuJoCo") are the ones these tests
measure; ``pytest -s tests/physics/test_physics_robot.py`` prints them.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import PROBLEMS
from scipy.optimize import brentq, fsolve

pytestmark = pytest.mark.mujoco
mujoco = pytest.importorskip("mujoco")

from mmstab.core.files import MmstabError  # noqa: E402
from mmstab.model.payload import Payload, attach_payload  # noqa: E402
from mmstab.model.robot import load_robot  # noqa: E402
from mmstab.model.urdf import arm_link_inertia, base_link_inertias  # noqa: E402
from mmstab.physics.robot_model import (  # noqa: E402
    ModelSettings,
    build_robot_mjcf,
    ground_xml,
    mjcf_header,
    track_wheels,
)
from mmstab.physics.robot_sim import RobotSim  # noqa: E402
from mmstab.stability.static import robot_force_angle  # noqa: E402
from mmstab.terrain.base import DEFAULT_FRICTION  # noqa: E402
from mmstab.terrain.factory import ramp_heightmap  # noqa: E402
from mmstab.terrain.heightmap_terrain import HeightmapTerrain  # noqa: E402
from mmstab.terrain.ramp import Ramp  # noqa: E402

ROBOTS = sorted((PROBLEMS / "robots").glob("*.yaml"))
#: A posture with every joint off zero (turret, shoulder, elbow, wrist) [rad].
POSTURE = np.array([0.7, 0.4, -0.9, 0.3])
PAYLOAD = Payload(3.0, np.array([0.05, 0.01, 0.0]))
#: The loaded arm stretched out to the right (turret at 270 deg), a little raised.
TIP_POSTURE = np.array([1.5 * np.pi, 0.3, -0.3, 0.0])


def fmt(values) -> str:
    return " ".join(repr(float(v)) for v in np.ravel(values))


def report(**numbers) -> None:
    print("\nMEASURED " + ", ".join(f"{k}={v:.4g}" for k, v in numbers.items()))


@pytest.fixture(scope="module")
def cameleon():
    return load_robot(PROBLEMS / "robots" / "cameleon.yaml")


# ---------------------------------------------------------------------------- mass model
def point(m, r):
    return m * (float(r @ r) * np.eye(3) - np.outer(r, r))


def mmstab_parts(robot, q, payload):
    """(mass, CoM in B, inertia about own CoM in B) of every part, as mmstab defines them."""
    parts, boxes = [], robot.base.collision_boxes()
    for name, inertia in base_link_inertias(robot).items():
        T = boxes[name].frame_T_shape @ inertia.frame_T_com
        parts.append((inertia.mass, T[:3, 3], T[:3, :3] @ inertia.tensor @ T[:3, :3].T))
    frames = robot.kinematics.link_frames(q)
    for link, B_T_R in zip(robot.links, frames, strict=True):
        inertia = arm_link_inertia(link)
        T = B_T_R @ inertia.frame_T_com
        parts.append((inertia.mass, T[:3, 3], T[:3, :3] @ inertia.tensor @ T[:3, :3].T))
    if payload is not None:
        R, p = frames[-1][:3, :3], frames[-1][:3, 3]
        parts.append((payload.mass, R @ payload.com_wrist + p, np.zeros((3, 3))))
    return parts


def mujoco_composite(model, data):
    """Mass, CoM and inertia about the CoM of the base's subtree, in B, from MuJoCo's arrays."""
    b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "base")
    G_R_B, G_p_B = data.xmat[b].reshape(3, 3), data.xpos[b]
    com = data.subtree_com[b]
    inertia = np.zeros((3, 3))
    iquat = np.zeros(9)
    for i in range(1, model.nbody):
        R = data.xmat[i].reshape(3, 3)
        mujoco.mju_quat2Mat(iquat, model.body_iquat[i])
        R_i = R @ iquat.reshape(3, 3)
        c = data.xpos[i] + R @ model.body_ipos[i]
        inertia += R_i @ np.diag(model.body_inertia[i]) @ R_i.T
        inertia += point(model.body_mass[i], c - com)
    return (
        float(model.body_subtreemass[b]),
        G_R_B.T @ (com - G_p_B),
        G_R_B.T @ inertia @ G_R_B,
    )


@pytest.mark.parametrize("path", ROBOTS, ids=lambda p: p.stem)
@pytest.mark.parametrize("with_payload", [False, True], ids=["bare", "payload"])
def test_mass_com_inertia_equal_mmstab(path, with_payload):
    robot = load_robot(path)
    payload = PAYLOAD if with_payload else None
    # any number of joints: the first four as for the 4-DoF arm, the wrist's bent by 0.2 rad
    posture = np.resize(POSTURE, robot.arm_joints) + np.where(
        np.arange(robot.arm_joints) < 4, 0, 0.2
    )
    xml = build_robot_mjcf(robot, Ramp(0.3), payload=payload, pose=(0.4, -0.2, 0.8), arm_q=posture)
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    mass, com, inertia = mujoco_composite(model, data)
    # mmstab's mass model: m_T and g_o (Eq. 5) of the robot with the payload folded in
    loaded = attach_payload(robot, payload) if payload else robot
    assert abs(mass - loaded.total_mass) < 1e-9
    assert np.abs(com - loaded.overall_com(loaded.arm_com(posture))).max() < 1e-9
    # mmstab has no whole-robot inertia: its parts' (the URDF export's) summed about g_o
    parts = mmstab_parts(robot, posture, payload)
    g_o = sum(m * c for m, c, _ in parts) / sum(m for m, _, _ in parts)
    reference = sum(tensor + point(m, c - g_o) for m, c, tensor in parts)
    assert np.abs(inertia - reference).max() < 1e-9
    # the arm's bodies are mmstab's DH frames R_i
    b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "base")
    G_R_B, G_p_B = data.xmat[b].reshape(3, 3), data.xpos[b]
    for link, B_T_R in zip(robot.links, robot.kinematics.link_frames(posture), strict=True):
        i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"arm_{link.name}")
        assert np.abs(G_R_B.T @ data.xmat[i].reshape(3, 3) - B_T_R[:3, :3]).max() < 1e-12
        assert np.abs(G_R_B.T @ (data.xpos[i] - G_p_B) - B_T_R[:3, 3]).max() < 1e-12


def test_model_parts_and_actuators(cameleon):
    settings = ModelSettings()
    wheels = track_wheels(cameleon, settings)
    t = cameleon.base.tracks
    assert np.max(np.diff(wheels.x)) <= 0.05 + 1e-12
    assert wheels.x[0] == -t.length / 2 and wheels.x[-1] == t.length / 2
    assert wheels.radius == t.height / 2
    sim = RobotSim(cameleon, friction=0.55)
    m = sim.model
    assert np.all(m.geom_friction[:, 0] == 0.55)
    assert len(sim.track_ctrl["left"]) == len(sim.track_ctrl["right"]) == len(wheels.x)
    kp = m.actuator_gainprm[sim.arm_ctrl, 0]
    assert np.all(kp == settings.arm_kp)
    # flippers at the robot's angle, in B (the base sits at B = G at the start, up 1 mm)
    box = cameleon.base.flippers.box("left")
    g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "flipper_left")
    assert np.allclose(sim.data.geom_xpos[g] - [0, 0, settings.drop_height], box.center)
    assert np.allclose(sim.data.geom_xmat[g].reshape(3, 3), box.frame_T_shape[:3, :3])


@pytest.mark.parametrize("wheel", ["sphere", "cylinder", "sphere_pair"])
def test_wheel_shapes_touch_on_the_rim_edges(cameleon, wheel):
    """At rest on the floor the wheels touch on their rim edges (EDGES) only, < 1 mm deep.

    Nearly all of them at any instant (the soft contacts flicker: one may be open).
    """
    sim = RobotSim(cameleon, settings=ModelSettings(wheel=wheel))
    sim.step((0.0, 0.0), None, 0.5)
    d, t = sim.data, cameleon.base.tracks
    points = np.array(d.contact.pos[: d.ncon])
    expected = 2 * len(EDGES[wheel]) * len(track_wheels(cameleon, ModelSettings()).x)
    assert 0.9 * expected <= d.ncon <= expected
    ys = {round(s * (t.separation / 2 + e * t.width / 2), 6) for s in (1, -1) for e in EDGES[wheel]}
    assert set(np.round(points[:, 1], 3)) == {round(y, 3) for y in ys}
    assert np.all(points[:, 2] > -1e-3) and np.all(points[:, 2] < 1e-3)


def test_unknown_wheel_shape_is_refused(cameleon):
    with pytest.raises(MmstabError, match="wheel must be one of"):
        build_robot_mjcf(cameleon, settings=ModelSettings(wheel="tyre"))


def test_arm_holds_and_follows_targets(cameleon):
    sim = RobotSim(cameleon, arm_q=cameleon.stowed)
    held = sim.step((0.0, 0.0), None, 1.0)
    assert np.abs(held.arm_q - cameleon.stowed).max() < 2e-3
    for f in np.linspace(0.0, 1.0, 31)[1:]:  # a 3 s move: a step target would throw it over
        sim.step((0.0, 0.0), (1 - f) * cameleon.stowed + f * POSTURE, 0.1)
    moved = sim.step((0.0, 0.0), None, 1.0)
    assert np.abs(moved.arm_q - POSTURE).max() < 2e-3
    assert abs(moved.roll) < np.radians(1.0) and abs(moved.pitch) < np.radians(1.0)


# ------------------------------------------------------------------- Coulomb: the box test
def box_displacement(slope, friction, duration=2.0):
    """How far a 10 kg box set at rest on a plane tilted by ``slope`` moves in ``duration``."""
    _, ground = ground_xml(Ramp(slope))
    R = Ramp(slope).G_T_M()[:3, :3]
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, R.ravel())
    half = np.array([0.2, 0.1, 0.05])
    pos = fmt(R @ [0.0, 0.0, half[2]])
    xml = f"""<mujoco>{mjcf_header(ModelSettings(), friction)}<worldbody>{ground}
      <body name="box" pos="{pos}" quat="{fmt(quat)}"><freejoint/>
        <inertial pos="0 0 0" mass="10" diaginertia="0.04 0.14 0.17"/>
        <geom type="box" size="{fmt(half)}"/></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    start = data.xpos[1].copy()
    mujoco.mj_step(model, data, nstep=round(duration / model.opt.timestep))
    return float(np.linalg.norm(data.xpos[1] - start))


@pytest.mark.parametrize("friction", [0.5, DEFAULT_FRICTION, 1.0])
def test_box_slides_at_the_friction_angle(friction):
    """Holds 0.5 deg below atan(mu) (< 5 mm in 2 s); slides 0.5 deg above as Coulomb says.

    Above, the box must cover g (sin t - mu cos t) T^2 / 2 (0.19-0.24 m in T = 2 s) within
    10 %; below, Coulomb says 0 and MuJoCo's regularised friction creeps (< 5 mm).
    """
    critical = np.arctan(friction)
    below = box_displacement(critical - np.radians(0.5), friction)
    above_slope = critical + np.radians(0.5)
    above = box_displacement(above_slope, friction)
    expected = 9.81 * (np.sin(above_slope) - friction * np.cos(above_slope)) * 2.0**2 / 2
    report(friction=friction, hold_mm=1e3 * below, slide_m=above, coulomb_m=expected)
    assert below < 5e-3
    assert abs(above - expected) < 0.1 * expected


# ------------------------------------------------------------------------------ tip-over
def predicted_tip_slope(robot, q, heading):
    """The Ramp slope at which mmstab's force-angle measure crosses 0 [rad]."""

    def mu(slope):
        gravity = Ramp(slope).gravity_body(np.array([[0.0, 0.0, heading]]))
        return float(robot_force_angle(robot, gravity, robot.arm_com(q)).mu[0])

    return brentq(mu, 0.0, np.radians(89.0), xtol=1e-10)


def tilt_after(robot, slope, q, heading, payload, hold=2.0):
    """Angle between z_B and the plane's normal [deg] after settling + ``hold`` seconds."""
    ramp = Ramp(slope, friction=1.5)
    sim = RobotSim(robot, ramp, payload=payload, pose=(0, 0, heading), arm_q=q)
    sim.settle(1.0)
    state = sim.step((0.0, 0.0), None, hold)
    normal = ramp.G_T_M()[:3, 2]
    return float(np.degrees(np.arccos(np.clip(state.G_T_B[:3, 2] @ normal, -1.0, 1.0))))


def test_tips_at_the_predicted_slope(cameleon):
    """The loaded robot, arm out to the downhill side, across the slope (Ramp heading 0).

    Friction 1.5 (> tan of every slope tried): it can only tip. Holds (tilt off the plane
    < 2 deg after 2 s) at the prediction - 1 deg; tips (> 10 deg) at + 1 deg; the simulated
    critical slope, bisected to 0.06 deg, is within 1 deg of the prediction.
    """
    heading = 0.0
    predicted = predicted_tip_slope(attach_payload(cameleon, PAYLOAD), TIP_POSTURE, heading)
    tips = {}

    def tipped(slope):
        if slope not in tips:
            tips[slope] = tilt_after(cameleon, slope, TIP_POSTURE, heading, PAYLOAD)
        return tips[slope] > 10.0

    lo, hi = predicted - np.radians(1.0), predicted + np.radians(1.0)
    assert not tipped(lo) and tips[lo] < 2.0
    assert tipped(hi)
    for _ in range(5):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if tipped(mid) else (mid, hi)
    simulated = 0.5 * (lo + hi)
    report(predicted_deg=np.degrees(predicted), simulated_deg=np.degrees(simulated))
    assert abs(simulated - predicted) < np.radians(1.0)


# ------------------------------------------------------------------------------- driving
#: Where each wheel shape touches a plane across its track: rim edges, +1 = outer [-].
EDGES = {"sphere": (1,), "cylinder": (-1, 1), "sphere_pair": (-1, 1)}


def coulomb_turn_ratio(robot, left, right, wheel="sphere", friction=DEFAULT_FRICTION):
    """Yaw rate / (right - left) / b of a rigid skid-steer on Coulomb friction.

    The contacts of the model (each wheel's contacts on its rim edges: the outer one for
    spheres, both for cylinders; both tracks) carry equal loads; each pushes against its
    slip velocity (chassis velocity + belt velocity) with mu N. The steady state (vx, vy,
    yaw rate) balances forces and yaw moment.
    """
    t = robot.base.tracks
    xs = track_wheels(robot, ModelSettings()).x
    ys = [s * (t.separation / 2 + e * t.width / 2) for s in (1, -1) for e in EDGES[wheel]]
    P = np.array([(x, y) for y in ys for x in xs])
    belt = np.where(P[:, 1] > 0, left, right)

    def balance(state):
        vx, vy, w = state
        ux, uy = vx - w * P[:, 1] - belt, vy + w * P[:, 0]
        norm = np.hypot(ux, uy) + 1e-12
        fx, fy = -friction * ux / norm, -friction * uy / norm
        return [fx.sum(), fy.sum(), (P[:, 0] * fy - P[:, 1] * fx).sum()]

    ideal = (right - left) / t.separation
    vx, vy, w = fsolve(balance, [(left + right) / 2, 0.0, 0.5 * ideal])
    return w / ideal


def drive(robot, left, right, wheel="sphere", spin_up=1.0, duration=2.0):
    """Mean base speed [m/s] and yaw rate [rad/s] over ``duration`` after ``spin_up``."""
    sim = RobotSim(robot, settings=ModelSettings(wheel=wheel))
    sim.step((0.0, 0.0), None, 0.5)
    a = sim.step((left, right), None, spin_up)
    b = sim.step((left, right), None, duration)
    distance = np.linalg.norm(b.G_T_B[:2, 3] - a.G_T_B[:2, 3])
    turn = np.angle(np.exp(1j * (b.yaw - a.yaw)))
    return distance / duration, turn / duration, b


@pytest.mark.parametrize("wheel", ["sphere", "cylinder"])
@pytest.mark.parametrize("speed", [0.3, 0.6])
def test_straight_line_at_the_commanded_speed(cameleon, speed, wheel):
    v, w, end = drive(cameleon, speed, speed, wheel)
    report(track_speed=speed, speed_ratio=v / speed, yaw_rate=w, lateral=end.velocity_body[1])
    assert abs(v / speed - 1.0) < 0.1
    assert abs(w) < 0.01 and abs(end.velocity_body[1]) < 0.01


@pytest.mark.parametrize("wheel", ["sphere", "cylinder"])
def test_pivot_turn_rate(cameleon, wheel):
    """Left = -right = 0.3 m/s: the yaw rate against the ideal 2 v / b.

    Skid-steer loses some: the tracks slide sideways at their ends, so the belts also slip.
    Bound: within 0.1 of the Coulomb skid-steer model of the same contacts (uniform load),
    and below 1. The base turns about a point near the CoM (4.9 cm ahead of B's origin with
    the arm stowed), so B's origin drifts on a circle of that order (< 10 cm).
    """
    v = 0.3
    speed, w, _ = drive(cameleon, -v, v, wheel)
    ideal = 2 * v / cameleon.base.tracks.separation
    coulomb = coulomb_turn_ratio(cameleon, -v, v, wheel)
    radius = speed / abs(w)
    report(yaw_rate=w, ideal=ideal, ratio=w / ideal, coulomb_ratio=coulomb, radius=radius)
    assert abs(w / ideal - coulomb) < 0.1
    assert w / ideal < 1.0
    assert radius < 0.1


@pytest.mark.parametrize("wheel", ["sphere", "cylinder"])
def test_one_track_turn_rate(cameleon, wheel):
    """Left braked, right 0.4 m/s: yaw rate and forward speed against the Coulomb model."""
    speed, w, _ = drive(cameleon, 0.0, 0.4, wheel)
    ideal = 0.4 / cameleon.base.tracks.separation
    coulomb = coulomb_turn_ratio(cameleon, 0.0, 0.4, wheel)
    report(yaw_rate=w, ratio=w / ideal, coulomb_ratio=coulomb)
    assert abs(w / ideal - coulomb) < 0.1


# --------------------------------------------------------------------------- heightfield
def test_settles_on_a_heightmap_terrain(cameleon):
    """A ramp sampled as a heightmap terrain: the robot settles on the ramp's plane."""
    ramp = Ramp(np.radians(12.0))
    ground = HeightmapTerrain(ramp_heightmap(ramp, (3.0, 3.0), 0.05), friction=0.9)
    heading = 0.4  # in G: a heightmap's map frame
    sim = RobotSim(cameleon, ground, pose=(0.1, 0.2, heading))
    assert np.all(sim.model.geom_friction[:, 0] == 0.9)  # the terrain's friction
    sim.settle(1.0)
    state = sim.step((0.0, 0.0), None, 0.5)
    up = ramp.G_T_M()[:3, 2]
    off = np.degrees(np.arccos(np.clip(state.G_T_B[:3, 2] @ up, -1.0, 1.0)))
    assert off < 0.5
    assert np.hypot(*(state.G_T_B[:2, 3] - [0.1, 0.2])) < 0.01
    assert abs(np.angle(np.exp(1j * (state.yaw - heading)))) < 0.01
