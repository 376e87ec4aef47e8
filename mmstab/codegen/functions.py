"""The Functions exported to C: step, task, plant and the rolled closed loop."""

from __future__ import annotations

import casadi as ca

from mmstab.control.controller import Controller, ControllerParams
from mmstab.control.plant import PLANT_NAME

STEP_NAME = "controller_step"  #: the exported step (and the .c/.h file stem)
TASK_NAME = "controller_task"  #: state -> ξ, exported alongside
ROLLOUT_NAME = "controller_rollout"  #: ROLLOUT_CHUNK closed-loop steps, exported alongside
QP_NAME = "controller_qp_data"  #: the step's QP (H, g, bounds): the example's KKT check
JACOBIAN_NAME = "controller_jacobian"  #: (state, ground) -> J: the benchmark's time split
ROLLOUT_CHUNK = 1000  #: closed-loop steps per ``controller_rollout`` call


def closed_loop(ctrl: Controller) -> ca.Function:
    """One closed-loop step: controller step, then the exact-arc motion over ``params.dt``.

    Returns:
        ``Function`` (state, reference, params) -> (state_next, qdot [rad/s], status), sized
        by ``ctrl.layout`` (4-DoF arm: 9, 23, 42 -> 9, 6, 1).
    """
    lay = ctrl.layout
    state, ref = ca.MX.sym("state", lay.state), ca.MX.sym("reference", lay.reference)
    p = ca.MX.sym("params", lay.params)
    qdot, status, _ = ctrl.step(state, ref, p)
    nxt = ctrl.model.f_integrate(state, qdot, ControllerParams.unpack(p).dt)
    return ca.Function(
        "closed_loop",
        [state, ref, p],
        [nxt, qdot, status],
        ["state", "reference", "params"],
        ["state_next", "qdot", "status"],
    )


def rollout_chunk(ctrl: Controller, steps: int = ROLLOUT_CHUNK) -> ca.Function:
    """``steps`` closed-loop steps in one Function (``mapaccum`` of :func:`closed_loop`).

    Returns:
        ``Function`` ``controller_rollout`` (state0, references (· x steps), params) ->
        (states after each step (· x steps), qdot (· x steps), status (1 x steps)), sized by
        ``ctrl.layout`` (4-DoF arm: 9, 23, 42 -> 9, 6).
    """
    lay = ctrl.layout
    acc = closed_loop(ctrl).mapaccum("closed_loop_acc", steps)
    x0 = ca.MX.sym("state0", lay.state)
    refs = ca.MX.sym("references", lay.reference, steps)
    p = ca.MX.sym("params", lay.params)
    states, qdot, status = acc(x0, refs, ca.repmat(p, 1, steps))
    return ca.Function(
        ROLLOUT_NAME,
        [x0, refs, p],
        [states, qdot, status],
        ["state0", "references", "params"],
        ["states", "qdot", "status"],
    )


def export_functions(ctrl: Controller) -> list[ca.Function]:
    """The Functions written to the C file: step, task, plant, rollout chunk, QP data, J."""
    step = ctrl.step
    if step.name() != STEP_NAME:  # the exported symbol is the Function's name
        raise RuntimeError(f"the controller's step is named {step.name()!r}, not {STEP_NAME!r}")
    m = ctrl.model
    task = ca.Function(TASK_NAME, [m.state, m.ground], [m.xi], ["state", "ground"], ["xi"])
    plant = ctrl.model.f_integrate
    if plant.name() != PLANT_NAME:
        raise RuntimeError(f"the plant is named {plant.name()!r}, not {PLANT_NAME!r}")
    qp = ctrl.qp
    qp_data = ca.Function(
        QP_NAME, qp.sx_in(), qp.call(qp.sx_in()), qp.name_in(), qp.name_out(), {"cse": True}
    )
    jac = ca.Function(
        JACOBIAN_NAME, [m.state, m.ground], [m.J], ["state", "ground"], ["J"], {"cse": True}
    )
    return [step, task, plant, rollout_chunk(ctrl), qp_data, jac]
