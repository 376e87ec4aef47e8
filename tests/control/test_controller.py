"""Tracking controller core: task Jacobian, QP (Eq. 7-8), plugins, limits, failures, references."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import write_problem

from mmstab.control.controller import (
    CODEGEN_PLUGINS,
    PARAMS_SIZE,
    PLUGINS,
    REFERENCE_SIZE,
    ControllerParams,
    ControllerSettings,
    QPStatus,
    StepReference,
    build_controller,
)
from mmstab.control.reference import (
    arm_reference,
    base_reference,
    circle_pose,
    periodic_spline,
    posture_reference,
    task_reference,
    unwrap_postures,
)
from mmstab.core.files import ConfigError
from mmstab.core.problem import load_problem
from mmstab.terrain import rot_z, wrap_angle


@pytest.fixture(scope="module")
def settings(problem) -> ControllerSettings:
    return ControllerSettings.from_section(problem.section("controller"))


@pytest.fixture(scope="module")
def controllers(problem, settings):
    return {
        p: build_controller(problem.robot, dataclasses.replace(settings, plugin=p)) for p in PLUGINS
    }


def random_states(robot, rng, n, margin=0.0):
    """States: pose in S, sprocket angles, arm joints within limits shrunk by ``margin``."""
    return np.column_stack(
        [
            rng.uniform(-2, 2, (n, 2)),
            rng.uniform(-np.pi, np.pi, n),
            rng.uniform(-20, 20, (n, 2)),
            rng.uniform(robot.joint_lower + margin, robot.joint_upper - margin, (n, 4)),
        ]
    )


# ----------------------------------------------------------------------------- task, Jacobian
def numpy_task(robot, state, d):
    """ξ from the NumPy kinematics: base point and Rz(γ) g_a^B placed at (x, y)."""
    x, y, h = state[:3]
    com_S = np.array([x, y, 0.0]) + rot_z(h) @ robot.arm_com(state[5:9])
    return np.r_[x + d * np.cos(h), y + d * np.sin(h), h, com_S]


def numpy_jacobian(robot, state, d, h=1e-6):
    """J from hand-derived track columns and NumPy central differences of g_a^B."""
    t = robot.base.tracks
    r, b = t.sprocket_radius, t.separation
    heading = state[2]
    c, s = np.cos(heading), np.sin(heading)
    com_S_rel = rot_z(heading) @ robot.arm_com(state[5:9])
    J = np.zeros((6, 6))
    for col, (v, w) in enumerate([(r / 2, -r / b), (r / 2, r / b)]):
        J[:3, col] = [v * c - d * w * s, v * s + d * w * c, w]
        J[3:, col] = [v * c - w * com_S_rel[1], v * s + w * com_S_rel[0], 0.0]
    q = state[5:9]
    for j, e in enumerate(np.eye(4)):
        dg = (robot.arm_com(q + h * e) - robot.arm_com(q - h * e)) / (2 * h)
        J[3:, 2 + j] = rot_z(heading) @ dg
    return J


def test_task_and_jacobian_match_numpy(robot, controllers, rng):
    model = controllers["qpoases"].model
    for state in random_states(robot, rng, 40):
        np.testing.assert_allclose(
            model.task(state),
            numpy_task(robot, state, controllers["qpoases"].settings.base_offset),
            atol=1e-12,
        )
        np.testing.assert_allclose(
            model.jacobian(state),
            numpy_jacobian(robot, state, controllers["qpoases"].settings.base_offset),
            atol=1e-8,
        )


def test_task_on_a_tilted_local_ground_is_M_T_B_applied(robot, controllers, rng):
    """With a nonzero local ground, ξ places the points with M_T_B = local_transforms(...)."""
    from mmstab.terrain import local_transforms

    model = controllers["qpoases"].model
    for state in random_states(robot, rng, 10):
        ground = rng.normal(0, 0.3, 3)
        T = local_transforms(state[:3], ground)[0]
        com_M = T[:3, :3] @ robot.arm_com(state[5:9]) + T[:3, 3]
        point = T[:3, :3] @ [controllers["qpoases"].settings.base_offset, 0, 0] + T[:3, 3]
        np.testing.assert_allclose(
            model.task(state, ground), np.r_[point[:2], state[2], com_M], atol=1e-12
        )


def test_jacobian_matches_finite_differences_of_integrated_motion(robot, controllers, rng):
    """(ξ(s after +h) − ξ(s after −h)) / 2h of the nonholonomic motion equals J q̇."""
    model = controllers["qpoases"].model
    h = 1e-6
    for state in random_states(robot, rng, 30):
        qdot = rng.uniform(-5, 5, 6)
        fd = (
            model.task(model.integrate(state, qdot, h))
            - model.task(model.integrate(state, qdot, -h))
        ) / (2 * h)
        np.testing.assert_allclose(model.jacobian(state) @ qdot, fd, atol=1e-7)


def test_integration_is_an_exact_arc_without_sideslip(robot, controllers, rng):
    model = controllers["qpoases"].model
    state = random_states(robot, rng, 1)[0]
    for qdot in (
        rng.uniform(-5, 5, 6),
        np.r_[3.0, 3.0, rng.uniform(-1, 1, 4)],
    ):  # turning, straight
        whole = model.integrate(state, qdot, 0.5)
        sub = state
        for _ in range(500):
            sub = model.integrate(sub, qdot, 1e-3)
            # no sideways motion: every substep's chord is along its mid heading
        np.testing.assert_allclose(whole, sub, atol=1e-12)
        chord = whole[:2] - state[:2]
        mid = (whole[2] + state[2]) / 2
        assert abs(chord @ np.array([-np.sin(mid), np.cos(mid)])) < 1e-12
        np.testing.assert_allclose(whole[3:], state[3:] + 0.5 * qdot, atol=1e-12)


# ------------------------------------------------------------------------------------ the QP
def numpy_qp(robot, P, state, d, xi_des, xi_dot_ref, q_ref, q_dot_ref, ground):
    """H, g, the constant, ξ̇_des and q̇_post of Eq. 7 + the posture task, in NumPy (ramp)."""
    assert not np.any(ground)  # the ramp's local ground
    e = xi_des - numpy_task(robot, state, d)
    e[2] = wrap_angle(e[2])
    xdd = P.kp * e + P.feedforward * xi_dot_ref
    qdp = P.posture_gain * (q_ref - state[5:9]) + P.feedforward * q_dot_ref
    J = numpy_jacobian(robot, state, d)
    W_q = np.r_[0.0, 0.0, P.posture_weight]  # the posture task acts on the arm columns only
    H = J.T @ np.diag(P.w_a) @ J + np.diag(P.w_b) + np.diag(W_q)
    g = -J.T @ (P.w_a * xdd) - W_q * np.r_[0.0, 0.0, qdp]
    cost0 = 0.5 * xdd @ (P.w_a * xdd) + 0.5 * qdp @ (P.posture_weight * qdp)
    return H, g, cost0, xdd, qdp


def random_reference(robot, c, state, rng):
    """ξ_des near ξ(state), ξ̇_ref, q_ref within the limits and q̇_ref: a StepReference."""
    return StepReference(
        c.model.task(state) + rng.normal(0, 0.2, 6),
        rng.normal(0, 0.1, 6),
        rng.uniform(robot.joint_lower, robot.joint_upper),
        rng.normal(0, 0.3, 4),
        np.zeros(3),
    )


def test_qp_matrices_are_eq7_with_the_posture_task(robot, controllers, rng):
    c = controllers["qpoases"]
    P = c.params
    assert np.all(P.posture_weight > 0) and np.all(P.posture_gain > 0)  # the term is on
    for state in random_states(robot, rng, 10):
        ref = random_reference(robot, c, state, rng)
        qp = c.qp_data(state, *ref)
        H, g, cost0, xdd, qdp = numpy_qp(robot, P, state, c.settings.base_offset, *ref)
        np.testing.assert_allclose(qp.xi_dot_des, xdd, atol=1e-12)
        np.testing.assert_allclose(qp.q_dot_posture, qdp, atol=1e-12)
        np.testing.assert_allclose(qp.H, H, atol=1e-8)
        np.testing.assert_allclose(qp.g, g, atol=1e-8)
        assert qp.cost0 == pytest.approx(cost0, rel=1e-12)
        assert np.linalg.eigvalsh(qp.H).min() > 0


def test_certificate_judges_the_posture_term(robot, controllers, rng):
    """The in-graph certificate uses the whole cost: the answer of Eq. 7 without the posture
    term is refused (SOLVER_FAILED), the true optimum accepted."""
    from mmstab.control.controller.certificate import build_guard_and_certificate

    c = controllers["qrqp"]
    _, certificate = build_guard_and_certificate(c.settings.kkt_tol, c.layout.joints)
    W_q = np.r_[0.0, 0.0, c.params.posture_weight]
    refused = 0
    for state in random_states(robot, rng, 10, margin=0.3):
        ref = random_reference(robot, c, state, rng)
        qp = c.qp_data(state, *ref)
        H0, g0 = qp.H - np.diag(W_q), qp.g + W_q * np.r_[0.0, 0.0, qp.q_dot_posture]
        without = np.asarray(c.conic(h=H0, g=g0, lbx=qp.lbx, ubx=qp.ubx)["x"]).ravel()
        args = (qp.H, qp.g, qp.lbx, qp.ubx, qp.cost0, float(qp.status))
        best = c.solve(state, *ref).qdot
        assert float(certificate(best, *args)[1]) == QPStatus.SUCCESS
        refused += float(certificate(without, *args)[1]) == QPStatus.SOLVER_FAILED
    assert refused == 10


def test_default_posture_reference_is_the_current_posture(robot, controllers, rng):
    """Without q_ref the posture term only damps the arm: q̇_post = 0, W_q adds to W_B."""
    c = controllers["qpoases"]
    state = random_states(robot, rng, 1)[0]
    xi_des = c.model.task(state) + 0.1
    held = c.qp_data(state, xi_des)
    explicit = c.qp_data(state, xi_des, np.zeros(6), state[5:9], np.zeros(4))
    np.testing.assert_array_equal(held.q_dot_posture, np.zeros(4))
    for a, b in zip(held, explicit, strict=True):
        np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match=r"q_ref must have shape \(4,\)"):
        c.solve(state, xi_des, None, np.zeros(3))


def test_heading_error_is_wrapped(robot, controllers, rng):
    c = controllers["qpoases"]
    state = random_states(robot, rng, 1)[0]
    xi = c.model.task(state)
    for offset, expected in [(2 * np.pi - 0.1, -0.1), (-2 * np.pi + 0.1, 0.1), (np.pi, np.pi)]:
        qp = c.qp_data(state, xi + np.r_[0, 0, offset, 0, 0, 0])
        assert qp.xi_dot_des[2] == pytest.approx(c.params.kp[2] * expected, abs=1e-9)


def test_unconstrained_step_is_weighted_least_squares(robot, controllers, rng):
    c = build_controller(robot, controllers["qpoases"].settings)
    P = c.params
    c.set_params(
        P._replace(qdot_max=np.full(6, 1e6), q_min=np.full(4, -1e6), q_max=np.full(4, 1e6))
    )
    for state in random_states(robot, rng, 20):
        ref = random_reference(robot, c, state, rng)
        res = c.solve(state, *ref)
        H, g, _, xdd, qdp = numpy_qp(robot, P, state, c.settings.base_offset, *ref)
        expected = np.linalg.solve(H, -g)
        assert res.success
        np.testing.assert_allclose(res.qdot, expected, rtol=1e-6, atol=1e-7)
        J, W_A = numpy_jacobian(robot, state, c.settings.base_offset), np.diag(P.w_a)
        r, r_q = xdd - J @ res.qdot, res.qdot[2:] - qdp
        cost = 0.5 * r @ W_A @ r + 0.5 * res.qdot @ np.diag(P.w_b) @ res.qdot
        cost += 0.5 * r_q @ (P.posture_weight * r_q)
        assert res.objective == pytest.approx(cost, rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("plugin", PLUGINS)
def test_limits_never_exceeded(robot, controllers, rng, plugin):
    """Random states (some on or just past a limit) and far references: limits hold to 1e-9."""
    c = controllers[plugin]
    dt, qdot_max = c.settings.dt, c.params.qdot_max
    states = random_states(robot, rng, 150)
    lo, hi = robot.joint_lower, robot.joint_upper
    k = rng.integers(0, 4, 100)
    states[:50, 5 + k[:50]] = np.where(rng.random(50) < 0.5, lo[k[:50]], hi[k[:50]])  # on a limit
    past = rng.uniform(0, 0.9, 50) * qdot_max[2 + k[50:]] * dt  # past it, recoverable in one step
    states[50:100, 5 + k[50:]] = np.where(
        rng.random(50) < 0.5, lo[k[50:]] - past, hi[k[50:]] + past
    )
    active = 0
    for state in states:
        xi_des = c.model.task(state) + rng.normal(0, 2.0, 6)
        q_ref = rng.uniform(lo - 1.0, hi + 1.0)  # posture targets also beyond the limits
        res = c.solve(state, xi_des, rng.normal(0, 1.0, 6), q_ref, rng.normal(0, 5.0, 4))
        assert res.success, res.status
        assert np.all(np.abs(res.qdot) <= qdot_max + 1e-9)
        q_next = state[5:9] + res.qdot[2:] * dt
        assert np.all(q_next >= lo - 1e-9) and np.all(q_next <= hi + 1e-9)
        active += np.any(np.isclose(np.abs(res.qdot), qdot_max, rtol=0, atol=1e-9))
    assert active > 50  # the test exercises saturated speeds, not only interior solutions


def test_plugins_agree_and_match_their_own_status(robot, controllers, rng):
    states = random_states(robot, rng, 60)
    # OSQP: first order
    tol = {"qpoases": 1e-9, "qrqp": 1e-9, "daqp": 1e-9, "box": 1e-9, "osqp": 1e-5}
    for state in states:
        step_ref = random_reference(robot, controllers["qpoases"], state, rng)
        ref = controllers["qpoases"].solve(state, *step_ref)
        for plugin, c in controllers.items():
            res, direct = c.solve(state, *step_ref), c.solve_direct(state, *step_ref)
            assert res.success and direct.success
            np.testing.assert_allclose(res.qdot, ref.qdot, atol=tol[plugin], err_msg=plugin)
            np.testing.assert_allclose(direct.qdot, res.qdot, atol=tol[plugin], err_msg=plugin)


# ------------------------------------------------------------------------------- failures
def test_nonfinite_state_or_reference_holds_still(robot, controllers, rng):
    for c in controllers.values():
        state = random_states(robot, rng, 1)[0]
        xi = c.model.task(state)
        before = c.failures
        bad_state = state.copy()
        bad_state[6] = np.nan
        bad_ref = xi.copy()
        bad_ref[4] = np.inf
        bad_posture = StepReference(
            xi, np.zeros(6), np.r_[1.0, np.nan, 0.0, 0.0], np.zeros(4), np.zeros(3)
        )
        for s, r in [(bad_state, (xi,)), (state, (bad_ref,)), (state, bad_posture)]:
            res = c.solve(s, *r)
            assert res.status is QPStatus.NONFINITE_INPUT and not res.success
            np.testing.assert_array_equal(res.qdot, np.zeros(6))
            assert c.solve_direct(s, *r).status is QPStatus.NONFINITE_INPUT
        assert c.failures == before + 3
        assert c.solve(state, xi + 0.01).success  # and it recovers once the input is sane


def test_infeasible_bounds_hold_still(robot, controllers, rng):
    for c in controllers.values():
        state = random_states(robot, rng, 1)[0]
        xi = c.model.task(state) + 0.1
        far = state.copy()  # joint 1 beyond its limit by more than one step can undo
        far[6] = robot.joint_upper[1] + 2 * c.params.qdot_max[3] * c.settings.dt
        res = c.solve(far, xi)
        assert res.status is QPStatus.INFEASIBLE and np.all(res.qdot == 0)
        assert c.solve_direct(far, xi).status is QPStatus.INFEASIBLE
    # contradictory position bounds given as parameters
    c = build_controller(robot, controllers["qrqp"].settings)
    c.set_params(c.params._replace(q_min=robot.joint_upper, q_max=robot.joint_lower))
    res = c.solve(state, xi)
    assert res.status is QPStatus.INFEASIBLE and np.all(res.qdot == 0) and c.failures == 1


def test_solver_failure_is_caught_by_status_not_exception(robot, settings, rng):
    """OSQP stopped after one iteration: the certificate and the plugin's status both say so."""
    s = dataclasses.replace(
        settings, plugin="osqp", osqp=dataclasses.replace(settings.osqp, max_iter=1)
    )
    c = build_controller(robot, s)
    state = random_states(robot, rng, 1)[0]
    xi_des = c.model.task(state) + 0.3
    res = c.solve(state, xi_des)
    assert res.status is QPStatus.SOLVER_FAILED and np.all(res.qdot == 0) and c.failures == 1
    assert c.solve_direct(state, xi_des).status is QPStatus.SOLVER_FAILED


# ------------------------------------------------------------------------------ closed loop
def _flat_run(tmp_path, w_heading, goal, seconds=4.0):
    flat = load_problem(
        write_problem(tmp_path, lambda p, r: p["terrain"].__setitem__("slope", 0.0))
    )
    robot = flat.robot
    s = ControllerSettings.from_section(flat.section("controller"))
    s = dataclasses.replace(s, feedforward=False, w_a=(*s.w_a[:2], w_heading, *s.w_a[3:]))
    # Eq. 7 alone (no posture task): a constant ξ target fixes no arm posture, and where the
    # base heading is free (w_heading = 0) no posture would agree with it anyway
    s = dataclasses.replace(s, posture_weight=(0.0,) * 4)
    c = build_controller(robot, s)
    state = np.r_[0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.5, 0.5, -0.2]
    xi_des = c.model.task(goal)
    errors = []
    for _ in range(int(seconds / s.dt)):
        errors.append(xi_des - c.model.task(state))
        res = c.solve(state, xi_des)
        assert res.success
        state = c.model.integrate(state, res.qdot, s.dt)
    return c, state, np.array(errors)


GOAL = np.r_[0.3, 0.1, 0.2, 0.0, 0.0, 2.0, 0.4, -0.6, 0.3]  # base 0.3 m ahead, 0.1 m left


def test_closed_loop_on_flat_floor_converges(tmp_path):
    """Base point + arm CoM (heading row weighted 0): every row is controllable, error -> 0."""
    c, _, e = _flat_run(tmp_path, 0.0, GOAL)
    err = np.linalg.norm(np.delete(e, 2, axis=1), axis=1)
    assert err[-1] < 1e-6 * err[0]
    after = err[int(0.5 / c.settings.dt) :]  # after the 0.5 s transient (speed saturation)
    after = after[after > 1e-9]  # above round-off
    assert after.size > 1000 and np.all(np.diff(after) < 0)


def test_closed_loop_with_heading_row_stops_where_j_cannot_correct(tmp_path, settings):
    """With the heading row the base has 3 task rows and 2 sprockets: J has rank 5, so a
    constant target is tracked until what is left lies in J's left null space (Jᵀ W_A e = 0)."""
    c, state, e = _flat_run(tmp_path, settings.w_a[2], GOAL)
    J = c.model.jacobian(state)
    assert np.linalg.matrix_rank(J) == 5
    assert np.linalg.norm(e[-1]) < 0.5 * np.linalg.norm(e[0])
    JtWe = J.T @ (np.array(c.settings.w_a) * e[-1])
    assert np.linalg.norm(JtWe) < 1e-6 * np.linalg.norm(e[-1])


def test_posture_task_alone_converges_to_a_constant_posture(robot, settings, rng):
    """W_A = 0 on the CoM rows: only the posture task moves the arm, and the arm columns of
    the QP decouple: q̇_arm = W_q/(W_q + W_B) K_q (q_ref − q), a geometric decay per step."""
    s = dataclasses.replace(settings, w_a=(*settings.w_a[:3], 0.0, 0.0, 0.0))
    c = build_controller(robot, s)
    P = c.params
    q_ref = np.array([2.0, 0.3, -0.5, 0.2])
    state = np.r_[0.3, -1.2, 0.4, 0.0, 0.0, q_ref + rng.uniform(-0.5, 0.5, 4)]
    xi_des = c.model.task(state)  # the base stays put; the CoM rows have no weight
    e0 = q_ref - state[5:9]
    steps = int(round(2.0 / s.dt))
    for _ in range(steps):
        res = c.solve(state, xi_des, np.zeros(6), q_ref, np.zeros(4))
        assert res.success
        state = c.model.integrate(state, res.qdot, s.dt)
    rate = P.posture_weight / (P.posture_weight + P.w_b[2:]) * P.posture_gain  # [1/s]
    np.testing.assert_allclose(q_ref - state[5:9], e0 * (1 - rate * s.dt) ** steps, atol=1e-12)
    assert np.abs(q_ref - state[5:9]).max() < 1e-3 * np.abs(e0).max()  # converged


# -------------------------------------------------------------------------------- settings
@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (lambda c: c.__setitem__("duration", 1e-4), "controller.duration"),
        (lambda c: c.__setitem__("kp", [5.0, 5.0, 5.0, 5.0, 5.0, 2000.0]), "controller.kp"),
        (lambda c: c.__setitem__("plugin", "quadprog"), "controller.plugin"),
        (lambda c: c["w_b"].__setitem__(2, 0.0), "controller.w_b[2]"),
        (lambda c: c["osqp"].__setitem__("eps_abs", -1.0), "controller.osqp.eps_abs"),
        (
            lambda c: c.__setitem__("posture_gain", [5.0, 5.0, 5.0, 2000.0]),
            "controller.posture_gain",
        ),
        (lambda c: c["posture_weight"].__setitem__(1, -1.0), "controller.posture_weight[1]"),
        (lambda c: c.__setitem__("approach_time", -1.0), "controller.approach_time"),
    ],
)
def test_bad_controller_settings_name_the_field(tmp_path, edit, field):
    path = write_problem(tmp_path, lambda p, r: edit(p["controller"]))
    with pytest.raises(ConfigError) as err:
        load_problem(path)
    assert err.value.field == field


def test_step_function_interface(controllers):
    for plugin, c in controllers.items():
        assert c.step.name_in() == ["state", "reference", "params"]
        assert c.step.name_out() == ["qdot", "status", "objective"]
        assert c.step.size_in(1) == (REFERENCE_SIZE, 1)
        assert c.step.size_in(2) == (len(c.params.pack()), 1) == (PARAMS_SIZE, 1)
        assert (plugin in CODEGEN_PLUGINS) == (plugin != "qpoases")
    fields = ControllerParams.unpack(np.arange(float(PARAMS_SIZE)))
    np.testing.assert_array_equal(np.concatenate([np.atleast_1d(f) for f in fields]), np.arange(42))
    assert fields.posture_weight.tolist() == [22, 23, 24, 25]  # after kp, w_a, w_b, posture_gain
    ref = StepReference.unpack(np.arange(float(REFERENCE_SIZE)))
    assert ref.q_ref.tolist() == [12, 13, 14, 15] and REFERENCE_SIZE == 23
    assert ref.ground.tolist() == [20, 21, 22]
    rows = np.arange(46.0).reshape(2, 23)  # (N, 23) tables split on the last axis
    np.testing.assert_array_equal(StepReference.unpack(rows).pack(), rows)


# ------------------------------------------------------------------------------ references
def test_references_rates_match_finite_differences(problem, rng):
    circle, h = problem.circle, 1e-6
    plan = SimpleNamespace(
        fractions=np.sort(rng.uniform(0, 1, 7)), target_com=rng.uniform(-0.5, 0.5, (7, 3))
    )
    terrain = problem.terrain
    arm = arm_reference(plan, circle, terrain)
    s = rng.uniform(0, 1, 20)
    base = lambda u: base_reference(circle, terrain, u, 0.2)  # noqa: E731
    for fn in (base, arm, lambda u: circle_pose(circle, u)):
        value, rate = fn(s)
        fd = (fn(s + h).value - fn(s - h).value) / (2 * h)
        np.testing.assert_allclose(rate, fd, atol=1e-6)
    # the arm reference passes through the plan's targets placed at the reference poses
    poses = circle.pose_at(plan.fractions)
    expected = np.stack(
        [np.r_[p[:2], 0.0] + rot_z(p[2]) @ g for p, g in zip(poses, plan.target_com, strict=True)]
    )
    np.testing.assert_allclose(arm(plan.fractions).value, expected, atol=1e-12)
    np.testing.assert_allclose(arm(1.0).value, arm(0.0).value, atol=1e-12)  # periodic
    q = rng.uniform(problem.robot.joint_lower, problem.robot.joint_upper, (7, 4))
    posture = posture_reference(plan.fractions, q, problem.robot.joint_lower, [7.0, 2, 2.9, 2.2])
    ref = task_reference(circle, terrain, 30.0, 0.2, arm, posture, [0.0, 15.0])
    np.testing.assert_allclose(
        ref.xi_dot_ref, np.hstack([base([0, 0.5]).rate, arm([0, 0.5]).rate]) / 30.0
    )
    # the base point is d ahead of the reference pose along its heading (hand computation)
    p = circle.pose_at([0.0, 0.5])
    np.testing.assert_allclose(
        ref.xi_des[:, :2], p[:, :2] + 0.2 * np.c_[np.cos(p[:, 2]), np.sin(p[:, 2])], atol=1e-12
    )
    np.testing.assert_array_equal(ref.ground, terrain.local_ground(p))
    np.testing.assert_allclose(ref.q_ref, posture([0, 0.5]).value)
    np.testing.assert_allclose(ref.q_dot_ref, posture([0, 0.5]).rate / 30.0)
    assert ref.pack().shape == (2, REFERENCE_SIZE)


def test_posture_reference_interpolates_the_postures(robot, rng):
    """Periodic spline through the postures, rate = d/ds, within the limits, knots kept."""
    lo, hi = robot.joint_lower, robot.joint_upper
    f = np.sort(rng.uniform(0, 1, 6))
    q = rng.uniform(lo + 0.3, hi - 0.3, (6, 4))
    q[:, 0] = [1.0, 1.5, 2.5, 3.0, 2.0, 1.2]  # turret: no wrap needed, the knots stay as given
    ref = posture_reference(f, q, lo, hi)
    np.testing.assert_allclose(ref(f).value, q, atol=1e-12)
    np.testing.assert_allclose(ref(f + 1.0).value, q, atol=1e-12)  # period 1
    s, h = rng.uniform(0, 1, 30), 1e-6
    value, rate = ref(s)
    inside = np.all((value > lo + 1e-6) & (value < hi - 1e-6), axis=1)
    fd = (ref(s + h).value - ref(s - h).value) / (2 * h)
    np.testing.assert_allclose(rate[inside], fd[inside], atol=1e-6)
    fine = ref(np.linspace(0, 1, 2001)).value
    assert np.all(fine >= lo) and np.all(fine <= hi)
    # a spline overshooting a limit is clipped there, with zero rate
    q[2, 3] = hi[3]
    q[3, 3] = hi[3] - 0.01
    clipped = posture_reference(f, q, lo, hi)(np.linspace(f[2], f[3], 50)[1:-1])
    assert np.isclose(clipped.value[:, 3], hi[3]).sum() > 1
    assert np.all(clipped.rate[np.isclose(clipped.value[:, 3], hi[3]), 3] == 0)


@pytest.mark.parametrize(
    ("turret", "upper", "expected"),
    [
        # short way across 0 rad would leave [0, 2π]: the long way, within the limits
        ([5.9, 0.3], 2 * np.pi, [5.9, 0.3]),
        # angles outside the limits (another branch) are brought in, then the short way
        ([7.0, 7.5], 2 * np.pi, [7.0 - 2 * np.pi, 7.5 - 2 * np.pi]),
        # a wider range (−π to 3π) lets the short way across 0 be taken
        ([1.0, 4.5], 3 * np.pi, [1.0, 4.5 - 2 * np.pi]),
    ],
)
def test_full_turn_joint_is_unwrapped_within_its_limits(turret, upper, expected):
    lower = [-np.pi if upper > 2 * np.pi else 0.0, -0.8, -2.9, -2.2]
    upper4 = [upper, 2.0, 2.9, 2.2]
    q = np.column_stack([turret, np.zeros((2, 3))])
    out = unwrap_postures(q, lower, upper4)
    np.testing.assert_allclose(out[:, 0], expected, atol=1e-12)
    np.testing.assert_array_equal(out[:, 1:], q[:, 1:])
    fine = posture_reference([0.0, 0.5], q, lower, upper4)(np.linspace(0, 1, 501)).value[:, 0]
    assert np.all(fine >= lower[0]) and np.all(fine <= upper4[0])
    assert np.ptp(fine) <= abs(expected[1] - expected[0]) + 1e-12  # no detour beyond the knots


def test_periodic_spline_rejects_bad_knots():
    with pytest.raises(ValueError, match="increase strictly"):
        periodic_spline([0.5, 0.2], np.zeros((2, 3)))
    with pytest.raises(ValueError, match=r"postures \(3, 4\) do not match"):
        posture_reference([0.0, 0.5], np.zeros((3, 4)), np.zeros(4), np.ones(4))
