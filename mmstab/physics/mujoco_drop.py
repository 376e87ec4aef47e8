"""MuJoCo heightfield drop tests of the tracked base.

The robot is ONE free rigid body whose collision geometry is exactly the one the
terrain's contact model uses, in the body frame B (origin at the centre of the
track-ground contact rectangle, x forward, y left, z up):

- each track: a box (L, width, height) centred at (0, +-separation/2, height/2) and two
  cylinders (radius height/2, axis y, length width) centred at (+-L/2, +-separation/2,
  height/2): the sprocket and the idler;
- each flipper: ``robot.base.flippers.box(side)`` at the flipper angle;
- the chassis: ``robot.base.body``.

Its mass is the robot's total mass at the overall CoM (base at its CoM + the arm's links as
point masses at the given posture, stowed by default). :func:`drop` places the body a few
cm above the heightmap at each (x, y, yaw) in G, lets it fall and settle, and reads the
resting pose. Roll and pitch follow ``Ramp.roll_pitch``: from gravity in the body,
positive roll lifts the left side, positive pitch lifts the nose.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, NamedTuple

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from mmstab.model.robot import FloatArray, Robot
from mmstab.physics.drop_geometry import (
    collision_geoms,
    mass_properties,
    pose_matrix,
    surface_points,
)
from mmstab.physics.heightfield import Heightmap, heightmap, hfield_mjcf
from mmstab.physics.plane import fit_plane, roll_pitch, tilted_frame


@dataclass(frozen=True)
class DropSettings:
    """Simulation settings of the drops (saved with the results).

    Attributes:
        timestep: integration step [s].
        friction: sliding friction coefficient of every contact [-].
        solref: contact (time constant [s], damping ratio [-]): stiff, critically damped.
        solimp: contact impedance (dmin, dmax, width [m], midpoint, power).
        impratio: frictional-to-normal impedance ratio (elliptic cones): high = less creep.
        damping: viscous damping of the free joint, every DOF [N s/m, N m s/rad]: it ends
            rocking on crests (rolling contacts lose no energy) and is zero at rest.
        noslip_iterations: MuJoCo's no-slip post-solver iterations (0 = off).
        drop_height: gap between the lowest robot point and the ground at release [m].
        start: initial attitude, ``"fit"`` (the plane fitted under the footprint) or
            ``"level"`` (roll = pitch = 0).
        max_time: give up settling after this much simulated time [s].
        settle_time: velocities must stay below the thresholds this long [s].
        linear_tol: settled when the B origin moves slower than this [m/s] ...
        angular_tol: ... and the body turns slower than this [rad/s].
        check_every: steps between settling checks.
    """

    timestep: float = 0.002
    friction: float = 1.5
    solref: tuple[float, float] = (0.004, 1.0)
    solimp: tuple[float, float, float, float, float] = (0.95, 0.99, 0.001, 0.5, 2.0)
    impratio: float = 1.0
    damping: float = 30.0
    noslip_iterations: int = 0
    drop_height: float = 0.03
    start: str = "fit"
    max_time: float = 4.0
    settle_time: float = 0.1
    linear_tol: float = 2e-3
    angular_tol: float = 1e-2
    check_every: int = 10


def _quat(R: FloatArray) -> FloatArray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=float).ravel())
    return q


def _f(values: ArrayLike) -> str:
    return " ".join(f"{float(v):.12g}" for v in np.atleast_1d(np.asarray(values)).ravel())


def build_model(
    robot: Robot,
    elevation: ArrayLike,
    resolution: float,
    origin: ArrayLike,
    flipper_angle: float | None = None,
    arm_posture: ArrayLike | None = None,
    settings: DropSettings | None = None,
) -> str:
    """MJCF of the heightmap (``hfield``) and the robot as one free rigid body ``base``.

    Args:
        robot: the robot.
        elevation: heights ``[iy, ix]`` [m] (grid_map: row = y, column = x), all finite.
        resolution: cell size [m/cell].
        origin: G (x, y) of the centre of cell [0, 0] [m].
        flipper_angle: flipper angle [rad]; None = the robot's.
        arm_posture: arm joint angles (4,) [rad]; None = stowed.
        settings: simulation settings (timestep, friction, contact softness).

    Returns:
        The MJCF document (string).
    """
    s = settings or DropSettings()
    hm = heightmap(elevation, resolution, origin)
    field = hfield_mjcf(hm)
    mp = mass_properties(robot, arm_posture)
    inertia = mp.inertia_body
    full = [inertia[i, j] for i, j in ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))]
    contact = (
        f'friction="{s.friction} 0.005 0.0001" solref="{_f(s.solref)}" solimp="{_f(s.solimp)}"'
    )
    lines = []
    for g in collision_geoms(robot, flipper_angle):
        size = g.size / 2 if g.kind == "box" else np.array([g.size[0], g.size[1] / 2])
        lines.append(
            f'      <geom name="{g.name}" type="{g.kind}" size="{_f(size)}" '
            f'pos="{_f(g.B_T_geom[:3, 3])}" quat="{_f(_quat(g.B_T_geom[:3, :3]))}"/>'
        )
    geoms = "\n".join(lines)
    return f"""<mujoco model="mmstab_drop_{robot.name}">
  <compiler angle="radian" inertiafromgeom="false"/>
  <option timestep="{s.timestep}" integrator="implicitfast" solver="Newton" cone="elliptic"
          impratio="{s.impratio}" noslip_iterations="{s.noslip_iterations}" iterations="100"/>
  <default><geom condim="3" {contact}/></default>
  <asset>
    {field.asset}
  </asset>
  <worldbody>
    {field.geom}
    <body name="base">
      <joint name="base" type="free" damping="{s.damping:.12g}"/>
      <inertial pos="{_f(mp.com_body)}" mass="{mp.mass:.12g}" fullinertia="{_f(full)}"/>
{geoms}
    </body>
  </worldbody>
</mujoco>
"""


class DropResult(NamedTuple):
    """Settled poses of N drops (arrays with a leading N axis).

    Attributes:
        roll: [rad], positive lifts the left side (``Ramp.roll_pitch``).
        pitch: [rad], positive lifts the nose.
        z: height of B's origin in G [m].
        G_T_B: settled body poses (N, 4, 4).
        settled: whether the velocity thresholds were met before ``max_time``.
        time: simulated time to settle [s].
        xy: settled (x, y) of B's origin in G (N, 2) [m].
        yaw: settled heading of the body x axis about G's z [rad].
        slip: horizontal distance of B's origin from the commanded (x, y) [m].
        yaw_drift: settled minus commanded yaw, wrapped [rad].
        penetration: deepest contact penetration at rest [m] (soft contacts).
        touching: per drop, the names of the robot geoms in contact at rest.
        wall_time: CPU wall time per drop [s].
        poses: the commanded (x, y, yaw) in G (N, 3) [m, m, rad].
    """

    roll: FloatArray
    pitch: FloatArray
    z: FloatArray
    G_T_B: FloatArray
    settled: np.ndarray
    time: FloatArray
    xy: FloatArray
    yaw: FloatArray
    slip: FloatArray
    yaw_drift: FloatArray
    penetration: FloatArray
    touching: list[tuple[str, ...]]
    wall_time: FloatArray
    poses: FloatArray

    @property
    def settled_poses(self) -> FloatArray:
        """Where the robot actually stands: settled (x, y, yaw) in G (N, 3)."""
        return np.column_stack([self.xy, self.yaw])


class DropModel:
    """A compiled drop model (one heightmap, one robot configuration), reused for all poses.

    Args:
        robot: the robot.
        elevation, resolution, origin: the heightmap (grid_map convention) [m], [m/cell], [m].
        flipper_angle: flipper angle [rad]; None = the robot's.
        arm_posture: arm joint angles (4,) [rad]; None = stowed.
        settings: simulation settings.
    """

    def __init__(
        self,
        robot: Robot,
        elevation: ArrayLike,
        resolution: float,
        origin: ArrayLike,
        flipper_angle: float | None = None,
        arm_posture: ArrayLike | None = None,
        settings: DropSettings | None = None,
    ):
        self.robot = robot
        self.settings = settings or DropSettings()
        self.heightmap: Heightmap = heightmap(elevation, resolution, origin)
        self.mjcf = build_model(
            robot, elevation, resolution, origin, flipper_angle, arm_posture, self.settings
        )
        self.model = mujoco.MjModel.from_xml_string(self.mjcf)
        self.data = mujoco.MjData(self.model)
        self.geoms = collision_geoms(robot, flipper_angle)
        self.points_body = surface_points(self.geoms)
        t = robot.base.tracks
        hx, hy = t.length / 2 + t.height / 2, t.separation / 2 + t.width / 2
        gx, gy = np.meshgrid(np.linspace(-hx, hx, 9), np.linspace(-hy, hy, 5))
        self.footprint_body = np.stack([gx.ravel(), gy.ravel()], -1)
        self.terrain_geom = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_GEOM, "terrain")
        self.body = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, "base")

    def initialpose_matrix(self, pose: ArrayLike) -> FloatArray:
        """Release pose G_T_B (4, 4) for (x [m], y [m], yaw [rad]) in G: gap ``drop_height``."""
        x, y, yaw = np.asarray(pose, dtype=float)
        c, s = np.cos(yaw), np.sin(yaw)
        xy = self.footprint_body @ np.array([[c, s], [-s, c]]) + [x, y]
        if not np.all(self.heightmap.contains(xy)):
            raise ValueError(f"pose ({x:.3f}, {y:.3f}, {yaw:.3f}): the footprint leaves the map")
        if self.settings.start == "fit":
            a, b, _ = fit_plane(xy, self.heightmap.height(xy))
            R = tilted_frame(a, b, yaw)
        else:
            R = tilted_frame(0.0, 0.0, yaw)
        p = self.points_body @ R.T + [x, y, 0.0]
        z0 = float(np.max(self.heightmap.height(p[:, :2]) - p[:, 2])) + self.settings.drop_height
        return pose_matrix(R, [x, y, z0])

    def drop_one(self, pose: ArrayLike, start: ArrayLike | None = None) -> dict[str, Any]:
        """Drop at one (x, y, yaw) in G and settle; the fields of :class:`DropResult`.

        Args:
            pose: the commanded (x [m], y [m], yaw [rad]) in G.
            start: release pose G_T_B (4, 4) instead of :meth:`initial_pose` (e.g. a
                predicted rest, to see whether MuJoCo stays there).
        """
        m, d, s = self.model, self.data, self.settings
        T0 = self.initialpose_matrix(pose) if start is None else np.asarray(start, dtype=float)
        mujoco.mj_resetData(m, d)
        d.qpos[:3] = T0[:3, 3]
        d.qpos[3:7] = _quat(T0[:3, :3])
        n_quiet = int(np.ceil(s.settle_time / (s.check_every * s.timestep)))
        quiet, settled = 0, False
        t_wall = time.perf_counter()
        while d.time < s.max_time:
            mujoco.mj_step(m, d, nstep=s.check_every)
            v = d.qvel
            if np.linalg.norm(v[:3]) < s.linear_tol and np.linalg.norm(v[3:6]) < s.angular_tol:
                quiet += 1
                if quiet >= n_quiet:
                    settled = True
                    break
            else:
                quiet = 0
        wall = time.perf_counter() - t_wall
        mujoco.mj_forward(m, d)
        R = d.xmat[self.body].reshape(3, 3).copy()
        G_T_B = pose_matrix(R, d.xpos[self.body].copy())
        dist = [d.contact[i].dist for i in range(d.ncon)]
        names = set()
        for i in range(d.ncon):
            c = d.contact[i]
            other = c.geom2 if c.geom1 == self.terrain_geom else c.geom1
            names.add(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, other))
        roll, pitch = roll_pitch(R)
        yaw = float(np.arctan2(R[1, 0], R[0, 0]))
        x, y, yaw0 = np.asarray(pose, dtype=float)
        return {
            "roll": roll,
            "pitch": pitch,
            "z": G_T_B[2, 3],
            "G_T_B": G_T_B,
            "settled": settled,
            "time": d.time,
            "xy": G_T_B[:2, 3],
            "yaw": yaw,
            "slip": float(np.hypot(G_T_B[0, 3] - x, G_T_B[1, 3] - y)),
            "yaw_drift": float(np.angle(np.exp(1j * (yaw - yaw0)))),
            "penetration": max(0.0, -min(dist)) if dist else 0.0,
            "touching": tuple(sorted(n for n in names if n)),
            "wall_time": wall,
        }


def drop(model: DropModel | dict[str, Any], poses: ArrayLike) -> DropResult:
    """Drop the robot at many poses and read the settled poses.

    Args:
        model: a :class:`DropModel` (reused), or the keyword arguments that build one.
        poses: (N, 3) or (3,) of (x [m], y [m], yaw [rad]) in G.

    Returns:
        The settled poses, one entry per pose.
    """
    dm = model if isinstance(model, DropModel) else DropModel(**model)
    P = np.atleast_2d(np.asarray(poses, dtype=float))
    rows = [dm.drop_one(p) for p in P]
    fields: dict[str, Any] = {}
    for key in DropResult._fields[:-1]:
        values = [r[key] for r in rows]
        fields[key] = values if key == "touching" else np.array(values)
    return DropResult(**fields, poses=P)
