"""The box QP plugin (mmstab/control/controller/boxqp.c): exact, checked against qrqp and KKT."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from mmstab.control.controller import QPStatus, StepReference, build_controller
from mmstab.control.controller.boxqp import BOXQP_NAME, build_boxqp
from mmstab.control.reference import initial_state
from mmstab.runs.rollout import controller_settings, example_plan, rollout, run_inputs


@pytest.fixture(scope="module")
def boxqp():
    return build_boxqp()


@pytest.fixture(scope="module")
def qrqp():
    opts = {"print_iter": False, "print_header": False, "print_info": False}
    sp = {"h": ca.Sparsity.dense(6, 6), "a": ca.Sparsity(0, 6)}
    return ca.conic("ref_qp", "qrqp", sp, {**opts, "error_on_fail": False})


def random_qp(rng: np.random.Generator, k: int):
    """A strictly convex box QP: well and badly conditioned H, wide and narrow boxes."""
    A = rng.normal(size=(6, 6))
    if k % 3 == 0:  # a strongly diagonal H over five decades
        H = np.diag(10 ** rng.uniform(-3, 2, 6)) + 0.01 * A @ A.T
    else:
        H = A @ A.T + 10 ** rng.uniform(-4, 1) * np.eye(6)
    g = rng.normal(size=6) * 10 ** rng.uniform(-2, 2)
    lb, ub = -rng.uniform(0, 2, 6), rng.uniform(0, 2, 6)
    if k % 5 == 0:  # boxes that may exclude 0: many active bounds
        lb = rng.uniform(-1, 0.5, 6)
        ub = lb + rng.uniform(0, 0.5, 6)
    return H, g, lb, ub


def natural_residual(H, g, lb, ub, x) -> float:
    """|x − Π(x − ∇f)|∞ / (1 + |∇f|∞): zero exactly at the optimum of a convex box QP."""
    grad = H @ x + g
    return float(np.abs(np.clip(x - grad, lb, ub) - x).max() / (1 + np.abs(grad).max()))


def test_box_solver_is_optimal_and_agrees_with_qrqp(boxqp, qrqp):
    rng = np.random.default_rng(7)
    worst_kkt, worst_diff, active, compared = 0.0, 0.0, 0, 0
    for k in range(2000):
        H, g, lb, ub = random_qp(rng, k)
        x, flag = (np.asarray(v).ravel() for v in boxqp(H, g, lb, ub))
        assert flag[0] == 0
        assert np.all(x >= lb) and np.all(x <= ub)  # feasible exactly (bounds are copied)
        worst_kkt = max(worst_kkt, natural_residual(H, g, lb, ub, x))
        active += bool(np.any((x == lb) | (x == ub)))
        y = np.asarray(qrqp(h=H, g=g, lbx=lb, ubx=ub)["x"]).ravel()
        if qrqp.stats()["success"] and natural_residual(H, g, lb, ub, y) < 1e-9:
            compared += 1
            worst_diff = max(worst_diff, float(np.abs(x - y).max() / (1 + np.abs(y).max())))
    assert worst_kkt < 1e-13
    assert worst_diff < 1e-8  # the unique optimum, found by an independent solver
    assert active > 500 and compared > 1900  # the cases exercise the active set


def test_box_solver_reports_a_hessian_that_is_not_positive_definite(boxqp):
    H = np.diag([1.0, 1.0, -1.0, 1.0, 1.0, 1.0])
    x, flag = (np.asarray(v).ravel() for v in boxqp(H, np.ones(6), -np.ones(6), np.ones(6)))
    assert flag[0] == 1 and np.isnan(x).all()
    H[2, 2] = np.nan
    x, flag = (np.asarray(v).ravel() for v in boxqp(H, np.ones(6), -np.ones(6), np.ones(6)))
    assert flag[0] == 1 and np.isnan(x).all()


def test_box_solver_has_casadi_names(boxqp):
    assert boxqp.name() == BOXQP_NAME
    assert boxqp.name_in() == ["h", "g", "lbx", "ubx"] and boxqp.name_out() == ["x", "flag"]


def test_box_plugin_equals_qrqp_on_the_closed_loop(problem):
    """The default run's states stepped by both plugins, as given and with far-off targets."""
    plan = example_plan(problem.robot)
    state0 = initial_state(problem.circle, problem.robot.stowed, lateral_offset=0.05)
    inputs = run_inputs(problem, plan, steps=1500, state0=state0)
    run = rollout(problem, plan, backend="casadi", inputs=inputs)
    box = build_controller(problem.robot, controller_settings(problem, "box"))
    ref = build_controller(problem.robot, controller_settings(problem, "qrqp"))
    rng = np.random.default_rng(3)
    saturated, worst = 0, 0.0
    for k in range(0, inputs.steps, 3):
        r = StepReference.unpack(inputs.reference[k])
        if k % 2:  # targets 0.3 m away: joint speed limits become active
            r = r._replace(xi_des=r.xi_des + np.r_[rng.normal(0, 0.3, 2), 0, rng.normal(0, 0.3, 3)])
        a, b = box.solve(run.states[k], *r), ref.solve(run.states[k], *r)
        assert a.status is QPStatus.SUCCESS and b.status is QPStatus.SUCCESS
        worst = max(worst, float(np.abs(a.qdot - b.qdot).max()))
        qp = box.qp_data(run.states[k], *r)
        saturated += bool(np.any((a.qdot == qp.lbx) | (a.qdot == qp.ubx)))
    assert worst < 1e-9
    assert saturated >= 50  # the comparison covers steps with active joint limits


def test_box_direct_solve_uses_the_solver_flag(problem):
    ctrl = build_controller(problem.robot, controller_settings(problem, "box"))
    state = np.r_[0.0, -1.5, 0.0, 0.0, 0.0, problem.robot.stowed]
    xi = ctrl.model.task(state)
    a, b = ctrl.solve(state, xi), ctrl.solve_direct(state, xi)
    assert a.success and b.success
    np.testing.assert_allclose(a.qdot, b.qdot, atol=1e-12)
