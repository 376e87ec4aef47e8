"""Tracking controller core (paper Section II-E, Eq. 7-8; DESIGN.md §6): task Jacobian and QP.

Vectors (all in the slope frame S, DESIGN.md §2)::

    state s = [x, y, γ, θ_l, θ_r, θ_0, θ_1, θ_2, θ_3]   base pose in S [m, m, rad], joints [rad]
    q       = [θ_l, θ_r, θ_0, θ_1, θ_2, θ_3]            = s[3:9]  (sprockets, then the arm)
    ξ       = [g_bx, g_by, γ, g_ax, g_ay, g_az]          task: base control point, heading, arm CoM

The base pose is part of the state, not a function of q: the tracked base is nonholonomic
(ẋ = v cos γ, ẏ = v sin γ, γ̇ = ω, v = r(θ̇_l+θ̇_r)/2, ω = r(θ̇_r−θ̇_l)/b), so
ξ̇ = J(s) q̇ with J = [∂ξ/∂pose · B(γ) | ∂ξ/∂q_arm], B the 3x2 track-to-pose-rate map, and
g_a^S = [x, y, 0] + Rz(γ) g_a^B(q_arm).

**Base control point.** ξ's first two rows are the paper's g_b, taken as the point a distance
d = ``base_offset`` [m] ahead of the body origin: g_b = [x, y] + d [cos γ, sin γ] (d = 0 is the
body origin, the centre of the track contact rectangle). Default d = 0.2 m with a small heading
weight (W_A[2] = 0.01): for d = 0 the base rows of J have rank 1 in position, so a lateral
error has no instantaneous correction and decays only through the heading on a curved path,
with time constant K_p/ω_ref² (≈ 110 s on the default lap: a 0.1 m offset is still 0.08 m
after one lap); for d > 0 the block [[cos γ, −d sin γ], [sin γ, d cos γ]] is invertible, so
the point's error is corrected directly (the usual look-ahead point of differential-drive tracking;
the same 0.1 m offset is under 1 mm after 5 s) and the light heading row only keeps the body
aligned where the point's motion leaves it free. The reference must use the same d
(:func:`mmstab.reference.base_reference`). Whatever d, J has rank 5 (three base rows, two
sprockets): a moving, consistent reference with feed-forward (the circle) is tracked to zero
error, but a *constant* target is reached only up to an error in J's left null space
(Jᵀ W_A e = 0; no smooth static feedback stabilises a nonholonomic pose, Brockett 1983).

**QP (Eq. 7-8).** ξ̇_des = K_p (ξ_des − ξ) + f ξ̇_ref with the heading error wrapped to (−π, π]
and f ∈ {0, 1} the feed-forward switch; then, with H = Jᵀ W_A J + W_B and g = −Jᵀ W_A ξ̇_des::

    min ½ q̇ᵀ H q̇ + gᵀ q̇    s.t.  max(−q̇_max, (q_min − q)/dt) ≤ q̇ ≤ min(q̇_max, (q_max − q)/dt)

(position bounds on the arm joints only; the sprockets turn freely). W_B > 0, so the QP is
strictly convex and every plugin must return the same q̇.

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

STATE_SIZE, JOINT_COUNT, TASK_SIZE = 9, 6, 6
REFERENCE_SIZE = 2 * TASK_SIZE  # [ξ_des, ξ̇_ref]
POSE, JOINTS, ARM = slice(0, 3), slice(3, 9), slice(5, 9)
PLUGINS = ("qpoases", "osqp", "qrqp", "daqp")
#: Plugins CasADi can generate C for (qpOASES emits ``#error``).
CODEGEN_PLUGINS = ("qrqp", "daqp", "osqp")
_SINC_SERIES_BELOW = 1e-4  # |ω dt / 2| under which sin(a)/a uses its series [rad]


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
        plugin: QP plugin, one of :data:`PLUGINS`.
        feedforward: add ξ̇_ref to ξ̇_des.
        base_offset: base control point ahead of the body origin d [m].
        kkt_tol: tolerance of the in-graph solution certificate [rad/s].
        osqp: OSQP options.
    """

    dt: float
    lap_time: float
    duration: float
    kp: tuple[float, ...]
    w_a: tuple[float, ...]
    w_b: tuple[float, ...]
    plugin: str
    feedforward: bool
    base_offset: float
    kkt_tol: float
    osqp: OsqpSettings

    @classmethod
    def from_section(cls, section: Mapping[str, Any]) -> ControllerSettings:
        """Build from a validated ``controller:`` section."""
        vecs = {k: tuple(float(v) for v in section[k]) for k in ("kp", "w_a", "w_b")}
        o = section["osqp"]
        return cls(
            dt=float(section["dt"]),
            lap_time=float(section["lap_time"]),
            duration=float(section["duration"]),
            plugin=str(section["plugin"]),
            feedforward=bool(section["feedforward"]),
            base_offset=float(section["base_offset"]),
            kkt_tol=float(section["kkt_tol"]),
            osqp=OsqpSettings(
                float(o["eps_abs"]), float(o["eps_rel"]), int(o["max_iter"]), bool(o["polish"])
            ),
            **vecs,
        )


def check_settings(path: Path, section: Mapping[str, Any]) -> None:
    """Semantic checks of the ``controller:`` section beyond its schema.

    Raises:
        ConfigError: naming the field (``controller.duration``, ``controller.kp``).
    """
    dt = float(section["dt"])
    if float(section["duration"]) < dt:
        raise ConfigError(path, "controller.duration", f"must be at least dt = {dt} s")
    if max(section["kp"]) * dt >= 1.0:
        raise ConfigError(
            path,
            "controller.kp",
            f"kp * dt must stay below 1 (the discrete loop overshoots); dt = {dt} s",
        )


class ControllerParams(NamedTuple):
    """Run-time parameters of the ``step`` Function, packed in this order (34 numbers).

    Attributes:
        kp: gains (6,) [1/s].
        w_a: task weights (6,).
        w_b: joint-velocity weights (6,).
        feedforward: 1.0 to add ξ̇_ref, 0.0 not to.
        dt: control period [s].
        qdot_max: joint speed limits (6,) [rad/s] (sprockets, then arm).
        q_min: arm joint lower limits (4,) [rad].
        q_max: arm joint upper limits (4,) [rad].
    """

    kp: Any
    w_a: Any
    w_b: Any
    feedforward: Any
    dt: Any
    qdot_max: Any
    q_min: Any
    q_max: Any

    @classmethod
    def sizes(cls) -> tuple[int, ...]:
        """Length of each field in the packed vector."""
        return (6, 6, 6, 1, 1, 6, 4, 4)

    @classmethod
    def from_settings(cls, robot: Robot, settings: ControllerSettings) -> ControllerParams:
        """Parameters from the settings and the robot's joint limits."""
        return cls(
            kp=np.array(settings.kp),
            w_a=np.array(settings.w_a),
            w_b=np.array(settings.w_b),
            feedforward=float(settings.feedforward),
            dt=settings.dt,
            qdot_max=np.r_[np.full(2, robot.base.tracks.velocity_limit), robot.joint_velocity],
            q_min=robot.joint_lower,
            q_max=robot.joint_upper,
        )

    def pack(self) -> FloatArray:
        """The packed parameter vector (34,)."""
        return np.concatenate([np.atleast_1d(np.asarray(v, dtype=float)) for v in self])

    @classmethod
    def unpack(cls, p: Any) -> ControllerParams:
        """Split a packed vector (NumPy or CasADi) into fields."""
        edges = np.cumsum((0, *cls.sizes()))
        return cls(*(p[int(a) : int(b)] for a, b in zip(edges[:-1], edges[1:], strict=True)))


# --------------------------------------------------------------------------- task kinematics
class TaskModel:
    """Task ξ(s), Jacobian J(s) and base + joint motion of one robot (CasADi and NumPy).

    Attributes:
        base_offset: base control point ahead of the body origin [m].
        state: the symbolic state (9,) SX.
        xi: ξ(state) (6,) SX [m, m, rad, m, m, m].
        J: the task Jacobian (6x6) SX: ξ̇ = J q̇.
        f_task: ``Function`` state -> xi.
        f_jacobian: ``Function`` state -> J.
        f_integrate: ``Function`` (state, qdot [rad/s], dt [s]) -> state after dt.
    """

    def __init__(self, robot: Robot, base_offset: float):
        self.base_offset = float(base_offset)
        tracks = robot.base.tracks
        r, b = tracks.sprocket_radius, tracks.separation
        s = self.state = ca.SX.sym("state", STATE_SIZE)
        x, y, heading = s[0], s[1], s[2]
        c, sn = ca.cos(heading), ca.sin(heading)
        com_B = robot.kinematics.f_arm_com(s[ARM])  # g_a^B(q_arm), inlined as SX
        self.xi = ca.vertcat(
            x + self.base_offset * c,
            y + self.base_offset * sn,
            heading,
            x + c * com_B[0] - sn * com_B[1],
            y + sn * com_B[0] + c * com_B[1],
            com_B[2],
        )
        # pose rate = B(γ) [θ̇_l, θ̇_r]: the nonholonomic track kinematics
        B = ca.vertcat(
            ca.horzcat(r / 2 * c, r / 2 * c),
            ca.horzcat(r / 2 * sn, r / 2 * sn),
            ca.horzcat(-r / b, r / b),
        )
        self.J = ca.horzcat(ca.jacobian(self.xi, s[POSE]) @ B, ca.jacobian(self.xi, s[ARM]))
        self.f_task = ca.Function("task", [s], [self.xi], ["state"], ["xi"])
        self.f_jacobian = ca.Function("task_jacobian", [s], [self.J], ["state"], ["J"])

        # Exact motion over dt for constant q̇: the base drives an arc (chord along mid-heading).
        qdot, dt = ca.SX.sym("qdot", JOINT_COUNT), ca.SX.sym("dt")
        v, w = r * (qdot[0] + qdot[1]) / 2, r * (qdot[1] - qdot[0]) / b
        half = w * dt / 2
        small = ca.fabs(half) < _SINC_SERIES_BELOW
        safe = ca.if_else(small, 1.0, half)
        sinc = ca.if_else(small, 1 - half**2 / 6, ca.sin(safe) / safe)
        chord, mid = v * dt * sinc, heading + half
        nxt = ca.vertcat(x + chord * ca.cos(mid), y + chord * ca.sin(mid), heading + w * dt)
        nxt = ca.vertcat(nxt, s[JOINTS] + qdot * dt)
        self.f_integrate = ca.Function(
            "integrate", [s, qdot, dt], [nxt], ["state", "qdot", "dt"], ["state_next"]
        )

    def task(self, state: ArrayLike) -> FloatArray:
        """ξ at a state (9,) -> (6,) [m, m, rad, m, m, m]."""
        return np.asarray(self.f_task(np.asarray(state, dtype=float))).ravel()

    def jacobian(self, state: ArrayLike) -> FloatArray:
        """J at a state (9,) -> (6, 6) [m/rad, rad/rad]."""
        return np.asarray(self.f_jacobian(np.asarray(state, dtype=float)))

    def integrate(self, state: ArrayLike, qdot: ArrayLike, dt: float) -> FloatArray:
        """State after ``dt`` [s] at constant joint speeds ``qdot`` (6,) [rad/s] (exact arc)."""
        out = self.f_integrate(np.asarray(state, dtype=float), np.asarray(qdot, dtype=float), dt)
        return np.asarray(out).ravel()


# ---------------------------------------------------------------------------------------- QP
class QPData(NamedTuple):
    """The QP of one step: min ½ q̇ᵀHq̇ + gᵀq̇ + cost0 s.t. lbx ≤ q̇ ≤ ubx; pre-solve status."""

    H: FloatArray
    g: FloatArray
    lbx: FloatArray
    ubx: FloatArray
    xi_dot_des: FloatArray
    cost0: float
    status: QPStatus


class ControlResult(NamedTuple):
    """One step's answer: joint speeds (6,) [rad/s], status, success, Eq. 7 cost at ``qdot``."""

    qdot: FloatArray
    status: QPStatus
    success: bool
    objective: float


def _all(x: ca.SX) -> ca.SX:
    return ca.mmin(x) if x.numel() else ca.SX(1)


def _finite(x: ca.SX) -> ca.SX:
    return _all(ca.fabs(x) < ca.inf)  # NaN compares false


def _build_qp(model: TaskModel) -> ca.Function:
    """SX Function (state, reference, params) -> the QP's matrices and the pre-solve status."""
    s = model.state
    ref, p = (
        ca.SX.sym("reference", REFERENCE_SIZE),
        ca.SX.sym("params", sum(ControllerParams.sizes())),
    )
    P = ControllerParams.unpack(p)
    e = ref[:TASK_SIZE] - model.xi
    e[2] = ca.atan2(ca.sin(e[2]), ca.cos(e[2]))  # heading error in (−π, π]
    xi_dot_des = P.kp * e + P.feedforward * ref[TASK_SIZE:]
    JtW = model.J.T @ ca.diag(P.w_a)
    H = JtW @ model.J + ca.diag(P.w_b)
    g = -JtW @ xi_dot_des
    q_arm = s[ARM]
    lbx = ca.vertcat(-P.qdot_max[:2], ca.fmax(-P.qdot_max[2:], (P.q_min - q_arm) / P.dt))
    ubx = ca.vertcat(P.qdot_max[:2], ca.fmin(P.qdot_max[2:], (P.q_max - q_arm) / P.dt))
    cost0 = 0.5 * ca.dot(xi_dot_des, P.w_a * xi_dot_des)
    finite = _finite(ca.vertcat(s, ref, p, ca.vec(H), g))
    status = ca.if_else(
        finite,
        ca.if_else(_all(lbx <= ubx), float(QPStatus.SUCCESS), float(QPStatus.INFEASIBLE)),
        float(QPStatus.NONFINITE_INPUT),
    )
    return ca.Function(
        "qp",
        [s, ref, p],
        [H, g, lbx, ubx, xi_dot_des, cost0, status],
        ["state", "reference", "params"],
        ["H", "g", "lbx", "ubx", "xi_dot_des", "cost0", "status"],
    )


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
    certified = ca.logic_and(_finite(x), violation <= kkt_tol)
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
        qp: ``Function`` (state, reference, params) -> (H, g, lbx, ubx, xi_dot_des, cost0,
            status): the QP's matrices, for inspection and tests.
        conic: the CasADi ``conic`` (dense H, no linear constraints).
        step: ``Function`` (state (9), reference (12) = [ξ_des, ξ̇_ref], params (34)) ->
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
        self.qp = _build_qp(self.model)
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
        p = ca.MX.sym("params", sum(ControllerParams.sizes()))
        H, g, lbx, ubx, _, cost0, status = self.qp(state, ref, p)
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

    def _load(self, state: ArrayLike, xi_des: ArrayLike, xi_dot_ref: ArrayLike | None) -> None:
        for name, value, n in (("state", state, STATE_SIZE), ("xi_des", xi_des, TASK_SIZE)):
            if np.shape(value) != (n,):
                raise ValueError(f"{name} must have shape ({n},), got {np.shape(value)}")
        self._state[:] = state
        self._ref[:TASK_SIZE] = xi_des
        if xi_dot_ref is None:
            self._ref[TASK_SIZE:] = 0.0
        elif np.shape(xi_dot_ref) != (TASK_SIZE,):
            raise ValueError(
                f"xi_dot_ref must have shape ({TASK_SIZE},), got {np.shape(xi_dot_ref)}"
            )
        else:
            self._ref[TASK_SIZE:] = xi_dot_ref

    def solve(
        self, state: ArrayLike, xi_des: ArrayLike, xi_dot_ref: ArrayLike | None = None
    ) -> ControlResult:
        """One control step: joint speeds for the current state and reference.

        Args:
            state: [x, y, γ, θ_l, θ_r, θ_0..θ_3] (9,) [m, m, rad, rad...].
            xi_des: desired task ξ_des (6,) in S [m, m, rad, m, m, m].
            xi_dot_ref: task feed-forward ξ̇_ref (6,) [m/s, rad/s] (used if ``feedforward``).

        Returns:
            The result; on failure ``qdot`` is zero (hold still) and ``failures`` counts it.
        """
        self._load(state, xi_des, xi_dot_ref)
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
        self, state: ArrayLike, xi_des: ArrayLike, xi_dot_ref: ArrayLike | None = None
    ) -> QPData:
        """The QP one step would solve (arguments as :meth:`solve`)."""
        self._load(state, xi_des, xi_dot_ref)
        H, g, lbx, ubx, xdd, cost0, status = (
            np.asarray(v) for v in self.qp(self._state, self._ref, self._p)
        )
        vec = (g.ravel(), lbx.ravel(), ubx.ravel(), xdd.ravel())
        return QPData(H, *vec, cost0.item(), QPStatus(int(status.item())))

    def solve_direct(
        self, state: ArrayLike, xi_des: ArrayLike, xi_dot_ref: ArrayLike | None = None
    ) -> ControlResult:
        """The same step judged by the plugin's own status (``stats()['success']``); slow.

        For cross-checking :meth:`solve`'s in-graph certificate; does not count steps.
        """
        qp = self.qp_data(state, xi_des, xi_dot_ref)
        zero = np.zeros(JOINT_COUNT)
        if qp.status is not QPStatus.SUCCESS:
            return ControlResult(zero, qp.status, False, qp.cost0)
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
