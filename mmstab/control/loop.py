"""The controller for a robot's own loop, as pink and mink: targets on tasks, then ``step``.

::

    import mmstab

    robot = mmstab.load_robot("problems/robots/cameleon.yaml")
    controller = mmstab.Controller(robot)                    # the default problem's settings
    controller.tasks["base_point"].set_target([1.0, 0.0, 0.0])   # x [m], y [m], heading [rad]
    controller.tasks["arm_com"].set_target([0.05, 0.0, 0.25])    # arm CoM [m] (map, or body)
    controller.tasks["posture"].set_target(robot.stowed)         # arm joints [rad] (optional)
    while running:
        command = controller.step(base_pose=[x, y, yaw], arm=q_arm)  # measured
        send(command.tracks, command.arm)                    # joint speeds [rad/s]

:class:`Controller` builds the QP controller (:class:`mmstab.control.controller.Controller`,
the paper's Eq. 7-8 with the posture task) once; each task of ``tasks`` keeps its target
(:meth:`Task.set_target`), and :meth:`Controller.step` solves one control period for the
measured state. ``step`` packs the targets into the QP step's reference exactly as the
tracking simulation does (:class:`mmstab.control.layout.StepReference`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.control.controller.certificate import QPStatus
from mmstab.control.controller.settings import ControllerSettings
from mmstab.control.controller.step import Controller as QPController
from mmstab.control.layout import SPROCKETS, TASK_SIZE
from mmstab.core.defaults import with_defaults
from mmstab.model.robot import FloatArray, Robot

if TYPE_CHECKING:
    from mmstab.control.tasks import Task as QPTask
    from mmstab.terrain import Terrain


class Command(NamedTuple):
    """One control period's answer (:meth:`Controller.step`).

    Attributes:
        tracks: sprocket speeds (left, right) (2,) [rad/s].
        arm: arm joint speeds (n,) [rad/s].
        status: the QP's status (:class:`~mmstab.control.controller.QPStatus`).
        success: ``status`` is SUCCESS; otherwise ``tracks`` and ``arm`` are zero (hold
            still, the safe action).
        objective: the QP's cost at the answer [-].
    """

    tracks: FloatArray
    arm: FloatArray
    status: QPStatus
    success: bool
    objective: float


class Task:
    """A task of the controller with its target, as pink's and mink's ``Task.set_target``.

    Attributes:
        name: the task's name (``base_point``, ``arm_com`` or ``arm_com_body``, ``posture``).
        size: its number of rows.
        qp_task: the QP task it drives (:mod:`mmstab.control.tasks`).
        target: the target set (size,), or None.
        rate: the target's rate, the feed-forward (size,) [units/s], or None (zero).
    """

    def __init__(self, qp_task: QPTask, size: int, units: str):
        self.qp_task, self.name, self.size, self._units = qp_task, qp_task.name, size, units
        self.target: FloatArray | None = None
        self.rate: FloatArray | None = None

    def set_target(self, target: ArrayLike, rate: ArrayLike | None = None) -> None:
        """Set the task's target (and its rate, the feed-forward; default zero).

        Args:
            target: (size,) in the task's units (see :class:`Controller`'s table).
            rate: (size,) [units/s], added to the task's rate when ``controller.feedforward``.

        Raises:
            ValueError: a shape other than (size,), or a value that is not finite.
        """
        self.target = self._checked("target", target)
        self.rate = None if rate is None else self._checked("rate", rate)

    def _checked(self, what: str, value: ArrayLike) -> FloatArray:
        v = np.array(value, dtype=float)
        if v.shape != (self.size,):
            raise ValueError(
                f"task {self.name!r}: {what} must have shape ({self.size},) {self._units}, "
                f"got {v.shape}"
            )
        if not np.all(np.isfinite(v)):
            raise ValueError(f"task {self.name!r}: {what} must be finite, got {v}")
        return v

    def __repr__(self) -> str:
        return f"Task({self.name!r}, target={self.target})"


#: Units of each task's target, for messages and the docs.
UNITS = {
    "base_point": "[m, m, rad]",
    "arm_com": "[m] (map frame)",
    "arm_com_body": "[m] (body frame)",
    "posture": "[rad]",
}


class Controller:
    """The QP tracking controller for a robot's own control loop.

    Tasks (``tasks[name]``), their targets and units:

    ============== ========================================================================
    ``base_point`` (x, y) of the control point ``base_offset`` ahead of the body origin
                   and the heading, in the map frame M (3,) [m, m, rad]; required.
    ``arm_com``    the arm's CoM in M (3,) [m] (``arm_com_frame: map``); required, or
    ``arm_com_body`` the arm's CoM in the body frame B (3,) [m] (``arm_com_frame: body``).
    ``posture``    the arm joints (n,) [rad]; optional: unset, the arm's own posture (the
                   task then only damps the arm's redundant directions).
    ============== ========================================================================

    Attributes:
        robot: the robot.
        settings: the controller's settings (gains, weights, plugin, dt).
        tasks: the tasks by name, in the QP's order.
        qp: the QP controller (:class:`mmstab.control.controller.Controller`): its packed
            ``solve(state, xi_des, ...)`` and the CasADi ``step`` Function the code
            generator exports.
        terrain: the ground under the robot, or None (a plane: the map frame's).
    """

    def __init__(
        self,
        robot: Robot,
        settings: ControllerSettings | None = None,
        terrain: Terrain | None = None,
    ):
        """Build the controller once (CasADi expressions and the QP solver: about a second).

        Args:
            robot: the robot.
            settings: the ``controller:`` settings; default the default problem's for this
                robot's joints (a problem file's that names none).
            terrain: the ground (its local ground under the base, for the task map); None: a
                plane, the map frame's.
        """
        if settings is None:
            section = with_defaults({}, robot.arm_joints)["controller"]
            settings = ControllerSettings.from_section(section)
        self.robot, self.settings, self.terrain = robot, settings, terrain
        self.qp = QPController(robot, settings)
        n = self.qp.layout.arm
        self.tasks: dict[str, Task] = {}
        for t in self.qp.tasks:
            size = t.rows(self.qp.model)
            self.tasks[t.name] = Task(t, size, UNITS.get(t.name, f"({size},)"))
        self._arm = n

    def step(
        self,
        *,
        base_pose: ArrayLike,
        arm: ArrayLike,
        tracks: ArrayLike = (0.0, 0.0),
        ground: ArrayLike | None = None,
    ) -> Command:
        """One control period: joint speeds toward the tasks' targets from the measured state.

        Call it every ``settings.dt`` seconds with the measured state; send the speeds to
        the tracks' sprockets and the arm's joints until the next call.

        Args:
            base_pose: the body's pose (x [m], y [m], heading [rad]) in the map frame M.
            arm: the arm's joint angles (n,) [rad].
            tracks: the sprockets' angles (left, right) (2,) [rad] (the QP does not depend
                on them).
            ground: the local ground (z [m], roll [rad], pitch [rad]) under the base; default
                the terrain's (:meth:`mmstab.terrain.Terrain.local_ground`), zero without one.

        Returns:
            The command; on failure the speeds are zero (hold still).

        Raises:
            ValueError: a required task has no target, or a shape is wrong.
        """
        pose = np.asarray(base_pose, dtype=float)
        if pose.shape != (3,):
            raise ValueError(f"base_pose must be (x, y, heading) (3,), got {pose.shape}")
        q_arm = np.asarray(arm, dtype=float)
        if q_arm.shape != (self._arm,):
            raise ValueError(f"arm must have shape ({self._arm},) [rad], got {q_arm.shape}")
        state = np.concatenate([pose, np.asarray(tracks, dtype=float), q_arm])
        if ground is None and self.terrain is not None:
            ground = self.terrain.local_ground(pose[None])[0]
        xi_des, xi_rate = np.zeros(TASK_SIZE), np.zeros(TASK_SIZE)
        q_ref = q_rate = None
        for t in self.tasks.values():
            slot = t.qp_task.slots.value
            if slot is None:
                continue
            if slot.field == "q_ref":  # the posture: optional
                q_ref, q_rate = t.target, t.rate
                continue
            if t.target is None:
                raise ValueError(f"task {t.name!r} has no target: call set_target first")
            a, b = slot.rows or (0, TASK_SIZE)
            xi_des[a:b] = t.target
            if t.rate is not None:
                xi_rate[a:b] = t.rate
        result = self.qp.solve(state, xi_des, xi_rate, q_ref, q_rate, ground)
        qdot = result.qdot
        tracks_rate, arm_rate = qdot[:SPROCKETS].copy(), qdot[SPROCKETS:].copy()
        return Command(tracks_rate, arm_rate, result.status, result.success, result.objective)
