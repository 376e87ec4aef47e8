"""Tracking controller (paper Section II-E, Eq. 7-8; DESIGN.md §6): settings, QP, one step.

The task model (ξ, J, motion) and the QP's assembly live in :mod:`mmstab.tasks`; this module
builds the solver around them and certifies its answers. Vectors: state s (9) = base pose in S
[x, y, γ] and the joints q = [θ_l, θ_r, θ_0..θ_3]; task ξ (6) = [g_bx, g_by, γ, g_ax, g_ay,
g_az] in S.

**Base control point.** ξ's first two rows are the paper's g_b, taken as the point a distance d
= ``base_offset`` [m] ahead of the body origin: g_b = [x, y] + d [cos γ, sin γ] (d = 0 is the
body origin, the centre of the track contact rectangle). Default d = 0.2 m with a small heading
weight (W_A[2] = 0.01): for d = 0 the base rows of J have rank 1 in position, so a lateral
error has no instantaneous correction and decays only through the heading on a curved path (on
the default lap a 0.1 m offset is still 0.1 m after 10 s, 1.5 mm after the 30 s lap); for d > 0
the block [[cos γ, −d sin γ], [sin γ, d cos γ]] is invertible, so the point's error is
corrected directly (the usual look-ahead point of differential-drive tracking; the same 0.1 m
offset is under 0.1 mm after 5 s; tests/test_tracking.py) and the light heading row only keeps
the body aligned where the point's motion leaves it free. The reference must use the same d
(:func:`mmstab.reference.base_reference`). Whatever d, J has rank 5 (three base rows, two
sprockets): a moving, consistent reference with feed-forward (the circle) is tracked to zero
error, but a *constant* target is reached only up to an error in J's left null space (Jᵀ W_A e
= 0; no smooth static feedback stabilises a nonholonomic pose, Brockett 1983).

**QP (Eq. 7-8 + posture task).** ξ̇_des = K_p (ξ_des − ξ) + f ξ̇_ref (heading error wrapped to
(−π, π]) and q̇_post = K_q (q_ref − q_arm) + f q̇_ref; then, with H = Jᵀ W_A J + W_B + Sᵀ W_q S
and g = −Jᵀ W_A ξ̇_des − Sᵀ W_q q̇_post (S: the arm columns)::

    min ½ q̇ᵀ H q̇ + gᵀ q̇    s.t.  max(−q̇_max, (q_min − q)/dt) ≤ q̇ ≤ min(q̇_max, (q_max − q)/dt)

(position bounds on the arm joints only; the sprockets turn freely). W_B > 0, so the QP is
strictly convex and every plugin must return the same q̇. The arm-CoM rows are 3 equations for
4 arm joints: the posture task (weights W_q = ``posture_weight``, 10⁻³ by default, well under
the CoM rows' ~0.1 m²/rad² in Jᵀ W_A J, so the CoM task dominates) chooses the remaining arm
direction by pulling toward the planner's collision-free postures q_ref(s)
(:mod:`mmstab.posture`); without it the redundancy drifts and the upper arm went through the
body for 29 % of the default lap.

**Failure handling.** The one CasADi ``step`` Function certifies its own answer, so the status
is the same interpreted and code-generated and does not depend on a plugin's exceptions:
non-finite inputs (``NONFINITE_INPUT``) or contradictory bounds (``INFEASIBLE``) are detected
*before* the solver, which is then fed a harmless dummy QP; the solver's answer must be finite,
within the bounds to ``kkt_tol`` and satisfy the projected-Newton optimality residual
``|q̇ − Π(q̇ − ∇f/diag H)|∞ ≤ kkt_tol`` (else ``SOLVER_FAILED``). The solution is then clipped to
the bounds, so the limits hold to round-off. On any failure the returned q̇ is the documented
safe action **hold still, q̇ = 0**, the result says so and :attr:`Controller.failures` counts it.
:meth:`Controller.solve_direct` solves the same QP through the plugin's own status
(``stats()['success']``), to cross-check the certificate.

**Speed.** :meth:`Controller.solve` evaluates ``step`` through ``Function.buffer()`` on
preallocated arrays: no dict arguments, no DM conversion.
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from enum import IntEnum
from pathlib import Path
from typing import Any, NamedTuple

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from mmstab.config import ConfigError
from mmstab.robot import FloatArray, Robot
from mmstab.tasks import (
    _SINC_SERIES_BELOW,
    ARM,
    ARM_JOINTS,
    JOINT_COUNT,
    JOINTS,
    PARAMS_SIZE,
    POSE,
    REFERENCE_SIZE,
    STATE_SIZE,
    TASK_SIZE,
    TRACK_DATA_SIZE,
    ControllerParams,
    QPData,
    StepReference,
    TaskModel,
    all_finite,
    build_qp,
)
from mmstab.terrain import GROUND_SIZE

__all__ = [  # the task model and layouts are re-exported: most callers import them from here
    "_SINC_SERIES_BELOW",
    "ARM",
    "ARM_JOINTS",
    "CODEGEN_PLUGINS",
    "JOINT_COUNT",
    "JOINTS",
    "PARAMS_SIZE",
    "PLUGINS",
    "POSE",
    "REFERENCE_SIZE",
    "STATE_SIZE",
    "TASK_SIZE",
    "TRACK_DATA_SIZE",
    "ControlResult",
    "Controller",
    "ControllerParams",
    "ControllerSettings",
    "OsqpSettings",
    "QPData",
    "QPStatus",
    "StepReference",
    "TaskModel",
    "build_controller",
    "check_settings",
    "quiet_stdout",
]

PLUGINS = ("qpoases", "osqp", "qrqp", "daqp")
#: Plugins CasADi can generate C for (qpOASES emits ``#error``).
CODEGEN_PLUGINS = ("qrqp", "daqp", "osqp")


#: The slices of ξ_des, ξ̇_ref, q_ref, q̇_ref and the local ground in the reference vector.
_REFERENCE_SLICES = tuple(StepReference.offsets().values())


def _shape_error(name: str, value: Any, n: int) -> ValueError:
    return ValueError(f"{name} must have shape ({n},), got {np.shape(value)}")


class QPStatus(IntEnum):
    """Outcome of one controller step; anything but SUCCESS returns q̇ = 0 (hold still)."""

    SUCCESS = 0
    NONFINITE_INPUT = 1  # NaN/inf in the state, reference or parameters
    INFEASIBLE = 2  # a joint's lower bound exceeds its upper bound (outside its limits)
    SOLVER_FAILED = 3  # the plugin's answer is not finite, feasible and optimal


# ----------------------------------------------------------------------------------- settings
@dataclass(frozen=True)
class OsqpSettings:
    """OSQP options: tolerances (absolute [rad/s], relative [-]), iterations, polishing."""

    eps_abs: float
    eps_rel: float
    max_iter: int
    polish: bool


_VECTORS = ("kp", "w_a", "w_b", "posture_gain", "posture_weight")


@dataclass(frozen=True)
class ControllerSettings:
    """The ``controller:`` section of a problem file.

    Attributes:
        dt: control period and integration step [s].
        lap_time: time for one lap of the base circle [s] (sets the reference speed).
        duration: simulated time [s].
        kp: proportional gains K_p, one per task row (6,) [1/s].
        w_a: task weights W_A (6,) [-].
        w_b: joint-velocity weights W_B (6,), > 0 [-].
        posture_gain: posture gains K_q, one per arm joint (4,) [1/s].
        posture_weight: posture weights W_q, one per arm joint (4,) [-].
        plugin: QP plugin, one of :data:`PLUGINS`.
        feedforward: add ξ̇_ref to ξ̇_des and q̇_ref to q̇_post.
        base_offset: base control point ahead of the body origin d [m].
        approach_time: length of the arm's start-up reference [s] (:mod:`mmstab.approach`;
            0: the lap's references from t = 0).
        kkt_tol: tolerance of the in-graph solution certificate [rad/s].
        osqp: OSQP options.
    """

    dt: float
    lap_time: float
    duration: float
    kp: tuple[float, ...]
    w_a: tuple[float, ...]
    w_b: tuple[float, ...]
    posture_gain: tuple[float, ...]
    posture_weight: tuple[float, ...]
    plugin: str
    feedforward: bool
    base_offset: float
    approach_time: float
    kkt_tol: float
    osqp: OsqpSettings

    @classmethod
    def from_section(cls, section: Mapping[str, Any]) -> ControllerSettings:
        """Build from a validated ``controller:`` section."""
        vecs = {k: tuple(float(v) for v in section[k]) for k in _VECTORS}
        o = section["osqp"]
        return cls(
            dt=float(section["dt"]),
            lap_time=float(section["lap_time"]),
            duration=float(section["duration"]),
            plugin=str(section["plugin"]),
            feedforward=bool(section["feedforward"]),
            base_offset=float(section["base_offset"]),
            approach_time=float(section["approach_time"]),
            kkt_tol=float(section["kkt_tol"]),
            osqp=OsqpSettings(
                float(o["eps_abs"]), float(o["eps_rel"]), int(o["max_iter"]), bool(o["polish"])
            ),
            **vecs,
        )


def check_settings(path: Path, section: Mapping[str, Any]) -> None:
    """Semantic checks of the ``controller:`` section beyond its schema.

    Raises:
        ConfigError: naming the field (``controller.duration``, ``controller.kp``,
            ``controller.posture_gain``).
    """
    dt = float(section["dt"])
    if float(section["duration"]) < dt:
        raise ConfigError(path, "controller.duration", f"must be at least dt = {dt} s")
    for gain in ("kp", "posture_gain"):
        if max(section[gain]) * dt >= 1.0:
            raise ConfigError(
                path,
                f"controller.{gain}",
                f"{gain} * dt must stay below 1 (the discrete loop overshoots); dt = {dt} s",
            )


class ControlResult(NamedTuple):
    """One step's answer: joint speeds (6,) [rad/s], status, success, Eq. 7 cost at ``qdot``."""

    qdot: FloatArray
    status: QPStatus
    success: bool
    objective: float


def _build_guard_and_certificate(kkt_tol: float) -> tuple[ca.Function, ca.Function]:
    n = JOINT_COUNT
    H, g = ca.SX.sym("H", n, n), ca.SX.sym("g", n)
    lbx, ubx, status = ca.SX.sym("lbx", n), ca.SX.sym("ubx", n), ca.SX.sym("status")
    ok = status == float(QPStatus.SUCCESS)
    guard = ca.Function(  # a dummy, well-posed QP when the real one must not reach the solver
        "guard",
        [H, g, lbx, ubx, status],
        [
            ca.if_else(ok, H, ca.SX.eye(n)),
            ca.if_else(ok, g, 0),
            ca.if_else(ok, lbx, -1),
            ca.if_else(ok, ubx, 1),
        ],
    )
    x, cost0 = ca.SX.sym("x", n), ca.SX.sym("cost0")
    clipped = ca.fmin(ca.fmax(x, lbx), ubx)
    violation = ca.mmax(ca.vertcat(lbx - x, x - ubx))
    newton = clipped - ca.fmin(ca.fmax(clipped - (H @ clipped + g) / ca.diag(H), lbx), ubx)
    certified = ca.logic_and(all_finite(x), violation <= kkt_tol)
    certified = ca.logic_and(certified, ca.mmax(ca.fabs(newton)) <= kkt_tol)
    final = ca.if_else(ok, ca.if_else(certified, status, float(QPStatus.SOLVER_FAILED)), status)
    qdot = ca.if_else(final == float(QPStatus.SUCCESS), clipped, 0)
    objective = 0.5 * ca.dot(qdot, H @ qdot) + ca.dot(g, qdot) + cost0
    certificate = ca.Function(
        "certificate", [x, H, g, lbx, ubx, cost0, status], [qdot, final, objective]
    )
    return guard, certificate


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
    }
    return {**opts[settings.plugin], "error_on_fail": False}


@contextlib.contextmanager
def quiet_stdout() -> Iterator[None]:
    """Silence C-level stdout (qpOASES prints its licence banner when it is created)."""
    sys.stdout.flush()
    try:
        saved = os.dup(1)
    except OSError:  # no real stdout (e.g. captured): nothing to silence
        yield
        return
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 1)
            yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


class Controller:
    """The built controller: CasADi QP and one ``step`` Function; NumPy ``solve``.

    Not thread-safe (``solve`` reuses preallocated buffers); build one per thread.

    Attributes:
        robot: the robot.
        settings: the settings it was built with.
        model: task kinematics (ξ, J, motion integration).
        params: the run-time parameters (joint limits, gains, weights, dt).
        qp: ``Function`` (state, reference, params) -> (H, g, lbx, ubx, xi_dot_des,
            q_dot_posture, cost0, status): the QP's matrices (:func:`mmstab.tasks.build_qp`),
            for inspection and tests.
        conic: the CasADi ``conic`` (dense H, no linear constraints).
        step: ``Function`` (state (9), reference (23) = [ξ_des, ξ̇_ref, q_ref, q̇_ref, ground]
            (:class:`StepReference`), params (42) (:class:`ControllerParams`)) ->
            (qdot (6) [rad/s], status (QPStatus as float), objective): J + QP assembly +
            conic + certificate, one call; what the code generator exports.
        steps: number of ``solve`` calls.
        failures: number of them that returned the safe action (status != SUCCESS).
    """

    def __init__(self, robot: Robot, settings: ControllerSettings):
        if settings.plugin not in PLUGINS:
            raise ValueError(f"unknown QP plugin {settings.plugin!r}; choose one of {PLUGINS}")
        self.robot, self.settings = robot, settings
        self.model = TaskModel(robot, settings.base_offset)
        self.params = ControllerParams.from_settings(robot, settings)
        self.qp = build_qp(
            self.model,
            (float(QPStatus.SUCCESS), float(QPStatus.NONFINITE_INPUT), float(QPStatus.INFEASIBLE)),
        )
        n = JOINT_COUNT
        with quiet_stdout():
            self.conic = ca.conic(
                "controller_qp",
                settings.plugin,
                {"h": ca.Sparsity.dense(n, n), "a": ca.Sparsity(0, n)},
                _conic_options(settings),
            )
        guard, certificate = _build_guard_and_certificate(settings.kkt_tol)
        state, ref = ca.MX.sym("state", STATE_SIZE), ca.MX.sym("reference", REFERENCE_SIZE)
        p = ca.MX.sym("params", PARAMS_SIZE)
        # the certificate judges the whole cost: task, regularisation and posture terms
        H, g, lbx, ubx, _, _, cost0, status = self.qp(state, ref, p)
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
        self._state, self._ref = np.zeros(STATE_SIZE), np.zeros(REFERENCE_SIZE)
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
        xi_sl, xi_dot_sl, q_sl, q_dot_sl, ground_sl = _REFERENCE_SLICES
        ref = self._ref
        if np.shape(state) != (STATE_SIZE,):
            raise _shape_error("state", state, STATE_SIZE)
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
        elif np.shape(q_ref) != (ARM_JOINTS,):
            raise _shape_error("q_ref", q_ref, ARM_JOINTS)
        else:
            ref[q_sl] = q_ref
        if q_dot_ref is None:
            ref[q_dot_sl] = 0.0
        elif np.shape(q_dot_ref) != (ARM_JOINTS,):
            raise _shape_error("q_dot_ref", q_dot_ref, ARM_JOINTS)
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
            state: [x, y, γ, θ_l, θ_r, θ_0..θ_3] (9,) [m, m, rad, rad...].
            xi_des: desired task ξ_des (6,) in M [m, m, rad, m, m, m].
            xi_dot_ref: task feed-forward ξ̇_ref (6,) [m/s, rad/s] (used if ``feedforward``);
                default zero.
            q_ref: arm posture reference (4,) [rad]; default the current arm posture (the
                posture task then only damps the arm speeds, with W_q on top of W_B).
            q_dot_ref: posture feed-forward q̇_ref (4,) [rad/s] (used if ``feedforward``);
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
        zero = np.zeros(JOINT_COUNT)
        if qp.status is not QPStatus.SUCCESS:
            return ControlResult(zero, QPStatus(qp.status), False, qp.cost0)
        with quiet_stdout() if self._quiet else contextlib.nullcontext():
            sol = self.conic(h=qp.H, g=qp.g, lbx=qp.lbx, ubx=qp.ubx)
        if not self.conic.stats()["success"]:
            return ControlResult(zero, QPStatus.SOLVER_FAILED, False, qp.cost0)
        qdot = np.asarray(sol["x"]).ravel()
        objective = 0.5 * qdot @ qp.H @ qdot + qp.g @ qdot + qp.cost0
        return ControlResult(qdot, QPStatus.SUCCESS, True, float(objective))


def build_controller(robot: Robot, settings: ControllerSettings) -> Controller:
    """Build the controller once (CasADi expressions, conic, ``step`` Function).

    Args:
        robot: the robot (joint and track speed limits, kinematics).
        settings: the ``controller:`` settings (plugin, gains, weights, dt, base offset).

    Raises:
        ValueError: an unknown plugin.
    """
    return Controller(robot, settings)
