"""The QP of one step, assembled from the tasks and the limits (paper Eq. 7-8 + posture task).

::

    v_b = K_b e_b + f ṙ_b   (base point and heading; heading error wrapped to (−π, π])
    v_c = K_c e_c + f ṙ_c   (arm CoM)
    v_q = K_q e_q + f q̇_ref (posture; no wrap: q_ref is in limit coordinates)
    min Σ_tasks ½‖v − J q̇‖²_W + ½‖q̇‖²_{W_B}   s.t. the limits' bounds on q̇

so H = Σ Jᵀ W J + W_B, g = −Σ Jᵀ W v (:meth:`mmstab.control.tasks.Task.objective`) and
lbx/ubx the intersection of the limits (:func:`mmstab.control.limits.base.intersect`); W_B > 0, so
the QP is strictly convex. As pink's ``build_ik``, :func:`build_qp` loops over the tasks
(each reads its target from its slots of the step's reference and parameters,
:meth:`~mmstab.control.tasks.Task.target`) and the limits (each bounds its rows of q̇); the
lists are the registries' defaults (:data:`mmstab.control.tasks.DEFAULT_TASKS`,
:data:`mmstab.control.limits.DEFAULT_LIMITS`) unless the caller gives others. The tasks are
evaluated at the reference's local ground.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import NamedTuple

import casadi as ca

from mmstab.control.layout import ControllerParams, StepReference
from mmstab.control.limits import Limit, LimitContext, intersect
from mmstab.control.tasks import Task, TaskModel, task_map
from mmstab.model.robot import FloatArray


class QPData(NamedTuple):
    """The QP of one step: min ½ q̇ᵀHq̇ + gᵀq̇ + cost0 s.t. lbx ≤ q̇ ≤ ubx; pre-solve status.

    Attributes:
        H: Hessian (2 + n, 2 + n), n the arm's joints.
        g: gradient (2 + n,).
        lbx: lower bounds on q̇ (2 + n,) [rad/s].
        ubx: upper bounds on q̇ (2 + n,) [rad/s].
        xi_dot_des: the task rate asked for ξ̇_des (6,) [m/s, rad/s].
        q_dot_posture: the arm joint rates the posture task asks for q̇_post (n,) [rad/s].
        cost0: the constant of the cost (its value at q̇ = 0).
        status: the pre-solve status (:class:`~mmstab.control.controller.QPStatus` value).
    """

    H: FloatArray
    g: FloatArray
    lbx: FloatArray
    ubx: FloatArray
    xi_dot_des: FloatArray
    q_dot_posture: FloatArray
    cost0: float
    status: int


def tree_reduce(x: ca.SX, op: Callable[[ca.SX, ca.SX], ca.SX]) -> ca.SX:
    """``op`` folded over the elements of ``x`` as a balanced tree (``x`` not empty).

    A left fold (``ca.sum1``, ``ca.mmin``) is a chain of n dependent operations: ~4 cycles of
    latency each, 0.15 µs for the ~100 numbers the step checks; the tree's depth is log₂ n.
    """
    items = [x[i] for i in range(x.numel())]
    while len(items) > 1:
        pairs = [op(a, b) for a, b in zip(items[::2], items[1::2], strict=False)]
        items = pairs + ([items[-1]] if len(items) % 2 else [])
    return items[0]


def all_true(x: ca.SX) -> ca.SX:
    """1 if every element of ``x`` is nonzero (1 for an empty ``x``)."""
    return tree_reduce(ca.vec(x), ca.fmin) if x.numel() else ca.SX(1)


def all_finite(x: ca.SX) -> ca.SX:
    """1 if every element of ``x`` is finite.

    The sum of the elements scaled by 2⁻¹⁰⁰⁰ (exact: a power of two) is finite exactly when
    every element is: a scaled finite element is below 2²⁴, so ~100 of them cannot overflow,
    while an inf stays inf (or meets −inf: NaN) and a NaN stays NaN. One multiply-add per
    element where ``|x| < inf`` and a minimum took three (the step checks ~100 numbers; CasADi
    simplifies x·0 to 0, so that cheaper-looking test cannot be written).
    """
    if not x.numel():
        return ca.SX(1)
    if x.numel() > 2**20:
        raise ValueError("all_finite: too many elements for the scaled sum")
    return ca.fabs(tree_reduce(ca.vec(x) * 2.0**-1000, ca.plus)) < ca.inf


def slot_notes(tasks: Sequence[Task], limits: Sequence[Limit], model: TaskModel) -> list[str]:
    """What each task reads of the packed inputs and which rows of q̇ each limit bounds.

    One line per task and limit, in the QP's order (``controller_layout.h``'s comments):
    ``task base_point: xi_des[0:3] xi_dot_ref[0:3] kp[0:3] w_a[0:3] feedforward`` (a
    computed target or a zero rate shows as ``-``), ``limit joint_position: qdot[2:6]``
    (a limit that reads the reference adds ``, reads ...``).
    """
    lines = []
    for t in tasks:
        read = [("-" if slot is None else slot.describe()) for slot in t.slots]
        lines.append(f"task {t.name} ({t.rows(model)} rows): {' '.join(read)} feedforward")
    for limit in limits:
        start, stop = limit.rows(model.layout)
        reads = f", reads {limit.reads}" if limit.reads else ""
        lines.append(f"limit {limit.name}: qdot[{start}:{stop}]{reads}")
    return lines


def build_qp(
    model: TaskModel,
    tasks: Sequence[Task],
    limits: Sequence[Limit],
    statuses: tuple[float, float, float],
) -> ca.Function:
    """SX Function (state, reference, params) -> the QP's matrices and the pre-solve status.

    Args:
        model: the task kinematics.
        tasks: the tasks, summed in this order (their values of ξ_des tile ξ,
            :func:`~mmstab.control.tasks.task_map`).
        limits: the limits, intersected in this order.
        statuses: the status values for (success, non-finite input, infeasible bounds).

    Returns:
        ``qp`` (state (5 + n), reference (15 + 2n), params (18 + 6n)) -> (H, g, lbx, ubx,
        xi_dot_des, q_dot_posture, cost0, status), n the arm's joints (``model.layout``); see
        the module docstring for the formulas. ``xi_dot_des`` stacks the rates of the tasks of
        ξ, ``q_dot_posture`` those of the tasks whose target is ``q_ref`` (zero without one).
    """
    success, nonfinite, infeasible = statuses
    s, ground = model.state, model.ground
    lay = model.layout
    ref, p = ca.SX.sym("reference", lay.reference), ca.SX.sym("params", lay.params)
    P, R = ControllerParams.unpack(p), StepReference.unpack(ref)
    xi_tasks = task_map(tasks)  # checked first: no tasks, or none of ξ, is a ValueError
    objectives = [t.objective(model, t.target(R, P)) for t in tasks]
    H, g, cost0 = objectives[0].H, objectives[0].g, objectives[0].cost0
    for o in objectives[1:]:
        H, g, cost0 = H + o.H, g + o.g, cost0 + o.cost0
    H = H + ca.diag(P.w_b)
    rate = {id(t): o.rate for t, o in zip(tasks, objectives, strict=True)}
    xi_dot_des = ca.vertcat(*(rate[id(t)] for t in xi_tasks))
    lbx, ubx = intersect(limits, s, P, LimitContext(model, R, xi_dot_des))
    posture = [rate[id(t)] for t in tasks if t.slots.value and t.slots.value.field == "q_ref"]
    q_dot_posture = ca.vertcat(*posture) if posture else ca.SX.zeros(lay.arm)
    # the inputs: finite inputs give a finite H and g (short of overflow, which the
    # certificate refuses as SOLVER_FAILED)
    finite = all_finite(ca.vertcat(s, ref, p))
    status = ca.if_else(finite, ca.if_else(all_true(lbx <= ubx), success, infeasible), nonfinite)
    outputs = [H, g, lbx, ubx, xi_dot_des, q_dot_posture, cost0, status]
    # cse: shared subexpressions (sin/cos of the joints, products of the Jacobian) once
    at_ground = ca.Function("qp_at_ground", [s, ground, ref, p], outputs, {"cse": True})
    return ca.Function(
        "qp",
        [s, ref, p],
        list(at_ground(s, R.ground, ref, p)),
        ["state", "reference", "params"],
        ["H", "g", "lbx", "ubx", "xi_dot_des", "q_dot_posture", "cost0", "status"],
        {"cse": True},
    )
