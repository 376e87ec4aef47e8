"""The step's own answer check: pre-solve guard, post-solve certificate, statuses.

See :mod:`mmstab.control.controller`, "Failure handling".
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator
from enum import IntEnum
from typing import NamedTuple

import casadi as ca

from mmstab.control.controller.qp import all_finite, tree_reduce
from mmstab.model.robot import FloatArray


class QPStatus(IntEnum):
    """Outcome of one controller step; anything but SUCCESS returns q̇ = 0 (hold still)."""

    SUCCESS = 0
    NONFINITE_INPUT = 1  # NaN/inf in the state, reference or parameters
    INFEASIBLE = 2  # a joint's lower bound exceeds its upper bound (outside its limits)
    SOLVER_FAILED = 3  # the plugin's answer is not finite, feasible and optimal


class ControlResult(NamedTuple):
    """One step's answer: joint speeds (2 + n,) [rad/s], status, success, Eq. 7 cost at ``qdot``."""

    qdot: FloatArray
    status: QPStatus
    success: bool
    objective: float


def build_guard_and_certificate(kkt_tol: float, n: int) -> tuple[ca.Function, ca.Function]:
    """The pre-solve guard and the post-solve certificate (tolerance ``kkt_tol`` [rad/s]).

    Args:
        kkt_tol: the certificate's tolerance [rad/s].
        n: the QP's variables (the joints: 2 + the arm's).

    Returns:
        ``guard`` (H, g, lbx, ubx, status) -> a harmless QP unless the status is SUCCESS;
        ``certificate`` (x, H, g, lbx, ubx, cost0, status) -> (qdot, status, objective).
    """
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
    violation = tree_reduce(ca.vertcat(lbx - x, x - ubx), ca.fmax)
    grad = H @ clipped + g  # also gives the objective below: H q̇ computed once
    newton = clipped - ca.fmin(ca.fmax(clipped - grad / ca.diag(H), lbx), ubx)
    certified = ca.logic_and(all_finite(x), violation <= kkt_tol)
    certified = ca.logic_and(certified, tree_reduce(ca.fabs(newton), ca.fmax) <= kkt_tol)
    final = ca.if_else(ok, ca.if_else(certified, status, float(QPStatus.SOLVER_FAILED)), status)
    success = final == float(QPStatus.SUCCESS)
    qdot = ca.if_else(success, clipped, 0)
    # ½ q̇ᵀHq̇ + gᵀq̇ = ½ q̇ᵀ(Hq̇ + g) + ½ gᵀq̇ at q̇ = clipped; cost0 alone at q̇ = 0
    objective = ca.if_else(success, 0.5 * ca.dot(clipped, grad + g), 0) + cost0
    certificate = ca.Function(
        "certificate", [x, H, g, lbx, ubx, cost0, status], [qdot, final, objective]
    )
    return guard, certificate


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
