"""The controller's memory layout: state, reference and parameter vectors (and their C header).

The step's run-time inputs are three packed vectors, the same in Python, CasADi and C; their
sizes follow the arm's joint count n (``len(robot.links)``, the robot file's ``arm.links``;
the numbers are for the 4-DoF arm)::

    state     (5 + n = 9)     [x, y, γ, θ_l, θ_r, θ_0..θ_{n-1}]: base pose in M, then joints
    reference (15 + 2n = 23)  :class:`StepReference`: ξ_des, ξ̇_ref, q_ref, q̇_ref, ground
    params    (18 + 6n = 42)  :class:`ControllerParams`: gains, weights, dt, limits

:class:`Layout` gives the sizes for an arm (``Layout.of(robot)``); the module's constants
(``STATE_SIZE``, ``REFERENCE_SIZE``, ...) are those of the 4-DoF arm. ``unpack`` reads the arm's
joint count from the packed vector's length.

Each layout class gives its sizes, ``offsets``, ``pack`` and ``unpack``; :func:`layout_header`
writes the same sizes and offsets as C macros (``controller_layout.h``, generated with the
step so the embedded example never repeats them by hand).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np

from mmstab.model.robot import FloatArray, Robot
from mmstab.terrain import GROUND_SIZE

#: Sizes of the 4-DoF arm's layout: state, joints (sprockets + arm), task ξ, arm joints.
STATE_SIZE, JOINT_COUNT, TASK_SIZE, ARM_JOINTS = 9, 6, 6, 4
#: Where the base pose, the joints and the arm joints sit in the state (any arm: open-ended).
POSE, JOINTS, ARM = slice(0, 3), slice(3, None), slice(5, None)
#: The state's numbers before the arm joints: base pose (3) and the two sprockets.
BASE_STATE, SPROCKETS = 5, 2


_OFFSETS: dict[tuple[str, int], dict[str, slice]] = {}  # per layout class and arm, computed once


def _offsets(cls: Any, arm: int) -> dict[str, slice]:
    if (cls.__name__, arm) not in _OFFSETS:
        edges = np.cumsum((0, *cls.sizes(arm)))
        _OFFSETS[cls.__name__, arm] = {
            name: slice(int(a), int(b))
            for name, a, b in zip(cls._fields, edges[:-1], edges[1:], strict=True)
        }
    return _OFFSETS[cls.__name__, arm]


def _arm_of(cls: Any, n: int) -> int:
    """The arm's joint count whose packed ``cls`` vector has length ``n``."""
    fixed, per_joint = sum(cls.sizes(0)), sum(cls.sizes(1)) - sum(cls.sizes(0))
    arm, rest = divmod(n - fixed, per_joint)
    if rest or arm < 1:
        raise ValueError(f"{cls.__name__}: a packed vector of {n} numbers fits no arm")
    return int(arm)


def _pack(values: tuple[Any, ...], rows: int | None) -> FloatArray:
    if rows is None:
        return np.concatenate([np.atleast_1d(np.asarray(v, dtype=float)) for v in values])
    cols = [np.asarray(v, dtype=float).reshape(rows, -1) for v in values]
    return np.ascontiguousarray(np.hstack(cols))


def _unpack(cls: Any, p: Any) -> Any:
    """Split a packed vector (NumPy (n,) or (N, n) on the last axis, or a CasADi column)."""
    if isinstance(p, np.ndarray):
        parts = _offsets(cls, _arm_of(cls, p.shape[-1])).values()
        return cls(*(p[..., sl] for sl in parts))
    parts = _offsets(cls, _arm_of(cls, p.numel())).values()
    return cls(*(p[sl.start : sl.stop] for sl in parts))


class Layout(NamedTuple):
    """The packed sizes for an arm of ``arm`` joints (``Layout.of(robot)``).

    Attributes:
        arm: the arm's joint count n.
    """

    arm: int = ARM_JOINTS

    @classmethod
    def of(cls, robot: Robot) -> Layout:
        """The layout of ``robot``'s arm (``len(robot.links)`` joints)."""
        return cls(len(robot.links))

    @property
    def state(self) -> int:
        """State size: base pose (3), sprockets (2), arm joints (n)."""
        return BASE_STATE + self.arm

    @property
    def joints(self) -> int:
        """Joint count: the q̇ the QP solves for (sprockets, then the arm)."""
        return SPROCKETS + self.arm

    @property
    def task(self) -> int:
        """Task size ξ (base point and heading, arm CoM): 6 for any arm."""
        return TASK_SIZE

    @property
    def reference(self) -> int:
        """Packed :class:`StepReference` size."""
        return StepReference.size(self.arm)

    @property
    def params(self) -> int:
        """Packed :class:`ControllerParams` size."""
        return ControllerParams.size(self.arm)


class ControllerParams(NamedTuple):
    """Run-time parameters of the ``step`` Function, packed in this order (18 + 6n numbers).

    Sizes for an arm of n joints (n = 4: 42 numbers).

    Attributes:
        kp: task gains K_p (6,) [1/s].
        w_a: task weights W_A (6,).
        w_b: joint-velocity weights W_B (2 + n,).
        posture_gain: posture gains K_q (n,) [1/s], one per arm joint.
        posture_weight: posture weights W_q (n,), one per arm joint.
        feedforward: 1.0 to add ξ̇_ref and q̇_ref, 0.0 not to.
        dt: control period [s].
        qdot_max: joint speed limits (2 + n,) [rad/s] (sprockets, then arm).
        q_min: arm joint lower limits (n,) [rad].
        q_max: arm joint upper limits (n,) [rad].
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
    def sizes(cls, arm: int = ARM_JOINTS) -> tuple[int, ...]:
        """Length of each field in the packed vector, for an arm of ``arm`` joints."""
        t, n, a = TASK_SIZE, SPROCKETS + arm, arm
        return (t, t, n, a, a, 1, 1, n, a, a)

    @classmethod
    def size(cls, arm: int = ARM_JOINTS) -> int:
        """Length of the packed vector."""
        return sum(cls.sizes(arm))

    @classmethod
    def offsets(cls, arm: int = ARM_JOINTS) -> dict[str, slice]:
        """Each field's slice in the packed vector."""
        return dict(_offsets(cls, arm))

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
        """The packed parameter vector (18 + 6n,)."""
        return _pack(tuple(self), None)

    @classmethod
    def unpack(cls, p: Any) -> ControllerParams:
        """Split a packed vector (NumPy or CasADi) into fields."""
        return _unpack(cls, p)


class StepReference(NamedTuple):
    """The controller's reference at one step (or N steps), packed in this order (15 + 2n numbers).

    Sizes for an arm of n joints (n = 4: 23 numbers).

    Attributes:
        xi_des: task reference ξ_des (6,) in M [m, m, rad, m, m, m].
        xi_dot_ref: its rate ξ̇_ref (6,) [m/s, rad/s] (feed-forward).
        q_ref: arm posture reference (n,) [rad], within the joint limits.
        q_dot_ref: its rate (n,) [rad/s] (feed-forward).
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
    def sizes(cls, arm: int = ARM_JOINTS) -> tuple[int, ...]:
        """Length of each field in the packed vector, for an arm of ``arm`` joints."""
        return (TASK_SIZE, TASK_SIZE, arm, arm, GROUND_SIZE)

    @classmethod
    def size(cls, arm: int = ARM_JOINTS) -> int:
        """Length of the packed vector."""
        return sum(cls.sizes(arm))

    @classmethod
    def offsets(cls, arm: int = ARM_JOINTS) -> dict[str, slice]:
        """Each field's slice in the packed vector."""
        return dict(_offsets(cls, arm))

    def pack(self) -> FloatArray:
        """The packed reference: (15 + 2n,) for one step, (N, 15 + 2n) if the fields are (N, ·)."""
        rows = None if np.ndim(self.xi_des) == 1 else int(np.shape(self.xi_des)[0])
        return _pack(tuple(self), rows)

    @classmethod
    def unpack(cls, r: Any) -> StepReference:
        """Split a packed reference ((15 + 2n,) or (N, 15 + 2n) NumPy, or a CasADi column)."""
        return _unpack(cls, r)


REFERENCE_SIZE = StepReference.size()
PARAMS_SIZE = ControllerParams.size()


def layout_header(
    kkt_tol: float | None = None, arm: int = ARM_JOINTS, notes: Sequence[str] = ()
) -> str:
    """``controller_layout.h``: the step's argument sizes and packed layouts as C macros.

    ``MMSTAB_N_*`` sizes (state, joints, task, arm joints, reference, params, local ground),
    then the offset of each field of the reference (``MMSTAB_REF_*``) and of the parameters
    (``MMSTAB_PARAM_*``), from :class:`StepReference` and :class:`ControllerParams`.

    Args:
        kkt_tol: the certificate's tolerance [rad/s], written as ``MMSTAB_KKT_TOL`` (the
            embedded example checks every step's KKT conditions with it); None: not written.
        arm: the arm's joint count (:class:`Layout`).
        notes: comment lines written after the offsets (the code generator's: which task
            reads which slots, which limit bounds which rows,
            :func:`mmstab.control.controller.qp.slot_notes`); they change no macro.
    """
    lay = Layout(arm)
    sizes = {
        "STATE": lay.state,
        "JOINTS": lay.joints,
        "TASK": lay.task,
        "ARM": lay.arm,
        "REFERENCE": lay.reference,
        "PARAMS": lay.params,
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
        *(
            f"#define MMSTAB_REF_{k.upper()} {v.start}"
            for k, v in StepReference.offsets(arm).items()
        ),
        "",
        "/* params (ControllerParams): offset of each field */",
        *(
            f"#define MMSTAB_PARAM_{k.upper()} {v.start}"
            for k, v in ControllerParams.offsets(arm).items()
        ),
        "",
        *([f"/* {note} */" for note in notes] + [""] if notes else []),
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
