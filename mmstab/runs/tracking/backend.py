"""The controller step a simulation runs with, and one control period as one CasADi call."""

from __future__ import annotations

from typing import NamedTuple

import casadi as ca

from mmstab.control.controller import (
    JOINT_COUNT,
    PARAMS_SIZE,
    REFERENCE_SIZE,
    STATE_SIZE,
    ControllerParams,
    QPStatus,
    TaskModel,
)
from mmstab.core.files import MmstabError


class StepBackend(NamedTuple):
    """A controller step to simulate with.

    Attributes:
        function: CasADi Function (state (9), reference (23) = [ξ_des, ξ̇_ref, q_ref, q̇_ref, ground],
            params (42))
            -> (qdot (6) [rad/s], status (a :class:`QPStatus` value), ...), the signature of
            :attr:`mmstab.control.controller.Controller.step`; on failure it should return q̇ = 0
            (the
            simulation holds still on any status but SUCCESS regardless).
        name: how it was made (``interpreted``, ``generated``, ``custom``), for the records.
    """

    function: ca.Function
    name: str

    def check(self) -> None:
        """Raise :class:`MmstabError` unless the Function has the step's signature."""
        f = self.function
        sizes_in = [f.size_in(i) for i in range(f.n_in())]
        expected = [(STATE_SIZE, 1), (REFERENCE_SIZE, 1), (PARAMS_SIZE, 1)]
        if sizes_in != expected:
            raise MmstabError(
                f"step Function {f.name()!r} takes {sizes_in}; expected {expected} "
                "(state, reference, params)"
            )
        if f.n_out() < 2 or f.size_out(0) != (JOINT_COUNT, 1) or f.size_out(1) != (1, 1):
            raise MmstabError(
                f"step Function {f.name()!r} must return qdot ({JOINT_COUNT}, 1) and a status "
                f"(1, 1) first; got {[f.size_out(i) for i in range(f.n_out())]}"
            )


def as_backend(step: ca.Function | StepBackend) -> StepBackend:
    """A :class:`StepBackend` from a bare CasADi Function (named ``custom``) or a backend."""
    backend = step if isinstance(step, StepBackend) else StepBackend(step, "custom")
    if not isinstance(backend.function, ca.Function):
        raise MmstabError(f"step must be a casadi.Function, got {type(backend.function)}")
    backend.check()
    return backend


def build_advance(model: TaskModel, step: ca.Function) -> ca.Function:
    """Compose one control period: controller step, hold-still guard, exact-arc integration.

    Args:
        model: task kinematics (gives the integrator).
        step: the step Function (see :class:`StepBackend`).

    Returns:
        Function (state (9), reference (23), params (42)) -> (state_next (9), qdot (6)
        [rad/s] as applied, status, finite): ``qdot`` is the step's answer when its status is
        SUCCESS and zero otherwise; ``finite`` is 1 when every component of ``state_next`` is
        finite. dt [s] is read from the parameters (``ControllerParams.dt``).
    """
    state = ca.MX.sym("state", STATE_SIZE)
    ref = ca.MX.sym("reference", REFERENCE_SIZE)
    p = ca.MX.sym("params", PARAMS_SIZE)
    out = step(state, ref, p)
    qdot_raw, status = out[0], out[1]
    ok = status == float(QPStatus.SUCCESS)
    qdot = ca.if_else(ok, qdot_raw, ca.MX.zeros(JOINT_COUNT))
    nxt = model.f_integrate(state, qdot, ControllerParams.unpack(p).dt)
    finite = ca.mmin(ca.fabs(nxt) < ca.inf)  # NaN compares false
    return ca.Function(
        "advance",
        [state, ref, p],
        [nxt, qdot, status, finite],
        ["state", "reference", "params"],
        ["state_next", "qdot", "status", "finite"],
    )
