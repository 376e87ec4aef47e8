"""Closed-loop tracking: limits, convergence, plant vs J, failures, plugins, experiment, CLI."""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import os
import subprocess
import sys
from types import SimpleNamespace

import casadi as ca
import numpy as np
import pytest
from conftest import write_problem

from mmstab.control.controller import (
    PARAMS_SIZE,
    REFERENCE_SIZE,
    ControllerParams,
    ControllerSettings,
    QPStatus,
    build_controller,
)
from mmstab.control.reference import initial_state
from mmstab.control.tasks import build_task_model
from mmstab.core.files import MmstabError
from mmstab.core.problem import load_problem
from mmstab.runs.tracking import simulate, summarize, task_batch
from mmstab.stability.static import force_angle
from mmstab.terrain import GRAVITY_G

REACHABLE = np.array([2.0, 0.3, -0.5, 0.2])  # an arm posture; its CoM is a reachable target [rad]
SUMMARY_KEYS = {
    "base_error_max_m",
    "base_error_final_m",
    "arm_com_error_max_m",
    "arm_com_error_final_m",
    "qdot_max_abs",
    "qdot_limit",
    "mean_track_speed_left",
    "mean_track_speed_right",
    "mu_min",
    "mu_mean",
    "qp_failures",
    "steps",
    "wall_seconds",
    "plugin",
}
CASES = {"reconfigured", "arm_removed", "stowed"}


def constant_plan(robot, posture):
    """A plan with one arm posture (and its CoM) for the whole lap."""
    q = np.atleast_2d(np.asarray(posture, dtype=float))
    return SimpleNamespace(fractions=np.zeros(1), target_com=robot.arm_com(q), postures=q)


def settings_of(problem, **changes):
    """The problem's controller settings with some fields replaced."""
    settings = ControllerSettings.from_section(problem.section("controller"))
    return dataclasses.replace(settings, **changes)


def posture_plan(robot, k=8):
    """A plan of k postures (link0 swinging about 2 rad) and their FK CoMs."""
    s = np.arange(k) / k
    q = np.column_stack([2.0 + 0.4 * np.sin(2 * np.pi * s), 0.2 + 0.1 * np.cos(2 * np.pi * s)])
    q = np.column_stack([q, np.full(k, -0.3), np.zeros(k)])
    return SimpleNamespace(fractions=s, target_com=robot.arm_com(q), postures=q)


@pytest.fixture(scope="module")
def flat(tmp_path_factory):
    path = write_problem(
        tmp_path_factory.mktemp("flat"), lambda p, r: p["terrain"].__setitem__("slope", 0.0)
    )
    return load_problem(path)


def param_slices():
    edges = np.cumsum((0, *ControllerParams.sizes()))
    names = ControllerParams._fields
    return {n: slice(int(a), int(b)) for n, a, b in zip(names, edges[:-1], edges[1:], strict=True)}


def window_step(problem, inner, t0, t1, make_bad):
    """Wrap a step Function: inside t0 <= t < t1 (read from ξ_des's x row) return make_bad(...).

    The reference's base x increases over the first quarter lap of the default circle, so a
    window on it is a window in time.
    """
    s = ca.MX.sym("state", 9)
    ref = ca.MX.sym("reference", REFERENCE_SIZE)
    p = ca.MX.sym("params", PARAMS_SIZE)
    settings = ControllerSettings.from_section(problem.section("controller"))
    from mmstab.control.reference import base_reference

    x0, x1 = base_reference(
        problem.circle,
        problem.terrain,
        np.array([t0, t1]) / settings.lap_time,
        settings.base_offset,
    ).value[:, 0]
    inside = ca.logic_and(ref[0] >= x0, ref[0] < x1)
    good = inner(s, ref, p)
    bad = make_bad(s, ref, p)
    outs = [ca.if_else(inside, b, g) for b, g in zip(bad, good, strict=True)]
    return ca.Function("faulty_step", [s, ref, p], outs), (x0, x1)


# -------------------------------------------------------------------------------- limits
def test_limits_never_exceeded_over_a_run(problem):
    """A posture on the joint limits as a step (no approach), and the base 0.5 m off its
    path, drive joints onto their limits and speeds to 4π."""
    robot = problem.robot
    lo, hi = robot.joint_lower, robot.joint_upper
    on_limits = np.array([hi[0], lo[1], lo[2], hi[3]])
    x, y, heading = problem.circle.pose_at(0.0)[0]
    state0 = np.r_[
        x - 0.5 * np.sin(heading), y + 0.5 * np.cos(heading), heading, 0, 0, robot.stowed
    ]
    run = simulate(
        problem,
        constant_plan(robot, on_limits),
        duration=1.0,
        progress=False,
        state0=state0,
        settings=settings_of(problem, approach_time=0.0),
    )
    assert run.failures == ()
    assert np.all(np.abs(run.qdot) <= run.qdot_limit + 1e-9)
    q = run.state[:, 5:]
    assert np.all(q >= robot.joint_lower - 1e-9) and np.all(q <= robot.joint_upper + 1e-9)
    # the limits are active, so the test can fail: speed saturation and joints on a limit
    saturated = np.isclose(np.abs(run.qdot), run.qdot_limit, rtol=0, atol=1e-9)
    assert saturated[:, :2].any() and saturated[:, 2:].any()
    on_limit = np.isclose(q, robot.joint_lower, atol=1e-9) | np.isclose(
        q, robot.joint_upper, atol=1e-9
    )
    # upper arm and wrist are driven onto their limits (the others approach theirs as e^-Kt)
    assert on_limit[1:, [1, 3]].sum(axis=0).min() > 100


# ---------------------------------------------------------------------------- convergence
def test_flat_floor_arm_com_error_converges(flat):
    """Eq. 7 alone (no posture task), reachable constant target, arm from stowed as a step:
    after the saturated transient the arm-CoM error decreases strictly."""
    robot = flat.robot
    run = simulate(
        flat,
        constant_plan(robot, REACHABLE),
        duration=3.0,
        progress=False,
        settings=settings_of(flat, approach_time=0.0, posture_weight=(0.0,) * 4),
    )
    e = run.arm_com_error
    saturated = np.isclose(np.abs(run.qdot), run.qdot_limit, rtol=0, atol=1e-9).any(axis=1)
    assert saturated.any()  # a real transient: the arm starts 0.5 m away, speeds saturate
    transient_end = np.flatnonzero(saturated)[-1] + 1
    assert np.all(np.diff(e[transient_end:]) < 0)
    assert e[-1] < 1e-5 * e[0]
    assert run.base_error.max() < 0.05 and run.base_error[-1] < 1e-4


def test_flat_floor_posture_and_arm_com_converge_together(flat):
    """With the posture task the arm converges to the planned posture and its CoM; the CoM
    error is no longer monotone (the two tasks' transients differ) but both vanish."""
    robot = flat.robot
    run = simulate(
        flat,
        constant_plan(robot, REACHABLE),
        duration=3.0,
        progress=False,
        settings=settings_of(flat, approach_time=0.0),
    )
    e, q_err = run.arm_com_error, np.abs(run.posture_error).max(axis=1)
    assert e[-1] < 2e-4 * e[0] and q_err[-1] < 5e-3 * q_err[0]
    last = run.t >= 2.0
    assert np.all(np.diff(q_err[last]) < 0) and e[last].max() < 2e-3 * e[0]
    np.testing.assert_allclose(run.q_ref, np.broadcast_to(REACHABLE, run.q_ref.shape))


# -------------------------------------------------------------------------------- the plant
def test_simulated_motion_matches_the_jacobian(problem):
    """Recorded states are the exact-arc plant; Δξ/dt = J q̇ at mid-step to O(dt²)."""
    robot = problem.robot
    base = ControllerSettings.from_section(problem.section("controller"))
    plan = posture_plan(robot)
    worst = []
    for dt in (1e-3, 5e-4):
        settings = dataclasses.replace(base, dt=dt)
        run = simulate(problem, plan, duration=0.4, progress=False, settings=settings)
        model = build_task_model(robot, settings.base_offset)
        k = np.arange(0, run.steps, 7)
        for i in k[:40]:  # the plant: exact arc for the base, q̇ dt for the joints
            np.testing.assert_allclose(
                run.state[i + 1], model.integrate(run.state[i], run.qdot[i], dt), atol=1e-12
            )
            chord, mid = run.state[i + 1, :2] - run.state[i, :2], run.state[i : i + 2, 2].mean()
            assert abs(chord @ [-np.sin(mid), np.cos(mid)]) < 1e-13  # no sideways motion
        np.testing.assert_allclose(run.xi[k], [model.task(s) for s in run.state[k]], atol=1e-12)
        rates = np.diff(run.xi, axis=0) / dt
        err = [
            np.abs(
                rates[i]
                - model.jacobian(model.integrate(run.state[i], run.qdot[i], dt / 2)) @ run.qdot[i]
            ).max()
            for i in range(run.steps)
        ]
        worst.append(max(err))
        assert worst[-1] < 1e-3 * np.abs(rates).max()
    assert 3.5 < worst[0] / worst[1] < 4.5  # second order in dt: the midpoint rate is J q̇


def test_task_batch_matches_the_casadi_task(problem, rng):
    robot = problem.robot
    model = build_task_model(robot, 0.2)
    states = np.column_stack(
        [
            rng.uniform(-2, 2, (20, 3)),
            rng.uniform(-9, 9, (20, 2)),
            rng.uniform(robot.joint_lower, robot.joint_upper, (20, 4)),
        ]
    )
    xi, com = task_batch(model, problem.terrain, states)
    np.testing.assert_allclose(xi, [model.task(s) for s in states], atol=1e-12)
    # independent: the ramp's placement by hand, [x, y, 0] + Rz(γ) g_a^B and the point d ahead
    c, s = np.cos(states[:, 2]), np.sin(states[:, 2])
    g = robot.arm_com(states[:, 5:])
    np.testing.assert_allclose(xi[:, 0], states[:, 0] + 0.2 * c, atol=1e-12)
    np.testing.assert_allclose(xi[:, 4], states[:, 1] + s * g[:, 0] + c * g[:, 1], atol=1e-12)
    np.testing.assert_allclose(xi[:, 5], g[:, 2], atol=1e-12)
    np.testing.assert_allclose(com, robot.arm_com(states[:, 5:]), atol=1e-12)


def test_stability_matches_force_angle_in_the_global_frame(problem):
    """μ of the three cases against the force angle computed in G from G_T_B."""
    robot, ramp = problem.robot, problem.terrain
    run = simulate(problem, posture_plan(robot), duration=0.3, progress=False)
    pts_B = robot.base.support_points()
    for k in (0, 150, 300):
        T = ramp.G_T_B(run.state[k, :3])
        pts_G = pts_B @ T[:3, :3].T + T[:3, 3]
        cases = {
            "reconfigured": (robot.total_mass, robot.overall_com(run.arm_com_body[k])),
            "stowed": (robot.total_mass, robot.overall_com(robot.arm_com(robot.stowed))),
            "arm_removed": (robot.base.mass, robot.base.com),
        }
        for name, (mass, com_B) in cases.items():
            expected = force_angle(pts_G, T[:3, :3] @ com_B + T[:3, 3], mass * GRAVITY_G)
            assert getattr(run.mu, name)[k] == pytest.approx(expected, rel=1e-9), name


# ------------------------------------------------------------------------------- failures
def test_injected_qp_failure_is_recorded_and_holds_still(problem):
    """Contradictory joint bounds for t in [0.1, 0.15) s: INFEASIBLE, state held, recovery."""
    robot = problem.robot
    ctrl = build_controller(robot, ControllerSettings.from_section(problem.section("controller")))
    sl = param_slices()

    def swapped(s, ref, p):  # q_min <-> q_max: every arm joint's bounds contradict
        p_bad = ca.vertcat(p[: sl["q_min"].start], p[sl["q_max"]], p[sl["q_min"]])
        return ctrl.step(s, ref, p_bad)

    faulty, (x0, x1) = window_step(problem, ctrl.step, 0.1, 0.15, swapped)
    plan = posture_plan(robot)
    kw = {"duration": 1.0, "progress": False, "initial_arm": "planned"}  # tracking from t = 0
    run = simulate(problem, plan, step=faulty, **kw)
    ref_x = run.xi_des[:-1, 0]
    expected = np.flatnonzero((ref_x >= x0) & (ref_x < x1))
    assert 45 <= expected.size <= 55  # ~50 periods of 1 ms
    assert [f.step for f in run.failures] == expected.tolist()
    assert all(f.status is QPStatus.INFEASIBLE for f in run.failures)
    assert [f.time for f in run.failures] == pytest.approx(run.t[expected].tolist())
    np.testing.assert_array_equal(run.qdot[expected], 0.0)
    np.testing.assert_array_equal(run.state[expected + 1], run.state[expected])  # held
    assert np.all(run.status[expected[-1] + 1 :] == QPStatus.SUCCESS)
    assert summarize(run)["qp_failures"] == expected.size
    clean = simulate(problem, plan, **kw)
    assert clean.failures == () and clean.arm_com_error.max() < 1e-3
    held = expected[-1] + 1  # while held the reference runs away: ~0.3 m/s for 50 ms
    assert run.arm_com_error[held] > 10 * clean.arm_com_error[held]
    assert run.base_error[held] > 0.01
    # and it recovers (K_p = 5/s: the error falls by e^-4 in 0.8 s)
    assert run.arm_com_error[-1] < 0.05 * run.arm_com_error[held]
    assert run.base_error[-1] < 0.05 * run.base_error[held]


def test_failure_status_holds_still_whatever_the_step_returns(problem):
    """A backend that reports failure with a NaN q̇ is held still by the simulation itself."""
    robot = problem.robot
    ctrl = build_controller(robot, ControllerSettings.from_section(problem.section("controller")))

    def nan_failed(s, ref, p):
        out = ctrl.step(s, ref, p)
        return [ca.MX.nan(6, 1), ca.MX(float(QPStatus.SOLVER_FAILED)), out[2]]

    faulty, _ = window_step(problem, ctrl.step, 0.1, 0.12, nan_failed)
    run = simulate(problem, posture_plan(robot), step=faulty, duration=0.3, progress=False)
    steps = [f.step for f in run.failures]
    assert 15 <= len(steps) <= 25
    assert all(f.status is QPStatus.SOLVER_FAILED for f in run.failures)
    np.testing.assert_array_equal(run.state[np.array(steps) + 1], run.state[steps])
    assert np.all(np.isfinite(run.state))


def test_nan_state_stops_the_run_with_a_clear_error(problem):
    robot = problem.robot
    plan = posture_plan(robot)
    state0 = np.r_[problem.circle.pose_at(0.0)[0], 0.0, 0.0, robot.stowed]
    state0[6] = np.nan
    with pytest.raises(MmstabError, match=r"initial state is not finite \(theta_1\)"):
        simulate(problem, plan, duration=0.1, progress=False, state0=state0)
    # a backend that claims success with a NaN q̇ from t = 0.1 s: the state turns NaN, run stops
    ctrl = build_controller(robot, ControllerSettings.from_section(problem.section("controller")))

    def nan_success(s, ref, p):
        qdot = ca.vertcat(ca.MX(0.0), ca.MX.nan(), ca.MX.zeros(4))
        return [qdot, ca.MX(0.0), ca.MX(0.0)]

    faulty, (x0, _) = window_step(problem, ctrl.step, 0.1, 0.2, nan_success)
    with pytest.raises(MmstabError, match=r"non-finite at t = 0\.10\d* s .*theta_r") as err:
        simulate(problem, plan, step=faulty, duration=0.3, progress=False)
    assert "x, y, heading" in str(err.value)  # the right sprocket moves the base pose too


def test_step_signature_is_checked(problem):
    x = ca.MX.sym("x", 9)
    wrong = ca.Function("wrong", [x], [x[:6]])
    with pytest.raises(MmstabError, match="expected"):
        simulate(problem, posture_plan(problem.robot), step=wrong, duration=0.1, progress=False)


@pytest.mark.parametrize(
    ("plan_edit", "message"),
    [
        (lambda p: setattr(p, "fractions", np.array([0.5, 0.2])), "increase strictly"),
        (lambda p: setattr(p, "target_com", np.zeros((3, 3))), "do not match"),
        (lambda p: setattr(p, "fractions", np.full(p.fractions.size, np.nan)), "finite"),
    ],
)
def test_bad_plan_is_rejected_at_the_boundary(problem, plan_edit, message):
    plan = SimpleNamespace(**posture_plan(problem.robot).__dict__)
    plan.fractions = plan.fractions[:2]
    plan.target_com = plan.target_com[:2]
    plan_edit(plan)
    with pytest.raises(MmstabError, match=message):
        simulate(problem, plan, duration=0.1, progress=False)


# -------------------------------------------------------------------------------- plugins
def test_qpoases_and_osqp_give_the_same_trajectory(problem):
    plan = posture_plan(problem.robot)
    kw = {"duration": 0.5, "progress": False, "settings": settings_of(problem, approach_time=0.0)}
    a = simulate(problem, plan, plugin="qpoases", **kw)
    b = simulate(problem, plan, plugin="osqp", **kw)
    assert a.failures == () and b.failures == ()
    assert np.abs(a.qdot).max(axis=0)[2] == pytest.approx(a.qdot_limit[2])  # saturated start
    np.testing.assert_allclose(b.qdot, a.qdot, atol=1e-5)  # OSQP: first-order accuracy
    np.testing.assert_allclose(b.state, a.state, atol=1e-7)
    assert (a.plugin, b.plugin) == ("qpoases", "osqp")


def test_planned_start_has_no_transient(problem):
    plan = posture_plan(problem.robot)
    run = simulate(problem, plan, duration=0.5, progress=False, initial_arm="planned")
    np.testing.assert_array_equal(run.state[0, 5:], plan.postures[0])
    assert run.arm_com_error[0] < 1e-12 and run.arm_com_error.max() < 1e-3
    assert np.abs(run.qdot[:, 2:]).max() < 0.5 * run.qdot_limit[2]  # no saturation


# ----------------------------------------------------------------------------- experiment
@pytest.mark.slow
def test_run_tracking_writes_figures_and_summary(problem, tmp_path):
    from mmstab.outputs.tracking import run_tracking

    s = run_tracking(
        problem, tmp_path, plan=posture_plan(problem.robot), duration=0.5, progress=False
    )
    for name in ("fig9.png", "fig10.png", "fig11.png", "fig12.png", "run.npz", "problem.yaml"):
        assert (tmp_path / name).stat().st_size > 0, name
    on_disk = json.loads((tmp_path / "summary.json").read_text())
    assert SUMMARY_KEYS <= set(on_disk) and "arm_self_collision" in on_disk
    assert set(on_disk["mu_min"]) == CASES and set(on_disk["mu_mean"]) == CASES
    assert (
        on_disk["steps"] == 500 and on_disk["plugin"] == "qpoases" and on_disk["qp_failures"] == 0
    )
    # the arm starts stowed and follows the approach, then the posture reference: no contact
    assert on_disk["arm_self_collision"]["colliding_share"] == 0.0
    assert on_disk["approach"]["duration_s"] == problem.section("controller")["approach_time"]
    assert on_disk["approach"]["path"]["colliding_samples"] == 0
    assert on_disk["approach"]["start_posture"] == problem.robot.stowed.tolist()
    assert on_disk["posture_reference"]["reference"]["colliding_samples"] == 0
    assert max(on_disk["posture_error_max_abs_rad"].values()) < 0.05
    assert s["base_error_max_m"] == on_disk["base_error_max_m"]
    data = np.load(tmp_path / "run.npz")
    assert data["t"][0] == 0.0 and data["t"][-1] == pytest.approx(0.5)
    assert data["state"].shape == (data["t"].size, 9)
    assert data["q_ref"].shape == (data["t"].size, 4)
    np.testing.assert_array_equal(data["q_ref"][0], problem.robot.stowed)  # approach start


@pytest.mark.slow
def test_generated_backend_gives_the_interpreted_trajectory(tmp_path):
    """run_tracking(backend="generated") simulates with the compiled step: same run as qrqp."""
    from mmstab.outputs.tracking import run_tracking

    def edit(prob, rob):
        prob["codegen"]["directory"] = str(tmp_path / "gen")

    problem = load_problem(write_problem(tmp_path, edit))
    plan = posture_plan(problem.robot)
    s = run_tracking(
        problem, tmp_path / "out", backend="generated", plan=plan, duration=0.5, progress=False
    )
    assert (s["backend"], s["plugin"]) == ("generated", problem.section("codegen")["plugin"])
    reference = simulate(problem, plan, plugin=s["plugin"], duration=0.5, progress=False)
    run = np.load(tmp_path / "out" / "run.npz")
    np.testing.assert_allclose(run["state"][-1], reference.state[-1], atol=1e-10)
    assert s["arm_com_error_final_m"] == pytest.approx(reference.arm_com_error[-1], abs=1e-12)
    with pytest.raises(MmstabError, match="qpOASES"):
        run_tracking(problem, tmp_path / "out", "qpoases", backend="generated", plan=plan)


@pytest.mark.slow
@pytest.mark.skipif(
    importlib.util.find_spec("mmstab.planner") is None,
    reason="mmstab.planner has not landed: `mmstab track` needs the plan",
)
def test_cli_track_end_to_end(tmp_path):
    problem = write_problem(tmp_path)
    out = tmp_path / "tracking"
    env = {**os.environ, "MPLBACKEND": "Agg"}
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "mmstab",
            "track",
            str(problem),
            "--duration",
            "0.5",
            "-o",
            str(out),
            "--plugin",
            "daqp",
        ],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stderr
    s = json.loads((out / "summary.json").read_text())
    assert SUMMARY_KEYS <= set(s)
    assert s["steps"] == 500 and s["plugin"] == "daqp" and s["qp_failures"] == 0
    assert s["qdot_max_abs"]["link0"] <= s["qdot_limit"]["link0"] + 1e-9
    assert s["arm_com_error_max_m"] < 5e-3  # the approach starts the CoM reference at the arm
    assert "track:" in proc.stdout


def test_arm_collisions_reports_intervals_and_pairs(problem):
    from mmstab.model.collision import CollisionChecker
    from mmstab.runs.tracking.checks import arm_collisions

    robot = problem.robot
    hit = np.array([2.25, -0.41, 0.5, 0.17])  # turret to the left-rear, upper arm down: hits
    checker = CollisionChecker(robot)
    pairs = checker.colliding_pairs(hit)
    assert pairs and not checker.collides(robot.stowed)
    q = np.array([robot.stowed, hit, hit, robot.stowed, robot.stowed])
    t = np.arange(5) * 0.01
    out = arm_collisions(problem.robot, t, q)
    assert out["samples"] == 5 and out["colliding_samples"] == 2
    assert out["colliding_share"] == pytest.approx(0.4)
    assert out["intervals_s"] == [[0.01, 0.03]]
    assert out["pairs"] == {p: 2 for p in pairs}


# --------------------------------------------------------------------- posture reference
@pytest.fixture(scope="module")
def default_plan(problem):
    """The plan with the first release's planner search, which these numbers describe."""
    from conftest import with_first_release_planner

    from mmstab.planner import plan_path

    return plan_path(with_first_release_planner(problem))


@pytest.fixture(scope="module")
def default_posture(problem, default_plan):
    from mmstab.control.posture import build_posture_reference, posture_samples

    s = settings_of(problem)
    return build_posture_reference(problem.robot, default_plan, posture_samples(s.lap_time, s.dt))


@pytest.mark.slow
def test_default_posture_reference_is_collision_free(problem, default_plan, default_posture):
    """The planned postures interpolated collide (s ≈ 0.81-0.87): the via postures repair it."""
    from mmstab.control.reference import periodic_spline
    from mmstab.model.collision import CollisionChecker
    from mmstab.workspace.ik import COM_TOLERANCE

    robot, ref = problem.robot, default_posture
    checker = CollisionChecker(robot)
    planned = ref.planned_check
    assert planned.colliding_samples > 1000 and "upper_arm-track_left" in planned.pairs
    assert any(0.8 < a < b < 0.9 for a, b in planned.intervals)  # between postures 8 and 9
    assert ref.via and ref.check.colliding_samples == 0 and ref.collision_free
    # an independent, finer sampling between the checked points: still free
    s = (np.arange(2 * ref.check.samples) + 0.5) / (2 * ref.check.samples)
    assert not np.any(checker.collides(ref(s).value))
    # the planned postures are kept, and each via posture realises the plan's splined CoM
    np.testing.assert_allclose(ref(default_plan.fractions).value, default_plan.postures, atol=1e-12)
    com = periodic_spline(default_plan.fractions, default_plan.target_com)
    for v in ref.via:
        np.testing.assert_allclose(ref(v.fraction).value[0], v.posture, atol=1e-12)
        assert np.linalg.norm(robot.arm_com(v.posture) - com(v.fraction).value[0]) <= COM_TOLERANCE
        assert not checker.collides(v.posture)
    # the CoM reference is the reference posture's CoM, rate J q̇_ref
    h, s = 1e-6, np.array([0.1, 0.45, 0.84])
    g = ref.com_body(s)
    np.testing.assert_allclose(g.value, robot.arm_com(ref(s).value), atol=1e-15)
    fd = (ref.com_body(s + h).value - ref.com_body(s - h).value) / (2 * h)
    np.testing.assert_allclose(g.rate, fd, atol=1e-6)


def _window_run(problem, plan, posture, settings, t0, t1):
    """The controller's closed loop over [t0, t1] s of the lap, from the reference state."""
    from mmstab.control.reference import task_reference

    ctrl = build_controller(problem.robot, settings)
    t = np.arange(t0, t1, settings.dt)
    ref = task_reference(
        problem.circle,
        problem.terrain,
        settings.lap_time,
        settings.base_offset,
        posture.arm_reference(problem.circle, problem.terrain),
        posture,
        t,
    )
    state = np.r_[problem.circle.pose_at(t0 / settings.lap_time)[0], 0.0, 0.0, ref.q_ref[0]]
    q_arm = [state[5:]]
    for k in range(t.size):
        res = ctrl.solve(state, ref.xi_des[k], ref.xi_dot_ref[k], ref.q_ref[k], ref.q_dot_ref[k])
        assert res.success
        state = ctrl.model.integrate(state, res.qdot, settings.dt)
        q_arm.append(state[5:])
    return np.array(q_arm), ref


def test_short_closed_loop_from_a_planned_posture_stays_collision_free(
    problem, default_plan, default_posture
):
    """2.5 s from the planned posture at s = 0.8 through the stretch where the planned
    interpolation collides: the arm never touches the body. With the unrepaired reference it
    does, and without the posture task (the paper's Eq. 7) it drifts off the postures."""
    from mmstab.control.posture import build_posture_reference
    from mmstab.model.collision import CollisionChecker

    checker = CollisionChecker(problem.robot)
    settings = settings_of(problem)
    t0 = default_plan.fractions[8] * settings.lap_time  # 24 s: a planned posture
    q_arm, ref = _window_run(problem, default_plan, default_posture, settings, t0, t0 + 2.5)
    np.testing.assert_allclose(q_arm[0], default_plan.postures[8], atol=1e-12)
    assert not np.any(checker.collides(q_arm))
    assert np.abs(q_arm[:-1] - ref.q_ref).max() < 0.05  # it follows the posture reference
    without_task = dataclasses.replace(settings, posture_weight=(0.0,) * 4)
    q_free, _ = _window_run(problem, default_plan, default_posture, without_task, t0, t0 + 2.5)
    unrepaired = build_posture_reference(
        problem.robot, default_plan, default_posture.check.samples, repair=False
    )
    q_unrep, _ = _window_run(problem, default_plan, unrepaired, settings, t0, t0 + 2.5)
    assert np.any(checker.collides(q_unrep))
    assert np.abs(q_free[:-1] - ref.q_ref).max() > 0.1  # Eq. 7 alone drifts off the postures


def test_approach_from_stowed_is_collision_free_and_meets_the_lap(problem, default_posture):
    from mmstab.control.approach import build_approach
    from mmstab.model.collision import CollisionChecker

    robot, s = problem.robot, settings_of(problem)
    ap = build_approach(robot, robot.stowed, default_posture, s.approach_time, s.lap_time, s.dt)
    assert ap.planned_check.colliding_samples > 0  # the straight joint path hits a flipper
    assert ap.via and ap.check.colliding_samples == 0
    t = (np.arange(4 * ap.check.samples) + 0.5) * s.approach_time / (4 * ap.check.samples)
    assert not np.any(CollisionChecker(robot).collides(ap.posture(t).value))
    # from the stowed posture at rest to the lap's posture reference, at rest
    start, end = ap.posture([0.0, s.approach_time])
    np.testing.assert_allclose(start[0], robot.stowed, atol=1e-12)
    np.testing.assert_allclose(
        start[1], default_posture(s.approach_time / s.lap_time).value[0], atol=1e-12
    )
    np.testing.assert_allclose(end, 0.0, atol=1e-12)
    # rates are d/dt of the values; the CoM reference is the posture's CoM
    h, tt = 1e-6, np.array([0.2, 0.5, 0.8]) * s.approach_time
    fd = (ap.posture(tt + h).value - ap.posture(tt - h).value) / (2 * h)
    np.testing.assert_allclose(ap.posture(tt).rate, fd, atol=1e-6)
    fd = (ap.com_body(tt + h).value - ap.com_body(tt - h).value) / (2 * h)
    np.testing.assert_allclose(ap.com_body(tt).rate, fd, atol=1e-6)
    np.testing.assert_allclose(ap.com_body(tt).value, robot.arm_com(ap.posture(tt).value))


def test_plan_whose_postures_miss_their_com_is_refused(problem):
    plan = posture_plan(problem.robot)
    plan.target_com = plan.target_com + np.array([0.0, 0.0, 0.01])
    with pytest.raises(MmstabError, match="do not realise target_com"):
        simulate(problem, plan, duration=0.1, progress=False)
    no_postures = SimpleNamespace(fractions=plan.fractions, target_com=plan.target_com)
    with pytest.raises(MmstabError, match="posture task needs postures"):
        simulate(problem, no_postures, duration=0.1, progress=False)


@pytest.mark.slow
def test_look_ahead_point_corrects_a_lateral_offset(problem):
    """docs/controller.md: at the body origin (d = 0) a lateral offset decays only slowly, through
    the path's curvature; the look-ahead point (d = 0.2 m) removes it within seconds."""
    import dataclasses

    from mmstab.control.controller import ControllerSettings
    from mmstab.runs import rollout as ro

    plan = ro.example_plan(problem.robot)
    base = ControllerSettings.from_section(problem.section("controller"))
    state0 = initial_state(problem.circle, plan.postures[0], lateral_offset=0.1)
    error = {}
    for d, duration in ((0.0, 10.0), (0.2, 5.0)):
        settings = dataclasses.replace(base, base_offset=d)
        run = simulate(
            problem, plan, duration=duration, progress=False, state0=state0, settings=settings
        )
        error[d] = run.base_error[-1]
    assert error[0.0] > 0.09  # after 10 s, still the whole 0.1 m
    assert error[0.2] < 1e-3  # after 5 s
