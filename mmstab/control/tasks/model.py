"""What the tasks read of the robot: symbolic state, local ground, track kinematics, ξ."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from mmstab.control.layout import ARM, POSE, Layout
from mmstab.control.plant import build_plant
from mmstab.model.robot import FloatArray, Robot
from mmstab.terrain import GROUND_SIZE, place_local_sx


class MappedTask(Protocol):
    """What the task map ξ needs of a task (:class:`mmstab.control.tasks.Task` gives it)."""

    def value(self, model: TaskModel) -> ca.SX:
        """The task's value at the model's state and ground."""
        ...

    def jacobian(self, model: TaskModel) -> ca.SX:
        """Its Jacobian with respect to the joint speeds."""
        ...


class TaskModel:
    """The robot as the tasks see it (pink's ``Configuration``), and the task map ξ.

    It holds the model only: the tasks whose values make ξ are handed in
    (:func:`mmstab.control.tasks.base.task_map`; :func:`mmstab.control.tasks.build_task_model`
    for the default ones), so this module imports no task.

    The base pose is part of the state, not a function of q: the tracked base is
    nonholonomic, pose rate = B(γ) [θ̇_l, θ̇_r] with B the 3x2 track map, so a quantity
    f(pose, q_arm) has d f/dt = [∂f/∂pose · B(γ) | ∂f/∂q_arm] q̇ (:meth:`rate_jacobian`).

    Attributes:
        robot: the robot.
        layout: the packed sizes for the robot's arm (n joints).
        state: the symbolic state (5 + n,) SX.
        ground: the symbolic local ground (3,) SX [m, rad, rad].
        track_map: B(γ) (3, 2) SX [m/rad, rad/rad].
        com_body: the arm CoM g_a^B(q_arm) (3,) SX [m].
        xi: ξ (6,) SX: the mapped tasks' values stacked (by default [base point and heading,
            arm CoM]).
        J: the task Jacobian (6, 2 + n) SX: ξ̇ = J q̇ (the ground held constant).
        f_task: ``Function`` (state, ground) -> xi.
        f_jacobian: ``Function`` (state, ground) -> J.
        f_integrate: the plant (:func:`mmstab.control.plant.build_plant`).
    """

    def __init__(self, robot: Robot, xi_tasks: Sequence[MappedTask]):
        """The model of ``robot``; ξ stacks the values of ``xi_tasks`` (in order)."""
        self.robot = robot
        tracks = robot.base.tracks
        r, b = tracks.sprocket_radius, tracks.separation
        self.layout = Layout.of(robot)
        s = self.state = ca.SX.sym("state", self.layout.state)
        ground = self.ground = ca.SX.sym("ground", GROUND_SIZE)
        c, sn = ca.cos(s[2]), ca.sin(s[2])
        self.track_map = ca.vertcat(
            ca.horzcat(r / 2 * c, r / 2 * c),
            ca.horzcat(r / 2 * sn, r / 2 * sn),
            ca.horzcat(-r / b, r / b),
        )
        self.com_body = robot.kinematics.f_arm_com(s[ARM])  # g_a^B(q_arm), inlined as SX
        self.xi = ca.vertcat(*(t.value(self) for t in xi_tasks))
        self.J = ca.vertcat(*(t.jacobian(self) for t in xi_tasks))
        names = ["state", "ground"]
        self.f_task = ca.Function("task", [s, ground], [self.xi], names, ["xi"])
        self.f_jacobian = ca.Function("task_jacobian", [s, ground], [self.J], names, ["J"])
        self.f_integrate = build_plant(robot)

    def place(self, point_body: ca.SX) -> ca.SX:
        """A body point placed in M at the state's pose and the local ground (SX (3,))."""
        return place_local_sx(self.state[POSE], self.ground, point_body)

    def rate_jacobian(self, expr: ca.SX) -> ca.SX:
        """J of ``expr(pose, q_arm)`` with respect to q̇: [∂/∂pose · B(γ) | ∂/∂q_arm] (m, 2 + n)."""
        s = self.state
        return ca.horzcat(ca.jacobian(expr, s[POSE]) @ self.track_map, ca.jacobian(expr, s[ARM]))

    def task(self, state: ArrayLike, ground: ArrayLike = (0.0, 0.0, 0.0)) -> FloatArray:
        """ξ at a state (5 + n,) and local ground (3,) -> (6,) [m, m, rad, m, m, m]."""
        return np.asarray(self.f_task(np.asarray(state, float), np.asarray(ground, float))).ravel()

    def task_batch(self, states: ArrayLike, ground: ArrayLike) -> FloatArray:
        """ξ for states (N, 5 + n) and their local ground (N, 3) -> (N, 6) (one mapped call)."""
        s = np.atleast_2d(np.asarray(states, dtype=float))
        g = np.broadcast_to(np.asarray(ground, dtype=float), (len(s), GROUND_SIZE))
        return np.asarray(self.f_task.map(len(s))(s.T, g.T)).T

    def jacobian(self, state: ArrayLike, ground: ArrayLike = (0.0, 0.0, 0.0)) -> FloatArray:
        """J at a state (5 + n,) and local ground (3,) -> (6, 2 + n) [m/rad, rad/rad]."""
        return np.asarray(self.f_jacobian(np.asarray(state, float), np.asarray(ground, float)))

    def integrate(self, state: ArrayLike, qdot: ArrayLike, dt: float) -> FloatArray:
        """State after ``dt`` [s] at constant joint speeds ``qdot`` (2 + n,) [rad/s] (the plant)."""
        out = self.f_integrate(np.asarray(state, dtype=float), np.asarray(qdot, dtype=float), dt)
        return np.asarray(out).ravel()
