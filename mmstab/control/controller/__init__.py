"""Tracking controller (paper Section II-E, Eq. 7-8; ``docs/design.md``, "Controller").

The tasks (ξ, J) live in :mod:`mmstab.control.tasks`, the limits in :mod:`mmstab.control.limits`,
the packed
vectors in :mod:`mmstab.control.layout` and the plant in :mod:`mmstab.control.plant`; this package
assembles
the QP (:mod:`~mmstab.control.controller.qp`), builds the solver around it and certifies its answers
(:mod:`~mmstab.control.controller.certificate`, :mod:`~mmstab.control.controller.step`); settings in
:mod:`~mmstab.control.controller.settings`. Vectors: state s (9) = base pose in S
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
offset is under 0.1 mm after 5 s; tests/control/test_tracking.py) and the light heading row only
keeps the body aligned where the point's motion leaves it free. The reference must use the same d
(:func:`mmstab.control.reference.base_reference`). Whatever d, J has rank 5 (three base rows, two
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
(:mod:`mmstab.control.posture`); without it the redundancy drifts and the upper arm went through the
body for 29 % of the default lap.

**Failure handling.** The one CasADi ``step`` Function certifies its own answer, so the status
is the same interpreted and code-generated and does not depend on a plugin's exceptions:
non-finite inputs (``NONFINITE_INPUT``: NaN/inf in the state, reference or parameters) or
contradictory bounds (``INFEASIBLE``) are detected *before* the solver, which is then fed a
harmless dummy QP (the ``box`` plugin's solver takes any numbers and needs no dummy); the
solver's answer must be finite, within the bounds to ``kkt_tol`` and satisfy the
projected-Newton optimality residual ``|q̇ − Π(q̇ − ∇f/diag H)|∞ ≤ kkt_tol`` (else
``SOLVER_FAILED``). The solution is then clipped to the bounds, so the limits hold to
round-off. On any failure the returned q̇ is the documented safe action **hold still, q̇ = 0**,
the result says so and :attr:`Controller.failures` counts it.
:meth:`Controller.solve_direct` solves the same QP through the plugin's own status
(``stats()['success']``), to cross-check the certificate.

**Speed.** :meth:`Controller.solve` evaluates ``step`` through ``Function.buffer()`` on
preallocated arrays: no dict arguments, no DM conversion.
"""

from mmstab.control.controller.certificate import ControlResult, QPStatus, quiet_stdout
from mmstab.control.controller.qp import QPData, build_qp
from mmstab.control.controller.settings import (
    CODEGEN_PLUGINS,
    PLUGINS,
    ControllerSettings,
    OsqpSettings,
    check_settings,
)
from mmstab.control.controller.step import Controller, build_controller
from mmstab.control.layout import (
    ARM,
    ARM_JOINTS,
    JOINT_COUNT,
    JOINTS,
    PARAMS_SIZE,
    POSE,
    REFERENCE_SIZE,
    STATE_SIZE,
    TASK_SIZE,
    ControllerParams,
    StepReference,
)
from mmstab.control.tasks import TaskModel

__all__ = [  # the task model and layouts are re-exported: most callers import them from here
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
    "build_qp",
    "check_settings",
    "quiet_stdout",
]
