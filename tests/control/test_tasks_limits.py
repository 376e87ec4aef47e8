"""Each task's value, error and Jacobian; each limit's bounds; the QP as their sum."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from mmstab.control.controller import ControllerParams, ControllerSettings, build_controller
from mmstab.control.layout import Layout, StepReference
from mmstab.control.limits import (
    JointPositionLimit,
    JointVelocityLimit,
    LimitContext,
    YawRateLimit,
    intersect,
)
from mmstab.control.tasks import (
    ArmCoMTask,
    BasePointTask,
    PostureTask,
    TaskTarget,
    build_task_model,
)


@pytest.fixture(scope="module")
def model(problem):
    return build_task_model(problem.robot, 0.2)


def states(robot, rng, n):
    return np.column_stack(
        [
            rng.uniform(-2, 2, (n, 2)),
            rng.uniform(-np.pi, np.pi, n),
            rng.uniform(-9, 9, (n, 2)),
            rng.uniform(robot.joint_lower, robot.joint_upper, (n, 4)),
        ]
    )


@pytest.mark.parametrize("task", [BasePointTask(0.2), ArmCoMTask(), PostureTask()])
def test_jacobian_is_the_rate_of_the_value_along_the_plant(model, problem, rng, task):
    """(value(s after +h) − value(s after −h)) / 2h = J q̇, on a tilted local ground too."""
    value = ca.Function("v", [model.state, model.ground], [task.value(model)])
    jac = ca.Function("J", [model.state, model.ground], [task.jacobian(model)])
    h = 1e-6
    for s in states(problem.robot, rng, 10):
        ground, qdot = rng.normal(0, 0.2, 3), rng.uniform(-3, 3, 6)
        fd = (
            np.asarray(value(model.integrate(s, qdot, h), ground))
            - np.asarray(value(model.integrate(s, qdot, -h), ground))
        ).ravel() / (2 * h)
        assert np.asarray(jac(s, ground)).shape == (task.rows(model), 6)
        np.testing.assert_allclose(np.asarray(jac(s, ground)) @ qdot, fd, atol=1e-7)


def test_errors(model, problem):
    s = np.r_[0.3, -0.2, 3.0, 0.0, 0.0, problem.robot.stowed]
    err = ca.Function(
        "e", [model.state, model.ground], [BasePointTask(0.2).error(model, ca.DM([0.5, 0.1, -3.0]))]
    )
    e = np.asarray(err(s, np.zeros(3))).ravel()
    # the point 0.2 m ahead on the ramp (ground zero), heading error wrapped: -3 - 3 + 2π
    np.testing.assert_allclose(
        e[:2], [0.5 - 0.3 - 0.2 * np.cos(3.0), 0.1 + 0.2 - 0.2 * np.sin(3.0)]
    )
    assert e[2] == pytest.approx(-6.0 + 2 * np.pi)
    q_ref = np.array([1.0, 0.1, -0.2, 0.3])
    pe = ca.Function("p", [model.state], [PostureTask().error(model, ca.DM(q_ref))])
    np.testing.assert_allclose(np.asarray(pe(s)).ravel(), q_ref - problem.robot.stowed)


def test_objective_is_the_weighted_least_squares_of_the_rate(model, problem, rng):
    task = ArmCoMTask()
    target = TaskTarget(
        ca.DM([0.1, 0.2, 0.3]),
        ca.DM([0.01, 0.0, -0.02]),
        ca.DM([5, 4, 3]),
        ca.DM([1.0, 2.0, 0.5]),
        1.0,
    )
    obj = task.objective(model, target)
    f = ca.Function("o", [model.state, model.ground], [obj.H, obj.g, obj.cost0, obj.rate])
    jac = ca.Function("J", [model.state, model.ground], [task.jacobian(model)])
    s = states(problem.robot, rng, 1)[0]
    H, g, c0, v = (np.asarray(x) for x in f(s, np.zeros(3)))
    J, W = np.asarray(jac(s, np.zeros(3))), np.diag([1.0, 2.0, 0.5])
    qdot = rng.normal(size=6)
    cost = 0.5 * (v.ravel() - J @ qdot) @ W @ (v.ravel() - J @ qdot)
    assert 0.5 * qdot @ H @ qdot + g.ravel() @ qdot + c0.item() == pytest.approx(cost, rel=1e-12)


def test_limits_bound_and_intersect(problem, rng):
    robot = problem.robot
    settings = ControllerSettings.from_section(problem.section("controller"))
    P = ControllerParams.from_settings(robot, settings)
    s = ca.SX.sym("s", 9)
    Ps = ControllerParams.unpack(ca.SX.sym("p", ControllerParams.size()))
    f = ca.Function(
        "b",
        [s, ca.vertcat(*[ca.vec(x) for x in Ps])],
        list(intersect([JointVelocityLimit(), JointPositionLimit()], s, Ps)),
    )
    state = states(robot, rng, 1)[0]
    state[5] = robot.joint_upper[0] - 1e-4  # near a stop: the position limit is the tighter
    lo, hi = (np.asarray(x).ravel() for x in f(state, P.pack()))
    q = state[5:]
    np.testing.assert_allclose(
        lo, np.r_[-P.qdot_max[:2], np.maximum(-P.qdot_max[2:], (robot.joint_lower - q) / P.dt)]
    )
    np.testing.assert_allclose(
        hi, np.r_[P.qdot_max[:2], np.minimum(P.qdot_max[2:], (robot.joint_upper - q) / P.dt)]
    )
    assert hi[2] == pytest.approx(1e-4 / P.dt) and hi[2] < P.qdot_max[2]
    assert JointPositionLimit().rows(Layout(4)) == (2, 6)  # the sprockets turn freely
    assert JointVelocityLimit().rows(Layout(4)) == (0, 6)
    free = ca.Function(
        "free",
        [s, ca.vertcat(*[ca.vec(x) for x in Ps])],
        [intersect([JointPositionLimit()], s, Ps).lower],
    )
    assert np.isneginf(np.asarray(free(state, P.pack())).ravel()[:2]).all()


def _yaw_bounds(model, problem, limit):
    """Function (state, reference, xi_dot_des, params) -> the sprockets' bounds."""
    lay = model.layout
    ref, xdd = ca.SX.sym("ref", lay.reference), ca.SX.sym("xdd", 6)
    p = ca.SX.sym("p", lay.params)
    P, R = ControllerParams.unpack(p), StepReference.unpack(ref)
    ctx = LimitContext(model, R, xdd)
    b = intersect([JointVelocityLimit(), limit], model.state, P, ctx)
    return ca.Function("yaw", [model.state, ref, xdd, p], [b.lower[:2], b.upper[:2]])


def _reference(yaw_rate, roll, pitch):
    return StepReference(
        np.zeros(6),
        np.r_[0.0, 0.0, yaw_rate, 0, 0, 0],
        np.zeros(4),
        np.zeros(4),
        [0.0, roll, pitch],
    ).pack()


def test_yaw_rate_limit_bounds_the_turn_on_slopes_only(model, problem):
    robot = problem.robot
    settings = ControllerSettings.from_section(problem.section("controller"))
    P = ControllerParams.from_settings(robot, settings)
    r, b = robot.base.tracks.sprocket_radius, robot.base.tracks.separation
    limit = YawRateLimit(margin=0.15, min_slope=np.radians(10.0))
    f = _yaw_bounds(model, problem, limit)
    state = np.r_[0.1, 0.2, 0.7, 0.0, 0.0, robot.stowed]
    # the base point asks for 0.1 m/s along the heading (0.7 rad) and 0.05 m/s across it
    along, across = np.array([np.cos(0.7), np.sin(0.7)]), np.array([-np.sin(0.7), np.cos(0.7)])
    xdd = np.r_[0.1 * along + 0.05 * across, 0.9, 0, 0, 0]
    # level (and the 5.7 deg ramp): the joint-speed limit only
    for roll in (0.0, 0.1):
        lo, hi = (
            np.asarray(x).ravel() for x in f(state, _reference(-0.2, roll, 0.0), xdd, P.pack())
        )
        np.testing.assert_allclose(lo, -P.qdot_max[:2])
        np.testing.assert_allclose(hi, P.qdot_max[:2])
    # 20 deg (roll 0.25, pitch 0.26): the widest yaw the box allows is |γ̇_ref| + margin
    lo, hi = (np.asarray(x).ravel() for x in f(state, _reference(-0.2, 0.25, 0.26), xdd, P.pack()))
    assert r * (hi[1] - lo[0]) / b == pytest.approx(0.2 + 0.15, rel=1e-12)
    assert r * (lo[1] - hi[0]) / b == pytest.approx(-(0.2 + 0.15), rel=1e-12)
    # ... about the forward speed the point asks for, which stays reachable (0.1 m/s)
    np.testing.assert_allclose((lo + hi) / 2, 0.1 / r)
    # a centre beyond the sprockets' speed limit is clipped to it: the box still meets it
    fast = np.r_[100.0 * along, 0.0, 0, 0, 0]
    lo, hi = (np.asarray(x).ravel() for x in f(state, _reference(0.0, 0.3, 0.0), fast, P.pack()))
    np.testing.assert_allclose(hi, P.qdot_max[:2])
    np.testing.assert_allclose(lo, P.qdot_max[:2] - 0.15 * b / (2 * r))
    with pytest.raises(ValueError, match="yaw_rate"):
        YawRateLimit(margin=-0.1)
    with pytest.raises(ValueError, match="context"):
        intersect([limit], model.state, ControllerParams.unpack(ca.SX.sym("p", P.pack().size)))


def test_controller_turns_no_faster_than_the_reference_on_a_slope(problem):
    """A heading 0.8 rad behind: the QP turns at 2 rad/s on the level, |γ̇_ref| + margin on 20°."""
    robot = problem.robot
    settings = ControllerSettings.from_section(problem.section("controller"))
    ctrl = build_controller(robot, settings)
    r, b = robot.base.tracks.sprocket_radius, robot.base.tracks.separation
    state = np.r_[0.0, 0.0, 0.0, 0.0, 0.0, robot.stowed]
    d = settings.base_offset
    com = robot.arm_com(robot.stowed)
    xi_des = np.r_[d * np.cos(0.8), d * np.sin(0.8), 0.8, com]
    xi_dot_ref = np.r_[0.0, 0.0, 0.1, 0, 0, 0]

    def yaw(ground):
        res = ctrl.solve(state, xi_des, xi_dot_ref, robot.stowed, None, ground)
        assert res.status == 0
        return r * (res.qdot[1] - res.qdot[0]) / b

    level, steep = yaw([0.0, 0.0, 0.0]), yaw([0.0, 0.35, 0.0])
    assert level > 0.5  # unbounded, the point's rows turn the base fast
    assert steep == pytest.approx(0.1 + YawRateLimit().margin, rel=1e-6)  # the bound binds
