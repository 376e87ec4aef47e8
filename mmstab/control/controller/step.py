"""The built controller: the QP, the conic and one ``step`` Function; NumPy ``solve``."""

from __future__ import annotations

import contextlib
from collections.abc import Sequence
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from mmstab.control.controller.boxqp import build_boxqp
from mmstab.control.controller.certificate import (
    ControlResult,
    QPStatus,
    build_guard_and_certificate,
    quiet_stdout,
)
from mmstab.control.controller.qp import QPData, build_qp
from mmstab.control.controller.settings import PLUGINS, ControllerSettings
from mmstab.control.layout import ARM, TASK_SIZE, ControllerParams, StepReference
from mmstab.control.limits import Limit, build_limits
from mmstab.control.tasks import Task, TaskModel, build_tasks, task_map
from mmstab.model.robot import Robot
from mmstab.terrain import GROUND_SIZE


def _shape_error(name: str, value: Any, n: int) -> ValueError:
    return ValueError(f"{name} must have shape ({n},), got {np.shape(value)}")


def _conic_options(settings: ControllerSettings) -> dict[str, Any]:
    opts: dict[str, dict[str, Any]] = {
        # qpOASES: "sparse" is refused without linear constraints; its default termination
        # tolerance (~1e-9) leaves q̇ errors ~1e-6 rad/s near degenerate active sets.
        "qpoases": {"printLevel": "none", "terminationTolerance": 1e-12},
        "osqp": {
            "osqp": {
                "eps_abs": settings.osqp.eps_abs,
                "eps_rel": settings.osqp.eps_rel,
                "max_iter": settings.osqp.max_iter,
                "polish": settings.osqp.polish,
                "verbose": False,
            }
        },
        "qrqp": {"print_iter": False, "print_header": False, "print_info": False},
        "daqp": {},
        "box": {},
    }
    return {**opts[settings.plugin], "error_on_fail": False}


class Controller:
    """The built controller: CasADi QP and one ``step`` Function; NumPy ``solve``.

    Not thread-safe (``solve`` reuses preallocated buffers); build one per thread.

    Attributes:
        robot: the robot.
        settings: the settings it was built with.
        tasks: the tasks of the QP, summed in this order (default
            :data:`~mmstab.control.tasks.DEFAULT_TASKS`).
        limits: its limits, intersected in this order (default
            :data:`~mmstab.control.limits.DEFAULT_LIMITS`).
        model: task kinematics (ξ of the tasks' :func:`~mmstab.control.tasks.task_map`, J,
            motion integration).
        params: the run-time parameters (joint limits, gains, weights, dt).
        qp: ``Function`` (state, reference, params) -> (H, g, lbx, ubx, xi_dot_des,
            q_dot_posture, cost0, status): the QP's matrices
            (:func:`mmstab.control.controller.qp.build_qp`),
            for inspection and tests.
        conic: the CasADi ``conic`` (dense H, no linear constraints), or for the ``box``
            plugin the dedicated solver (:mod:`~mmstab.control.controller.boxqp`, same arguments).
        layout: the packed sizes for the robot's arm of n joints (``model.layout``).
        step: ``Function`` (state (5 + n), reference (15 + 2n) = [ξ_des, ξ̇_ref, q_ref, q̇_ref,
            ground] (:class:`StepReference`), params (18 + 6n) (:class:`ControllerParams`)) ->
            (qdot (2 + n) [rad/s], status (QPStatus as float), objective): J + QP assembly +
            conic + certificate, one call; what the code generator exports.
        steps: number of ``solve`` calls.
        failures: number of them that returned the safe action (status != SUCCESS).
    """

    def __init__(
        self,
        robot: Robot,
        settings: ControllerSettings,
        tasks: Sequence[Task] | None = None,
        limits: Sequence[Limit] | None = None,
    ):
        if settings.plugin not in PLUGINS:
            raise ValueError(f"unknown QP plugin {settings.plugin!r}; choose one of {PLUGINS}")
        self.robot, self.settings = robot, settings
        self.tasks = tuple(build_tasks(settings) if tasks is None else tasks)
        self.limits = tuple(build_limits() if limits is None else limits)
        self.model = TaskModel(robot, task_map(self.tasks))
        self.params = ControllerParams.from_settings(robot, settings)
        self.qp = build_qp(
            self.model,
            self.tasks,
            self.limits,
            (float(QPStatus.SUCCESS), float(QPStatus.NONFINITE_INPUT), float(QPStatus.INFEASIBLE)),
        )
        self.layout = lay = self.model.layout
        n = lay.joints
        if settings.plugin == "box":  # the dedicated box-QP solver (same signature)
            self.conic = build_boxqp(n)
        else:
            with quiet_stdout():
                self.conic = ca.conic(
                    "controller_qp",
                    settings.plugin,
                    {"h": ca.Sparsity.dense(n, n), "a": ca.Sparsity(0, n)},
                    _conic_options(settings),
                )
        guard, certificate = build_guard_and_certificate(settings.kkt_tol, n)
        state, ref = ca.MX.sym("state", lay.state), ca.MX.sym("reference", lay.reference)
        p = ca.MX.sym("params", lay.params)
        # the certificate judges the whole cost: task, regularisation and posture terms
        H, g, lbx, ubx, _, _, cost0, status = self.qp(state, ref, p)
        if settings.plugin == "box":
            # no guard: the solver takes any numbers (NaN, crossed bounds) and returns within
            # its iteration limit, and the certificate ignores x unless the status is SUCCESS
            x = self.conic(h=H, g=g, lbx=lbx, ubx=ubx)["x"]
        else:
            Hs, gs, lbs, ubs = guard(H, g, lbx, ubx, status)
            x = self.conic(h=Hs, g=gs, lbx=lbs, ubx=ubs)["x"]
        self.step = ca.Function(
            "controller_step",
            [state, ref, p],
            list(certificate(x, H, g, lbx, ubx, cost0, status)),
            ["state", "reference", "params"],
            ["qdot", "status", "objective"],
        )
        self.steps = self.failures = 0
        # Preallocated arguments/results bound once to the Function's buffer (fast calls).
        #: The slices of ξ_des, ξ̇_ref, q_ref, q̇_ref and the local ground in the reference.
        self._slices = tuple(StepReference.offsets(lay.arm).values())
        self._state, self._ref = np.zeros(lay.state), np.zeros(lay.reference)
        self._p = self.params.pack()
        self._qdot, self._status, self._objective = np.zeros(n), np.zeros(1), np.zeros(1)
        # (the stubs ask for a byte size the SWIG typemap fills in from the memoryview)
        self._buffer: Any
        self._buffer, self._eval = self.step.buffer()
        for i, a in enumerate((self._state, self._ref, self._p)):
            self._buffer.set_arg(i, memoryview(a))  # type: ignore[arg-type]
        for i, a in enumerate((self._qdot, self._status, self._objective)):
            self._buffer.set_res(i, memoryview(a))  # type: ignore[arg-type]
        with quiet_stdout():  # the plugin's per-memory set-up may print (qpOASES banner)
            self._eval()
        # OSQP's polishing prints a line on stdout whatever "verbose" says.
        self._quiet = settings.plugin == "osqp" and settings.osqp.polish

    def set_params(self, params: ControllerParams) -> None:
        """Replace the run-time parameters (gains, weights, limits, dt) without rebuilding."""
        packed = params.pack()
        if packed.shape != self._p.shape:
            raise ValueError(f"params pack to {packed.shape}, expected {self._p.shape}")
        self.params = params
        self._p[:] = packed

    def _load(
        self,
        state: ArrayLike,
        xi_des: ArrayLike,
        xi_dot_ref: ArrayLike | None,
        q_ref: ArrayLike | None,
        q_dot_ref: ArrayLike | None,
        ground: ArrayLike | None,
    ) -> None:
        # written out (no loop): this runs every control step
        xi_sl, xi_dot_sl, q_sl, q_dot_sl, ground_sl = self._slices
        ref, arm = self._ref, self.layout.arm
        if np.shape(state) != self._state.shape:
            raise _shape_error("state", state, self._state.size)
        self._state[:] = state
        if np.shape(xi_des) != (TASK_SIZE,):
            raise _shape_error("xi_des", xi_des, TASK_SIZE)
        ref[xi_sl] = xi_des
        if xi_dot_ref is None:  # no feed-forward
            ref[xi_dot_sl] = 0.0
        elif np.shape(xi_dot_ref) != (TASK_SIZE,):
            raise _shape_error("xi_dot_ref", xi_dot_ref, TASK_SIZE)
        else:
            ref[xi_dot_sl] = xi_dot_ref
        if q_ref is None:  # the posture held: the posture task only damps the arm
            ref[q_sl] = self._state[ARM]
        elif np.shape(q_ref) != (arm,):
            raise _shape_error("q_ref", q_ref, arm)
        else:
            ref[q_sl] = q_ref
        if q_dot_ref is None:
            ref[q_dot_sl] = 0.0
        elif np.shape(q_dot_ref) != (arm,):
            raise _shape_error("q_dot_ref", q_dot_ref, arm)
        else:
            ref[q_dot_sl] = q_dot_ref
        if ground is None:  # the pose rests level on M's plane (the ramp)
            ref[ground_sl] = 0.0
        elif np.shape(ground) != (GROUND_SIZE,):
            raise _shape_error("ground", ground, GROUND_SIZE)
        else:
            ref[ground_sl] = ground

    def solve(
        self,
        state: ArrayLike,
        xi_des: ArrayLike,
        xi_dot_ref: ArrayLike | None = None,
        q_ref: ArrayLike | None = None,
        q_dot_ref: ArrayLike | None = None,
        ground: ArrayLike | None = None,
    ) -> ControlResult:
        """One control step: joint speeds for the current state and reference.

        Args:
            state: [x, y, γ, θ_l, θ_r, θ_0..θ_{n-1}] (5 + n,) [m, m, rad, rad...].
            xi_des: desired task ξ_des (6,) [m, m, rad, m, m, m]: the base point in M, the arm CoM
                in M or, with ``arm_com_frame: body``, in B.
            xi_dot_ref: task feed-forward ξ̇_ref (6,) [m/s, rad/s] (used if ``feedforward``);
                default zero.
            q_ref: arm posture reference (n,) [rad]; default the current arm posture (the
                posture task then only damps the arm speeds, with W_q on top of W_B).
            q_dot_ref: posture feed-forward q̇_ref (n,) [rad/s] (used if ``feedforward``);
                default zero.
            ground: local ground (z [m], roll [rad], pitch [rad]) of the reference pose
                (:meth:`mmstab.terrain.Terrain.local_ground`); default zero (the ramp).

        Returns:
            The result; on failure ``qdot`` is zero (hold still) and ``failures`` counts it.
        """
        self._load(state, xi_des, xi_dot_ref, q_ref, q_dot_ref, ground)
        if self._quiet:
            with quiet_stdout():
                self._eval()
        else:
            self._eval()
        status = QPStatus(int(self._status[0]))
        success = status is QPStatus.SUCCESS
        self.steps += 1
        self.failures += not success
        return ControlResult(self._qdot.copy(), status, success, float(self._objective[0]))

    def qp_data(
        self,
        state: ArrayLike,
        xi_des: ArrayLike,
        xi_dot_ref: ArrayLike | None = None,
        q_ref: ArrayLike | None = None,
        q_dot_ref: ArrayLike | None = None,
        ground: ArrayLike | None = None,
    ) -> QPData:
        """The QP one step would solve (arguments as :meth:`solve`)."""
        self._load(state, xi_des, xi_dot_ref, q_ref, q_dot_ref, ground)
        H, g, lbx, ubx, xdd, qdp, cost0, status = (
            np.asarray(v) for v in self.qp(self._state, self._ref, self._p)
        )
        vec = (g.ravel(), lbx.ravel(), ubx.ravel(), xdd.ravel(), qdp.ravel())
        return QPData(H, *vec, cost0.item(), QPStatus(int(status.item())))

    def solve_direct(
        self,
        state: ArrayLike,
        xi_des: ArrayLike,
        xi_dot_ref: ArrayLike | None = None,
        q_ref: ArrayLike | None = None,
        q_dot_ref: ArrayLike | None = None,
        ground: ArrayLike | None = None,
    ) -> ControlResult:
        """The same step judged by the plugin's own status (``stats()['success']``); slow.

        For cross-checking :meth:`solve`'s in-graph certificate; does not count steps.
        Arguments as :meth:`solve`.
        """
        qp = self.qp_data(state, xi_des, xi_dot_ref, q_ref, q_dot_ref, ground)
        zero = np.zeros(self.layout.joints)
        if qp.status is not QPStatus.SUCCESS:
            return ControlResult(zero, QPStatus(qp.status), False, qp.cost0)
        with quiet_stdout() if self._quiet else contextlib.nullcontext():
            sol = self.conic(h=qp.H, g=qp.g, lbx=qp.lbx, ubx=qp.ubx)
        if self.settings.plugin == "box":  # its own status is an output: 0 = optimal
            success = float(sol["flag"]) == 0.0
        else:
            success = self.conic.stats()["success"]
        if not success:
            return ControlResult(zero, QPStatus.SOLVER_FAILED, False, qp.cost0)
        qdot = np.asarray(sol["x"]).ravel()
        objective = 0.5 * qdot @ qp.H @ qdot + qp.g @ qdot + qp.cost0
        return ControlResult(qdot, QPStatus.SUCCESS, True, float(objective))


def build_controller(
    robot: Robot,
    settings: ControllerSettings,
    tasks: Sequence[Task] | None = None,
    limits: Sequence[Limit] | None = None,
) -> Controller:
    """Build the controller once (CasADi expressions, conic, ``step`` Function).

    Args:
        robot: the robot (joint and track speed limits, kinematics).
        settings: the ``controller:`` settings (plugin, gains, weights, dt, base offset).
        tasks: the QP's tasks (default: :data:`~mmstab.control.tasks.DEFAULT_TASKS` built
            from ``settings``, :func:`~mmstab.control.tasks.build_tasks`).
        limits: its limits (default: :data:`~mmstab.control.limits.DEFAULT_LIMITS`).

    Raises:
        ValueError: an unknown plugin, or tasks whose ξ_des rows do not tile ξ.
    """
    return Controller(robot, settings, tasks, limits)
