"""The controller's memory layout: state, reference and parameter vectors (and their C header).

The step's run-time inputs are three packed vectors, the same in Python, CasADi and C::

    state     (9)   [x, y, γ, θ_l, θ_r, θ_0..θ_3]: base pose in the map frame M, then the joints
    reference (23)  :class:`StepReference`: ξ_des, ξ̇_ref, q_ref, q̇_ref, local ground
    params    (42)  :class:`ControllerParams`: gains, weights, dt, limits

Each layout class gives its sizes, ``offsets``, ``pack`` and ``unpack``; :func:`layout_header`
writes the same sizes and offsets as C macros (``controller_layout.h``, generated with the
step so the embedded example never repeats them by hand).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from mmstab.model.robot import FloatArray, Robot
from mmstab.terrain import GROUND_SIZE

STATE_SIZE, JOINT_COUNT, TASK_SIZE, ARM_JOINTS = 9, 6, 6, 4
POSE, JOINTS, ARM = slice(0, 3), slice(3, 9), slice(5, 9)


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
        """Parameters from the controller settings and the joint limits (``ControllerSettings``)."""
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


def layout_header(kkt_tol: float | None = None) -> str:
    """``controller_layout.h``: the step's argument sizes and packed layouts as C macros.

    ``MMSTAB_N_*`` sizes (state, joints, task, arm joints, reference, params, local ground),
    then the offset of each field of the reference (``MMSTAB_REF_*``) and of the parameters
    (``MMSTAB_PARAM_*``), from :class:`StepReference` and :class:`ControllerParams`.

    Args:
        kkt_tol: the certificate's tolerance [rad/s], written as ``MMSTAB_KKT_TOL`` (the
            embedded example checks every step's KKT conditions with it); None: not written.
    """
    sizes = {
        "STATE": STATE_SIZE,
        "JOINTS": JOINT_COUNT,
        "TASK": TASK_SIZE,
        "ARM": ARM_JOINTS,
        "REFERENCE": REFERENCE_SIZE,
        "PARAMS": PARAMS_SIZE,
        "GROUND": GROUND_SIZE,
    }
    lines = [
        "/* Sizes and layouts of controller_step's arguments (mmstab.control.layout.layout_header,",
        " * from StepReference and ControllerParams). Generated: do not edit. */",
        "#ifndef MMSTAB_CONTROLLER_LAYOUT_H",
        "#define MMSTAB_CONTROLLER_LAYOUT_H",
        "",
        *(f"#define MMSTAB_N_{name} {n}" for name, n in sizes.items()),
        "",
        "/* reference (StepReference): offset of each field */",
        *(f"#define MMSTAB_REF_{k.upper()} {v.start}" for k, v in StepReference.offsets().items()),
        "",
        "/* params (ControllerParams): offset of each field */",
        *(
            f"#define MMSTAB_PARAM_{k.upper()} {v.start}"
            for k, v in ControllerParams.offsets().items()
        ),
        "",
        *(
            ["/* the step's certificate tolerance [rad/s] (controller.kkt_tol) */"]
            + [f"#define MMSTAB_KKT_TOL {kkt_tol!r}", ""]
            if kkt_tol is not None
            else []
        ),
        "#endif /* MMSTAB_CONTROLLER_LAYOUT_H */",
        "",
    ]
    return "\n".join(lines)
