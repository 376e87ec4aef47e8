"""The whole robot as a MuJoCo model (MJCF text), generated from its description.

Tree (frames as in ``docs/design.md``, "Frames"; the body frame B is MuJoCo's body ``base``)::

    base (free joint; carries the chassis box "body")
    ├── track_left, track_right       welded at the track boxes' poses
    │   └── wheel_<side>_NN           road wheels: [drop,] suspension slides (z), hinge (y)
    ├── flipper_left, flipper_right   welded at the flippers' angle (a rear pair too)
    └── arm_<link 0> ─ … ─ arm_<link 3> [─ payload]
        hinge joints with position servos; each body's frame IS mmstab's DH frame R_i

**Masses.** The base's five parts carry the inertias of the URDF export
(:func:`mmstab.model.urdf.base_link_inertias`: volume-weighted solid boxes summing to
``base.mass`` at ``base.com``); each arm link carries
:func:`~mmstab.model.urdf.arm_link_inertia` (its solid shape's inertia at its CoM); a payload
is a point mass at its CoM in the wrist frame (:mod:`mmstab.model.payload`). The road wheels'
mass is taken out of their track's (mass, first and second moments: :func:`minus`), so the
model has exactly mmstab's mass, CoM and part inertias (at rest, suspension unloaded).

**Tracks.** MuJoCo has no track: each side is a row of ``n`` cylinders of radius
``tracks.height / 2`` whose outline is the collision model's (the sprocket and idler at the
two ends, road wheels between, the flat run sampled every ``wheel_spacing``), all driven by
velocity servos at one surface speed, so the belt's velocity relative to the chassis is
reproduced at every sample (skid-steer). ``gear`` = the wheel radius: ``ctrl`` is the track
speed [m/s], the actuator force the rim force [N]. Each wheel rides on a stiff, critically
damped spring (``suspension_deflection`` at the mean load, preloaded so the wheels sit at
their nominal height at that load): without it the rigid row of 2 x 15 wheels chatters
while it skids (MuJoCo's soft contacts push sliding bodies apart), loads the end wheels and
halves the turn rate (``docs/physics.md``).

**Ground.** An mmstab :class:`~mmstab.terrain.base.Terrain`: a planar one (the ramp) is a
MuJoCo plane through its map frame M (``G_T_M``), a heightmap terrain a MuJoCo ``hfield``
(:func:`mmstab.physics.heightfield.hfield_mjcf`); a bare
:class:`~mmstab.physics.heightfield.Heightmap` is a heightfield too; ``None`` is the flat
floor z_G = 0. The start pose ``(x, y, heading)`` is in M, as everywhere in mmstab (on the
ramp heading 0 faces across the slope, the left side uphill). One friction coefficient for
every contact (MuJoCo takes the larger of two geoms'; all are equal here), by default the
terrain's (``terrain.friction``, else :data:`~mmstab.terrain.base.DEFAULT_FRICTION`).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from mmstab.core.files import MmstabError
from mmstab.model.payload import Payload
from mmstab.model.robot import Box, FloatArray, Geometry, Robot, homogeneous
from mmstab.model.urdf import arm_link_inertia, base_link_inertias, dh_constant_T, rot_z_T
from mmstab.physics.heightfield import hfield_mjcf
from mmstab.physics.robot_mass import Inertial, Wheels, inertial_of, minus, principal
from mmstab.physics.robot_start import Ground, ground_heightmap, plane_T, start_pose
from mmstab.stability.slip import terrain_friction
from mmstab.terrain.base import GRAVITY_G


@dataclass(frozen=True)
class ModelSettings:
    """Numbers of the MuJoCo model that the robot description does not give.

    Attributes:
        timestep: integration step [s].
        integrator: MuJoCo's; ``discrete`` solves contacts with the servos' damping (physics.md).
        solref: contact (time constant [s], damping ratio [-]).
        solimp: contact impedance (dmin, dmax, width [m], midpoint, power).
        impratio: frictional-to-normal impedance ratio (elliptic cones): high = less creep.
        noslip_iterations: MuJoCo's no-slip post-solver iterations (0 = off).
        wheel_spacing: largest gap between wheel centres along the flat run [m].
        wheel_mass_fraction: share of a track's mass carried by its wheels [-].
        suspension_deflection: wheel spring deflection under the mean wheel load [m]
            (0: rigid wheels, no suspension joint).
        suspension_damping: damping ratio of a wheel spring with its share of the mass [-].
        suspension_armature: reflected mass on each wheel's spring joint [kg] (lets a
            4 ms step integrate the 0.18 kg wheel on its spring without chatter).
        suspension_travel: how far each wheel may drop below its bump stop [m] (0: none,
            the default). A wheel over a dip up to this deep is pressed onto it by a small
            drop force while the chassis rests on the others' stops: the support mmstab's
            ``terrain.compliance`` assumes (the bottom run within it of the ground bears).
        travel_force: the force pressing a wheel that left its stop onto the ground, as a
            share of the mean wheel load [-]; :class:`~mmstab.physics.robot_sim.RobotSim`
            applies it with the wheel's weight taken off (the chassis carries it, as the
            rigid robot does), so a wheel leaves its stop only when it bears less than this.
        travel_damping: damping of a wheel's drop [N s/m].
        track_kv: velocity-servo gain of each wheel at the rim [N/(m/s)].
        wheel_armature: reflected rotor inertia of each wheel joint [kg m^2].
        arm_kp: position-servo stiffness of every arm joint [N m/rad].
        arm_kv: position-servo damping of every arm joint [N m s/rad].
        arm_armature: reflected rotor inertia of every arm joint [kg m^2].
        drop_height: gap between the wheels and the ground at the start [m].
        wheel: road wheels' collision shape (:data:`WHEEL_SHAPES`).
    """

    timestep: float = 0.004
    integrator: str = "discrete"
    solref: tuple[float, float] = (0.01, 1.0)
    solimp: tuple[float, float, float, float, float] = (0.95, 0.99, 0.001, 0.5, 2.0)
    impratio: float = 10.0
    noslip_iterations: int = 0
    wheel_spacing: float = 0.05
    wheel_mass_fraction: float = 0.25
    suspension_deflection: float = 0.001
    suspension_damping: float = 1.0
    suspension_armature: float = 0.2
    suspension_travel: float = 0.0
    travel_force: float = 0.01
    travel_damping: float = 0.5
    track_kv: float = 2000.0
    wheel_armature: float = 0.05
    arm_kp: float = 2000.0
    arm_kv: float = 100.0
    arm_armature: float = 0.05
    drop_height: float = 0.001
    wheel: str = "sphere"


def track_wheels(robot: Robot, settings: ModelSettings) -> Wheels:
    """The wheels of one track: the flat run sampled at most ``wheel_spacing`` apart."""
    t = robot.base.tracks
    n = int(np.ceil(t.length / settings.wheel_spacing - 1e-9)) + 1
    track_mass = base_link_inertias(robot)["track_left"].mass
    mass = settings.wheel_mass_fraction * track_mass / n
    return Wheels(np.linspace(-t.length / 2, t.length / 2, n), t.height / 2, t.width, mass)


# ---------------------------------------------------------------------------------- writing
VISUAL = ' contype="0" conaffinity="0" group="1"'
_AXLE_Y = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # a cylinder's z -> y


def _f(values: ArrayLike) -> str:
    return " ".join(f"{float(v):.17g}" for v in np.atleast_1d(np.asarray(values)).ravel())


def _quat(R: ArrayLike) -> FloatArray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=float).ravel())
    return q


def _frame(T: FloatArray) -> str:
    return f'pos="{_f(T[:3, 3])}" quat="{_f(_quat(T[:3, :3]))}"'


def _inertial_xml(inertial: Inertial) -> str:
    """``<inertial>`` with NumPy's principal moments and axes, so MuJoCo keeps them as given."""
    moments, axes = principal(inertial.tensor)
    return (
        f'<inertial pos="{_f(inertial.com)}" quat="{_f(_quat(axes))}" '
        f'mass="{inertial.mass:.17g}" diaginertia="{_f(moments)}"/>'
    )


def _geom_xml(name: str, geometry: Geometry) -> str:
    if isinstance(geometry, Box):
        size = _f(geometry.size / 2)
        return f'<geom name="{name}" type="box" size="{size}" {_frame(geometry.frame_T_shape)}/>'
    r = _f(geometry.radius)
    if geometry.length == 0:
        return f'<geom name="{name}" type="sphere" size="{r}" pos="{_f(geometry.p0)}"/>'
    ends = _f(np.concatenate([geometry.p0, geometry.p1]))
    return f'<geom name="{name}" type="capsule" size="{r}" fromto="{ends}"/>'


def mjcf_header(settings: ModelSettings, friction: float) -> str:
    """``<compiler>``, ``<option>`` and the contact defaults shared by every model here.

    Robot geoms collide with the ground only (``contype=0 conaffinity=1``; the ground has
    ``contype=1 conaffinity=0``); contacts are ``condim=3`` on elliptic cones with sliding
    friction ``friction`` (no torsional or rolling friction).
    """
    s = settings
    return f"""  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>
  <option timestep="{s.timestep!r}" gravity="{_f(GRAVITY_G)}" integrator="{s.integrator}"
          solver="Newton" cone="elliptic" impratio="{s.impratio!r}"
          noslip_iterations="{s.noslip_iterations}" iterations="100"/>
  <default>
    <geom condim="3" contype="0" conaffinity="1" friction="{float(friction)!r} 0 0"
          solref="{_f(s.solref)}" solimp="{_f(s.solimp)}"/>
  </default>"""


def ground_xml(ground: Ground) -> tuple[str, str]:
    """(asset, worldbody geom) of the ground, geom named ``terrain`` (:data:`Ground`)."""
    grid = ground_heightmap(ground)
    if grid is not None:
        field = hfield_mjcf(grid)
        return field.asset, field.geom.replace("/>", ' contype="1" conaffinity="0"/>')
    attrs = f'type="plane" size="0 0 1" {_frame(plane_T(ground))} contype="1" conaffinity="0"'
    return "", f'<geom name="terrain" {attrs}/>'


def _wheel_xml(name: str, k: int, wheels: Wheels, robot: Robot, s: ModelSettings) -> list[str]:
    """Wheel ``k`` of a track: a sprung slide along the track's z (if any), the driven hinge."""
    x, n = float(wheels.x[k]), 2 * len(wheels.x)
    outer = 1.0 if "left" in name else -1.0  # the left track's outer edge is at +y_B
    joints = []
    if s.suspension_travel > 0:  # no spring: the wheel drops by its weight, stops at 0
        joints.append(
            f'<joint name="{name}_zdrop" type="slide" axis="0 0 1" '
            f'damping="{s.travel_damping!r}" range="{_f([-s.suspension_travel, 0.0])}" '
            f'solreflimit="{_f(s.solref)}" solimplimit="{_f(s.solimp)}" '
            f'armature="{s.suspension_armature!r}"/>'
        )
    if s.suspension_deflection > 0:
        stiff = robot.total_mass * float(-GRAVITY_G[2]) / n / s.suspension_deflection
        damp = 2 * s.suspension_damping * np.sqrt(stiff * robot.total_mass / n)
        spring = f'stiffness="{_f(stiff)}" damping="{_f(damp)}"'
        ref = _f(-s.suspension_deflection)
        joints.append(
            f'<joint name="{name}_z" type="slide" axis="0 0 1" {spring} springref="{ref}" '
            f'armature="{s.suspension_armature!r}"/>'
        )
    joints.append(
        f'<joint name="{name}" type="hinge" axis="0 1 0" armature="{s.wheel_armature!r}"/>'
    )
    at_wheel = homogeneous(np.eye(3), [-x, 0.0, 0.0])
    return [
        f'<body name="{name}" pos="{_f(x)} 0 0">',
        *("  " + j for j in joints),
        f"  {_inertial_xml(wheels.inertial(k).moved(at_wheel))}",
        *("  " + g for g in _wheel_geoms(name, k, wheels, s.wheel, outer)),
        "</body>",
    ]


#: Road-wheel collision shapes (``docs/physics.md``): ``sphere``, one sphere per wheel
#: centred on the track's outer rim edge (one contact each, on the outline mmstab's support
#: polygon uses; the cheapest on a heightfield); ``cylinder``, track-wide (two contacts on a
#: plane, the rim edges); ``sphere_pair``, a sphere on each rim edge (the cylinder's lines).
WHEEL_SHAPES = ("cylinder", "sphere", "sphere_pair")


def _wheel_geoms(name: str, k: int, wheels: Wheels, shape: str, outer: float) -> list[str]:
    """Wheel ``k``'s collision geoms in its body's frame (axle along y; ``outer`` = +-1 [-])."""
    r, half = _f(wheels.radius), wheels.width / 2
    if shape == "cylinder":
        axle = homogeneous(_AXLE_Y, np.zeros(3))
        return [f'<geom name="{name}" type="cylinder" size="{r} {_f(half)}" {_frame(axle)}/>']
    by_shape = {"sphere": [outer * half], "sphere_pair": [half, -half]}
    edges = by_shape.get(shape)
    if edges is None:
        raise MmstabError(f"MuJoCo robot model: wheel must be one of {WHEEL_SHAPES}, not {shape!r}")
    return [f'<geom name="{name}{"_b" * i}" type="sphere" size="{r}" pos="0 {_f(y)} 0"/>'
            for i, y in enumerate(edges)]  # fmt: skip


def _track_xml(robot: Robot, side: str, track: Inertial, s: ModelSettings) -> list[str]:
    box = robot.base.tracks.box(side)  # type: ignore[arg-type]
    wheels = track_wheels(robot, s)
    rest = minus(track, [wheels.inertial(k) for k in range(len(wheels.x))])
    out = [
        f'<body name="track_{side}" {_frame(box.frame_T_shape)}>',
        f"  {_inertial_xml(rest)}",
        f'  <geom name="track_{side}" type="box" size="{_f(box.size / 2)}"{VISUAL}/>',
    ]
    for k in range(len(wheels.x)):
        out += ["  " + line for line in _wheel_xml(f"wheel_{side}_{k:02d}", k, wheels, robot, s)]
    return [*out, "</body>"]


def _arm_xml(robot: Robot, payload: Payload | None, armature: float) -> list[str]:
    """Nested arm bodies, one per link, each at mmstab's DH frame R_i.

    Body R_i sits at ``Rz(theta_offset_i) C_i`` in R_{i-1} (the mount for i = 0) at q = 0;
    its hinge turns about R_{i-1}'s z axis through R_{i-1}'s origin, i.e. axis
    ``C_i^-1 z`` through ``C_i^-1 0`` in R_i, so the joint angle is mmstab's ``q_i``.
    """
    out, parent_T = [], robot.mount_T
    for i, link in enumerate(robot.links):
        C = dh_constant_T(link)
        Ci = np.linalg.inv(C)
        name, pad = f"arm_{link.name}", "  " * i
        inertia = arm_link_inertia(link)
        inertial = inertial_of(inertia.mass, inertia.frame_T_com, inertia.tensor)
        out += [
            f'{pad}<body name="{name}" {_frame(parent_T @ rot_z_T(link.theta_offset) @ C)}>',
            f'{pad}  <joint name="{name}" type="hinge" pos="{_f(Ci[:3, 3])}" '
            f'axis="{_f(Ci[:3, 2])}" range="{_f([link.lower, link.upper])}" '
            f'armature="{armature!r}"/>',
            f"{pad}  {_inertial_xml(inertial)}",
            f"{pad}  {_geom_xml(name, link.geometry)}",
        ]
        parent_T = np.eye(4)
    pad = "  " * len(robot.links)
    if payload is not None and payload.mass > 0:
        out += [
            f'{pad}<body name="payload" pos="{_f(payload.com_wrist)}">',
            f'{pad}  <inertial pos="0 0 0" mass="{float(payload.mass)!r}" diaginertia="0 0 0"/>',
            f'{pad}  <geom name="payload" type="sphere" size="0.03"{VISUAL}/>',
            f"{pad}</body>",
        ]
    return out + ["  " * i + "</body>" for i in reversed(range(len(robot.links)))]


def _base_xml(robot: Robot, s: ModelSettings, payload: Payload | None) -> list[str]:
    """The ``base`` body's content: chassis inertial and box, tracks, flippers, arm."""
    parts = {
        name: inertial_of(p.mass, p.frame_T_com, p.tensor)
        for name, p in base_link_inertias(robot).items()
    }  # each in its box's frame
    boxes = robot.base.collision_boxes()
    out = [
        _inertial_xml(parts["body"].moved(boxes["body"].frame_T_shape)),
        _geom_xml("chassis", boxes["body"]),
    ]
    for side in ("left", "right"):
        out += _track_xml(robot, side, parts[f"track_{side}"], s)
    for name in (n for n in boxes if n.startswith("flipper_")):
        box = boxes[name]
        out += [
            f'<body name="{name}" {_frame(box.frame_T_shape)}>',
            f"  {_inertial_xml(parts[name])}",
            f'  <geom name="{name}" type="box" size="{_f(box.size / 2)}"/>',
            "</body>",
        ]
    return out + _arm_xml(robot, payload, s.arm_armature)


def _actuators_xml(robot: Robot, s: ModelSettings, n_wheels: int) -> list[str]:
    """Velocity servos on the wheels (ctrl = track speed [m/s]), position servos on the arm."""
    r = _f(robot.base.tracks.height / 2)
    out = [
        f'<velocity name="wheel_{side}_{k:02d}" joint="wheel_{side}_{k:02d}" gear="{r}" '
        f'kv="{s.track_kv!r}"/>'
        for side in ("left", "right")
        for k in range(n_wheels)
    ]
    for link in robot.links:
        out.append(
            f'<position name="arm_{link.name}" joint="arm_{link.name}" kp="{s.arm_kp!r}" '
            f'kv="{s.arm_kv!r}" ctrlrange="{_f([link.lower, link.upper])}"/>'
        )
    return out


def build_robot_mjcf(
    robot: Robot,
    ground: Ground = None,
    *,
    friction: float | None = None,
    payload: Payload | None = None,
    pose: ArrayLike = (0.0, 0.0, 0.0),
    arm_q: ArrayLike | None = None,
    settings: ModelSettings | None = None,
) -> str:
    """The MJCF document of the whole robot on the ground (see the module docstring).

    Args:
        robot: the robot (without its payload folded in: give ``payload`` instead).
        ground: a planar or heightmap terrain, a heightmap, or None: the flat floor.
        friction: Coulomb friction coefficient of every contact [-]; None = the
            terrain's (``DEFAULT_FRICTION`` for a bare heightmap or the floor).
        payload: a point mass held at the wrist, or None.
        pose: the base's start (x [m], y [m], heading [rad]) (:func:`start_pose`).
        arm_q: the arm's start posture and servo targets (4,) [rad]; None = stowed.
        settings: the model's numbers (:class:`ModelSettings`).

    Returns:
        The MJCF text; its keyframe ``start`` holds the start state and servo targets.
    """
    s = settings or ModelSettings()
    if friction is None:
        friction = terrain_friction(ground)
    q = robot.stowed if arm_q is None else np.asarray(arm_q, dtype=float)
    n = len(track_wheels(robot, s).x)
    asset, ground_geom = ground_xml(ground)
    T = start_pose(robot, ground, pose, s.drop_height)
    joints_per_wheel = 1 + (s.suspension_deflection > 0) + (s.suspension_travel > 0)
    qpos = np.concatenate([T[:3, 3], _quat(T[:3, :3]), np.zeros(2 * n * joints_per_wheel), q])
    ctrl = np.concatenate([np.zeros(2 * n), q])
    base = "\n".join("      " + line for line in _base_xml(robot, s, payload))
    actuators = "\n".join("    " + line for line in _actuators_xml(robot, s, n))
    return f"""<mujoco model="mmstab_{robot.name}">
{mjcf_header(s, friction)}
  <asset>{asset}</asset>
  <worldbody>
    {ground_geom}
    <body name="base">
      <freejoint name="base"/>
{base}
    </body>
  </worldbody>
  <actuator>
{actuators}
  </actuator>
  <keyframe>
    <key name="start" qpos="{_f(qpos)}" ctrl="{_f(ctrl)}"/>
  </keyframe>
</mujoco>
"""
