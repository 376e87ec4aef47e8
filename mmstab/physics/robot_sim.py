"""A thin simulation wrapper around :func:`~mmstab.physics.robot_model.build_robot_mjcf`.

:class:`RobotSim` compiles the whole robot on its ground, starts it at the model's keyframe
and advances it for a given time with constant commands: left/right track speeds [m/s]
(every wheel's velocity servo of a side) and arm joint targets [rad] (the position
servos). With ``ModelSettings.suspension_travel`` each wheel's drop joint gets its bias
force (the wheel's weight carried by the chassis) less the drop force that presses it onto
the ground. By default each arm joint also gets the torque that holds its subtree against
gravity and the base's motion (``qfrc_bias``, recomputed every step, fed forward as a
generalized force: an internal torque between link and parent, as a real joint controller's
gravity feed-forward), so the servo's stiffness alone does not let the arm sag.
:meth:`RobotSim.state` reads back the base pose and the joint angles; :meth:`RobotSim.settle`
sets the robot down on its ground quasi-statically (static cases near a limit).
"""

from __future__ import annotations

from typing import NamedTuple

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from mmstab.model.payload import Payload
from mmstab.model.robot import FloatArray, Robot
from mmstab.physics.plane import roll_pitch
from mmstab.physics.robot_model import Ground, ModelSettings, build_robot_mjcf
from mmstab.terrain.base import GRAVITY_G


class RobotState(NamedTuple):
    """The simulated robot at one instant.

    Attributes:
        time: simulated time [s].
        G_T_B: base pose (4, 4) in G [m].
        roll: [rad], positive lifts the left side (from gravity in B, ``Ramp.roll_pitch``).
        pitch: [rad], positive lifts the nose.
        yaw: heading of x_B about G's z [rad].
        arm_q: arm joint angles (4,) [rad].
        velocity_body: linear velocity of B's origin in B (3,) [m/s].
        omega_body: angular velocity of B in B (3,) [rad/s].
    """

    time: float
    G_T_B: FloatArray
    roll: float
    pitch: float
    yaw: float
    arm_q: FloatArray
    velocity_body: FloatArray
    omega_body: FloatArray


class RobotSim:
    """The whole robot in MuJoCo, stepped with constant track speeds and arm targets.

    Args:
        robot: the robot (payload given separately).
        ground: a planar or heightmap terrain, a heightmap, or None: the flat floor
            (:func:`build_robot_mjcf`).
        friction: Coulomb friction coefficient [-]; None = the terrain's.
        payload: a point mass at the wrist, or None.
        pose: the base's start (x [m], y [m], heading [rad]) in the terrain's map frame.
        arm_q: the arm's start posture (4,) [rad]; None = stowed.
        settings: the model's numbers.
        gravity_feedforward: feed the arm joints' bias torques forward (module docstring).
    """

    def __init__(
        self,
        robot: Robot,
        ground: Ground = None,
        *,
        friction: float | None = None,
        payload: Payload | None = None,
        pose: ArrayLike = (0.0, 0.0, 0.0),
        arm_q: ArrayLike | None = None,
        settings: ModelSettings | None = None,
        gravity_feedforward: bool = True,
    ):
        self.robot = robot
        self.settings = settings or ModelSettings()
        self.mjcf = build_robot_mjcf(
            robot,
            ground,
            friction=friction,
            payload=payload,
            pose=pose,
            arm_q=arm_q,
            settings=self.settings,
        )
        self.model = mujoco.MjModel.from_xml_string(self.mjcf)
        self.data = mujoco.MjData(self.model)
        self.gravity_feedforward = gravity_feedforward
        m = self.model
        self.base = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "base")
        self.terrain = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "terrain")
        names = [f"arm_{link.name}" for link in robot.links]
        joints = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n) for n in names]
        self.arm_qpos = np.array([m.jnt_qposadr[j] for j in joints])
        self.arm_dof = np.array([m.jnt_dofadr[j] for j in joints])
        drops = [j for j in range(m.njnt) if m.joint(j).name.endswith("_zdrop")]
        self.drop_dof = np.array([m.jnt_dofadr[j] for j in drops], dtype=int)
        n_wheels = max(len(drops), 1)
        mean_load = robot.total_mass * float(-GRAVITY_G[2]) / n_wheels
        self.drop_force = self.settings.travel_force * mean_load
        self.arm_ctrl = np.array(
            [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, n) for n in names]
        )
        self.track_ctrl = {
            side: np.array(
                [i for i in range(m.nu) if m.actuator(i).name.startswith(f"wheel_{side}_")]
            )
            for side in ("left", "right")
        }
        self.reset()

    def reset(self) -> RobotState:
        """Back to the start keyframe (tracks braked, arm at its start posture)."""
        self.model.opt.gravity[:] = GRAVITY_G
        mujoco.mj_resetDataKeyframe(self.model, self.data, 0)
        mujoco.mj_forward(self.model, self.data)
        return self.state()

    def step(
        self, track_speeds: ArrayLike, arm_q_target: ArrayLike | None, duration: float
    ) -> RobotState:
        """Simulate ``duration`` [s] with constant commands; the state at the end.

        Args:
            track_speeds: (left, right) track surface speeds [m/s]; (0, 0) brakes.
            arm_q_target: the arm servos' targets (4,) [rad]; None keeps the current ones.
                A step input: interpolate large moves (a 3.8 rad step throws the robot over).
            duration: simulated time [s] (rounded to whole steps, at least one).
        """
        n = max(1, int(round(duration / self.model.opt.timestep)))
        self.advance(track_speeds, arm_q_target, n)
        return self.state()

    def advance(
        self,
        track_speeds: ArrayLike,
        arm_q_target: ArrayLike | None,
        n: int,
        arm_qdot: ArrayLike | None = None,
    ) -> None:
        """:meth:`step`'s simulation without the read-back: ``n`` MuJoCo steps [-].

        ``arm_qdot`` [rad/s]: the joints' commanded speeds, fed forward through the servos'
        damping (``arm_kv · q̇``), so that a servo tracks a moving target without the lag
        ``kv q̇ / kp`` of a position servo damped against rest; None: no feed-forward.
        """
        m, d = self.model, self.data
        d.ctrl[self.track_ctrl["left"]] = track_speeds[0]  # type: ignore[index]
        d.ctrl[self.track_ctrl["right"]] = track_speeds[1]  # type: ignore[index]
        if arm_q_target is not None:
            d.ctrl[self.arm_ctrl] = arm_q_target
        damping = 0.0 if arm_qdot is None else self.settings.arm_kv * np.asarray(arm_qdot)
        drop = self.drop_dof if len(self.drop_dof) else None
        if not self.gravity_feedforward:
            d.qfrc_applied[self.arm_dof] = damping
            if drop is not None:
                d.qfrc_applied[drop] = d.qfrc_bias[drop] - self.drop_force
            mujoco.mj_step(m, d, nstep=n)
            return
        for _ in range(n):
            d.qfrc_applied[self.arm_dof] = d.qfrc_bias[self.arm_dof] + damping
            if drop is not None:  # a dropping wheel: its weight on the body, pressed down
                d.qfrc_applied[drop] = d.qfrc_bias[drop] - self.drop_force
            mujoco.mj_step(m, d)

    def settle(self, duration: float = 1.0, pieces: int = 20) -> RobotState:
        """Set the robot down quasi-statically: tracks braked, arm held at its targets.

        Gravity first points against the base's current z axis (the ground normal under it
        at the start), so the contacts load without any tipping moment; over the last three
        quarters of ``duration`` [s] it turns, in ``pieces`` equal steps, to G's vertical
        (where it stays). A start at rest on a slope near the tipping limit would otherwise
        be kicked over by the contacts' first impulse: the potential barrier 1 deg before the
        limit is a few hundredths of a joule.
        """
        m, d = self.model, self.data
        n = d.xmat[self.base].reshape(3, 3)[:, 2].copy()
        z = -GRAVITY_G / np.linalg.norm(GRAVITY_G)
        axis = np.cross(n, z)
        angle = float(np.arctan2(np.linalg.norm(axis), n @ z))
        axis = axis / np.linalg.norm(axis) if angle > 0 else z
        quat, up = np.zeros(4), np.zeros(3)
        for k in range(pieces + 1):
            mujoco.mju_axisAngle2Quat(quat, axis, angle * k / pieces)
            mujoco.mju_rotVecQuat(up, n, quat)
            m.opt.gravity[:] = -np.linalg.norm(GRAVITY_G) * up
            self.step((0.0, 0.0), None, duration / 4 if k == 0 else 0.75 * duration / pieces)
        m.opt.gravity[:] = GRAVITY_G
        return self.state()

    def state(self) -> RobotState:
        """The current :class:`RobotState`."""
        d, b = self.data, self.base
        R = d.xmat[b].reshape(3, 3).copy()
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, d.xpos[b]
        roll, pitch = roll_pitch(R)
        return RobotState(
            time=float(d.time),
            G_T_B=T,
            roll=roll,
            pitch=pitch,
            yaw=float(np.arctan2(R[1, 0], R[0, 0])),
            arm_q=d.qpos[self.arm_qpos].copy(),
            velocity_body=R.T @ d.qvel[:3],
            omega_body=d.qvel[3:6].copy(),
        )
