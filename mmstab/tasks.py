"""Task model and QP assembly of the tracking controller (paper Eq. 7-8 + a posture task).

Vectors (all in the terrain's map frame M, ``docs/design.md``, "Frames")::

    state s = [x, y, γ, θ_l, θ_r, θ_0, θ_1, θ_2, θ_3]   base pose in M [m, m, rad], joints [rad]
    q       = [θ_l, θ_r, θ_0, θ_1, θ_2, θ_3]            = s[3:9]  (sprockets, then the arm)
    ξ       = [g_bx, g_by, γ, g_ax, g_ay, g_az]          task: base control point, heading, arm CoM
    ground  = [z, roll, pitch]                           local ground of the pose (reference)

The base pose is part of the state, not a function of q: the tracked base is nonholonomic
(ẋ = v cos γ, ẏ = v sin γ, γ̇ = ω, v = r(θ̇_l+θ̇_r)/2, ω = r(θ̇_r−θ̇_l)/b), so
ξ̇ = J(s) q̇ with J = [∂ξ/∂pose · B(γ) | ∂ξ/∂q_arm], B the 3x2 track-to-pose-rate map. Both
points of ξ are placed by the one placement of the terrain package,
:func:`mmstab.terrain.place_local_sx` (``M_T_B p`` with the local ground as data, so the
step does not depend on which terrain it runs on; ``docs/controller-terrain.md``):
g_a^M = place(pose, ground, g_a^B(q_arm)), and the base control point ``base_offset`` d ahead
of the body origin, g_b = place(pose, ground, [d, 0, 0])[:2] (on the ramp [x, y] + d [cos γ,
sin γ]; see :mod:`mmstab.controller`).

**QP.** Eq. 7 with a posture task on the arm joints: the CoM rows have 3 rows for 4 arm
joints, so one arm direction is free; the posture task holds it near the planner's
collision-free postures q_ref (as pink's and mink's ``PostureTask``)::

    ξ̇_des  = K_p (ξ_des − ξ) + f ξ̇_ref                   (heading error wrapped to (−π, π])
    q̇_post = K_q (q_ref − q_arm) + f q̇_ref               (no wrap: q_ref is in limit coordinates)
    min ½‖ξ̇_des − J q̇‖²_{W_A} + ½‖q̇‖²_{W_B} + ½‖q̇_arm − q̇_post‖²_{W_q}
    s.t. max(−q̇_max, (q_min − q)/dt) ≤ q̇ ≤ min(q̇_max, (q_max − q)/dt)   (arm joints)

so H = Jᵀ W_A J + W_B + Sᵀ W_q S and g = −Jᵀ W_A ξ̇_des − Sᵀ W_q q̇_post (S selects the arm
columns of q̇), f ∈ {0, 1} the feed-forward switch. W_B > 0: strictly convex.

**Layouts.** The step's run-time inputs are two packed vectors: :class:`StepReference`
(``reference``, 23 numbers: ξ_des, ξ̇_ref, q_ref, q̇_ref, local ground) and :class:`ControllerParams`
(``params``, 42 numbers: gains, weights, dt, limits). Both classes give their sizes, ``pack``
and ``unpack``; the code generator writes the same layouts into a C header.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from mmstab.robot import FloatArray, Robot
from mmstab.terrain import GROUND_SIZE, place_local_sx

STATE_SIZE, JOINT_COUNT, TASK_SIZE, ARM_JOINTS = 9, 6, 6, 4
POSE, JOINTS, ARM = slice(0, 3), slice(3, 9), slice(5, 9)
TRACK_DATA_SIZE = 3  # [sprocket radius, track separation, series threshold] (motion in C)
_SINC_SERIES_BELOW = 1e-4  # |ω dt / 2| under which sin(a)/a uses its series [rad]


_OFFSETS: dict[str, dict[str, slice]] = {}  # per layout class, computed once


def _offsets(cls: Any) -> dict[str, slice]:
    if cls.__name__ not in _OFFSETS:
        edges = np.cumsum((0, *cls.sizes()))
        _OFFSETS[cls.__name__] = {
            name: slice(int(a), int(b))
            for name, a, b in zip(cls._fields, edges[:-1], edges[1:], strict=True)
        }
    return _OFFSETS[cls.__name__]


def _pack(values: tuple[Any, ...], rows: int | None) -> FloatArray:
    if rows is None:
        return np.concatenate([np.atleast_1d(np.asarray(v, dtype=float)) for v in values])
    cols = [np.asarray(v, dtype=float).reshape(rows, -1) for v in values]
    return np.ascontiguousarray(np.hstack(cols))


def _unpack(cls: Any, p: Any) -> Any:
    """Split a packed vector (NumPy (n,) or (N, n) on the last axis, or a CasADi column)."""
    parts = _offsets(cls).values()
    if isinstance(p, np.ndarray):
        return cls(*(p[..., sl] for sl in parts))
    return cls(*(p[sl.start : sl.stop] for sl in parts))


class ControllerParams(NamedTuple):
    """Run-time parameters of the ``step`` Function, packed in this order (42 numbers).

    Attributes:
        kp: task gains K_p (6,) [1/s].
        w_a: task weights W_A (6,).
        w_b: joint-velocity weights W_B (6,).
        posture_gain: posture gains K_q (4,) [1/s], one per arm joint.
        posture_weight: posture weights W_q (4,), one per arm joint.
        feedforward: 1.0 to add ξ̇_ref and q̇_ref, 0.0 not to.
        dt: control period [s].
        qdot_max: joint speed limits (6,) [rad/s] (sprockets, then arm).
        q_min: arm joint lower limits (4,) [rad].
        q_max: arm joint upper limits (4,) [rad].
    """

    kp: Any
    w_a: Any
    w_b: Any
    posture_gain: Any
    posture_weight: Any
    feedforward: Any
    dt: Any
    qdot_max: Any
    q_min: Any
    q_max: Any

    @classmethod
    def sizes(cls) -> tuple[int, ...]:
        """Length of each field in the packed vector."""
        t, n, a = TASK_SIZE, JOINT_COUNT, ARM_JOINTS
        return (t, t, n, a, a, 1, 1, n, a, a)

    @classmethod
    def size(cls) -> int:
        """Length of the packed vector."""
        return sum(cls.sizes())

    @classmethod
    def offsets(cls) -> dict[str, slice]:
        """Each field's slice in the packed vector."""
        return dict(_offsets(cls))

    @classmethod
    def from_settings(cls, robot: Robot, settings: Any) -> ControllerParams:
        """Parameters from :class:`~mmstab.controller.ControllerSettings` and the joint limits."""
        return cls(
            kp=np.array(settings.kp),
            w_a=np.array(settings.w_a),
            w_b=np.array(settings.w_b),
            posture_gain=np.array(settings.posture_gain),
            posture_weight=np.array(settings.posture_weight),
            feedforward=float(settings.feedforward),
            dt=settings.dt,
            qdot_max=np.r_[np.full(2, robot.base.tracks.velocity_limit), robot.joint_velocity],
            q_min=robot.joint_lower,
            q_max=robot.joint_upper,
        )

    def pack(self) -> FloatArray:
        """The packed parameter vector (42,)."""
        return _pack(tuple(self), None)

    @classmethod
    def unpack(cls, p: Any) -> ControllerParams:
        """Split a packed vector (NumPy or CasADi) into fields."""
        return _unpack(cls, p)


class StepReference(NamedTuple):
    """The controller's reference at one step (or N steps), packed in this order (23 numbers).

    Attributes:
        xi_des: task reference ξ_des (6,) in M [m, m, rad, m, m, m].
        xi_dot_ref: its rate ξ̇_ref (6,) [m/s, rad/s] (feed-forward).
        q_ref: arm posture reference (4,) [rad], within the joint limits.
        q_dot_ref: its rate (4,) [rad/s] (feed-forward).
        ground: local ground (z [m], roll [rad], pitch [rad]) of the reference pose
            (:meth:`mmstab.terrain.Terrain.local_ground`; zero on the ramp): the task map
            places body points with it.
    """

    xi_des: Any
    xi_dot_ref: Any
    q_ref: Any
    q_dot_ref: Any
    ground: Any

    @classmethod
    def sizes(cls) -> tuple[int, ...]:
        """Length of each field in the packed vector."""
        return (TASK_SIZE, TASK_SIZE, ARM_JOINTS, ARM_JOINTS, GROUND_SIZE)

    @classmethod
    def size(cls) -> int:
        """Length of the packed vector."""
        return sum(cls.sizes())

    @classmethod
    def offsets(cls) -> dict[str, slice]:
        """Each field's slice in the packed vector."""
        return dict(_offsets(cls))

    def pack(self) -> FloatArray:
        """The packed reference: (23,) for one step, (N, 23) if the fields are (N, ·)."""
        rows = None if np.ndim(self.xi_des) == 1 else int(np.shape(self.xi_des)[0])
        return _pack(tuple(self), rows)

    @classmethod
    def unpack(cls, r: Any) -> StepReference:
        """Split a packed reference ((23,) or (N, 23) NumPy, or a CasADi column)."""
        return _unpack(cls, r)


REFERENCE_SIZE = StepReference.size()
PARAMS_SIZE = ControllerParams.size()


# --------------------------------------------------------------------------- task kinematics
class TaskModel:
    """Task ξ(s), Jacobian J(s) and base + joint motion of one robot (CasADi and NumPy).

    Attributes:
        robot: the robot.
        base_offset: base control point ahead of the body origin [m].
        state: the symbolic state (9,) SX.
        ground: the symbolic local ground (3,) SX [m, rad, rad].
        xi: ξ(state, ground) (6,) SX [m, m, rad, m, m, m].
        J: the task Jacobian (6x6) SX: ξ̇ = J q̇ (the ground held constant).
        f_task: ``Function`` (state, ground) -> xi.
        f_jacobian: ``Function`` (state, ground) -> J.
        f_integrate: ``Function`` (state, qdot [rad/s], dt [s]) -> state after dt.
    """

    def __init__(self, robot: Robot, base_offset: float):
        self.robot = robot
        self.base_offset = float(base_offset)
        tracks = robot.base.tracks
        r, b = tracks.sprocket_radius, tracks.separation
        s = self.state = ca.SX.sym("state", STATE_SIZE)
        ground = self.ground = ca.SX.sym("ground", GROUND_SIZE)
        x, y, heading = s[0], s[1], s[2]
        c, sn = ca.cos(heading), ca.sin(heading)
        com_B = robot.kinematics.f_arm_com(s[ARM])  # g_a^B(q_arm), inlined as SX
        point_M = place_local_sx(s[POSE], ground, ca.vertcat(self.base_offset, 0, 0))
        self.xi = ca.vertcat(point_M[:2], heading, place_local_sx(s[POSE], ground, com_B))
        # pose rate = B(γ) [θ̇_l, θ̇_r]: the nonholonomic track kinematics
        B = ca.vertcat(
            ca.horzcat(r / 2 * c, r / 2 * c),
            ca.horzcat(r / 2 * sn, r / 2 * sn),
            ca.horzcat(-r / b, r / b),
        )
        self.J = ca.horzcat(ca.jacobian(self.xi, s[POSE]) @ B, ca.jacobian(self.xi, s[ARM]))
        names = ["state", "ground"]
        self.f_task = ca.Function("task", [s, ground], [self.xi], names, ["xi"])
        self.f_jacobian = ca.Function("task_jacobian", [s, ground], [self.J], names, ["J"])

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

    def task(self, state: ArrayLike, ground: ArrayLike = (0.0, 0.0, 0.0)) -> FloatArray:
        """ξ at a state (9,) and local ground (3,) -> (6,) [m, m, rad, m, m, m]."""
        return np.asarray(self.f_task(np.asarray(state, float), np.asarray(ground, float))).ravel()

    def task_batch(self, states: ArrayLike, ground: ArrayLike) -> FloatArray:
        """ξ for many states (N, 9) and their local ground (N, 3) -> (N, 6) (one mapped call)."""
        s = np.atleast_2d(np.asarray(states, dtype=float))
        g = np.broadcast_to(np.asarray(ground, dtype=float), (len(s), GROUND_SIZE))
        return np.asarray(self.f_task.map(len(s))(s.T, g.T)).T

    def jacobian(self, state: ArrayLike, ground: ArrayLike = (0.0, 0.0, 0.0)) -> FloatArray:
        """J at a state (9,) and local ground (3,) -> (6, 6) [m/rad, rad/rad]."""
        return np.asarray(self.f_jacobian(np.asarray(state, float), np.asarray(ground, float)))

    def integrate(self, state: ArrayLike, qdot: ArrayLike, dt: float) -> FloatArray:
        """State after ``dt`` [s] at constant joint speeds ``qdot`` (6,) [rad/s] (exact arc)."""
        out = self.f_integrate(np.asarray(state, dtype=float), np.asarray(qdot, dtype=float), dt)
        return np.asarray(out).ravel()


# ---------------------------------------------------------------------------------------- QP
class QPData(NamedTuple):
    """The QP of one step: min ½ q̇ᵀHq̇ + gᵀq̇ + cost0 s.t. lbx ≤ q̇ ≤ ubx; pre-solve status.

    Attributes:
        H: Hessian (6, 6).
        g: gradient (6,).
        lbx: lower bounds on q̇ (6,) [rad/s].
        ubx: upper bounds on q̇ (6,) [rad/s].
        xi_dot_des: the task rate asked for ξ̇_des (6,) [m/s, rad/s].
        q_dot_posture: the arm joint rates the posture task asks for q̇_post (4,) [rad/s].
        cost0: the constant of the cost (its value at q̇ = 0).
        status: the pre-solve status (:class:`~mmstab.controller.QPStatus` value).
    """

    H: FloatArray
    g: FloatArray
    lbx: FloatArray
    ubx: FloatArray
    xi_dot_des: FloatArray
    q_dot_posture: FloatArray
    cost0: float
    status: int


def all_true(x: ca.SX) -> ca.SX:
    """1 if every element of ``x`` is nonzero (1 for an empty ``x``)."""
    return ca.mmin(x) if x.numel() else ca.SX(1)


def all_finite(x: ca.SX) -> ca.SX:
    """1 if every element of ``x`` is finite (NaN compares false)."""
    return all_true(ca.fabs(x) < ca.inf)


def build_qp(model: TaskModel, statuses: tuple[float, float, float]) -> ca.Function:
    """SX Function (state, reference, params) -> the QP's matrices and the pre-solve status.

    Args:
        model: the task kinematics.
        statuses: the status values for (success, non-finite input, infeasible bounds).

    Returns:
        ``qp`` (state (9), reference (23), params (42)) -> (H, g, lbx, ubx, xi_dot_des,
        q_dot_posture, cost0, status); see the module docstring for the formulas.
    """
    success, nonfinite, infeasible = statuses
    s = model.state
    ref, p = ca.SX.sym("reference", REFERENCE_SIZE), ca.SX.sym("params", PARAMS_SIZE)
    P, R = ControllerParams.unpack(p), StepReference.unpack(ref)
    q_arm = s[ARM]
    xi, J = model.f_task(s, R.ground), model.f_jacobian(s, R.ground)
    e = R.xi_des - xi
    e[2] = ca.atan2(ca.sin(e[2]), ca.cos(e[2]))  # heading error in (−π, π]
    xi_dot_des = P.kp * e + P.feedforward * R.xi_dot_ref
    q_dot_post = P.posture_gain * (R.q_ref - q_arm) + P.feedforward * R.q_dot_ref
    JtW = J.T @ ca.diag(P.w_a)
    w_q = ca.vertcat(ca.SX.zeros(JOINT_COUNT - ARM_JOINTS), P.posture_weight)
    H = JtW @ J + ca.diag(P.w_b + w_q)
    g = -JtW @ xi_dot_des - ca.vertcat(ca.SX.zeros(2), P.posture_weight * q_dot_post)
    lbx = ca.vertcat(-P.qdot_max[:2], ca.fmax(-P.qdot_max[2:], (P.q_min - q_arm) / P.dt))
    ubx = ca.vertcat(P.qdot_max[:2], ca.fmin(P.qdot_max[2:], (P.q_max - q_arm) / P.dt))
    cost0 = 0.5 * ca.dot(xi_dot_des, P.w_a * xi_dot_des)
    cost0 += 0.5 * ca.dot(q_dot_post, P.posture_weight * q_dot_post)
    finite = all_finite(ca.vertcat(s, ref, p, ca.vec(H), g))
    status = ca.if_else(finite, ca.if_else(all_true(lbx <= ubx), success, infeasible), nonfinite)
    return ca.Function(
        "qp",
        [s, ref, p],
        [H, g, lbx, ubx, xi_dot_des, q_dot_post, cost0, status],
        ["state", "reference", "params"],
        ["H", "g", "lbx", "ubx", "xi_dot_des", "q_dot_posture", "cost0", "status"],
    )
