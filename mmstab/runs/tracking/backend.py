"""The controller step a simulation runs with, and one control period as one CasADi call."""

from __future__ import annotations

from typing import NamedTuple

import casadi as ca

from mmstab.control.controller import ControllerParams, QPStatus, TaskModel
from mmstab.control.layout import BASE_STATE, Layout
from mmstab.core.files import MmstabError


class StepBackend(NamedTuple):
    """A controller step to simulate with.

    Attributes:
        function: CasADi Function (state (5 + n), reference (15 + 2n) = [ξ_des, ξ̇_ref, q_ref,
            q̇_ref, ground], params (18 + 6n)) -> (qdot (2 + n) [rad/s], status (a
            :class:`QPStatus` value), ...), n the arm's joints, the signature of
            :attr:`mmstab.control.controller.Controller.step`; on failure it should return
            q̇ = 0 (the simulation holds still on any status but SUCCESS regardless).
        name: how it was made (``interpreted``, ``generated``, ``custom``), for the records.
    """

    function: ca.Function
    name: str

    @property
    def layout(self) -> Layout:
        """The layout its state argument implies (an arm of ``state size − 5`` joints)."""
        f = self.function
        return Layout(max(f.size1_in(0) - BASE_STATE, 1) if f.n_in() else 1)

    def check(self) -> None:
        """Raise :class:`MmstabError` unless the Function has the step's signature."""
        f = self.function
        sizes_in = [f.size_in(i) for i in range(f.n_in())]
        lay = self.layout
        expected = [(lay.state, 1), (lay.reference, 1), (lay.params, 1)]
        if sizes_in != expected:
            raise MmstabError(
                f"step Function {f.name()!r} takes {sizes_in}; expected {expected} "
                "(state, reference, params)"
            )
        if f.n_out() < 2 or f.size_out(0) != (lay.joints, 1) or f.size_out(1) != (1, 1):
            raise MmstabError(
                f"step Function {f.name()!r} must return qdot ({lay.joints}, 1) and a status "
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
        Function (state, reference, params) -> (state_next, qdot [rad/s] as applied, status,
        finite), sized by ``model.layout`` (4-DoF arm: 9, 23, 42 -> 9, 6): ``qdot`` is the
        step's answer when its status is SUCCESS and zero otherwise; ``finite`` is 1 when every
        component of ``state_next`` is finite. dt [s] is read from the parameters
        (``ControllerParams.dt``).
    """
    lay = model.layout
    state = ca.MX.sym("state", lay.state)
    ref = ca.MX.sym("reference", lay.reference)
    p = ca.MX.sym("params", lay.params)
    out = step(state, ref, p)
    qdot_raw, status = out[0], out[1]
    ok = status == float(QPStatus.SUCCESS)
    qdot = ca.if_else(ok, qdot_raw, ca.MX.zeros(lay.joints))
    nxt = model.f_integrate(state, qdot, ControllerParams.unpack(p).dt)
    finite = ca.mmin(ca.fabs(nxt) < ca.inf)  # NaN compares false
    return ca.Function(
        "advance",
        [state, ref, p],
        [nxt, qdot, status, finite],
        ["state", "reference", "params"],
        ["state_next", "qdot", "status", "finite"],
    )
