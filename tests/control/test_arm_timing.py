"""The arm's time law (``controller.dynamic_fraction``, :mod:`mmstab.control.timing`)."""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np
import pytest
import yaml
from conftest import ROOT

import mmstab
from mmstab.control.controller import build_controller
from mmstab.control.reference import initial_state, posture_reference
from mmstab.control.timing import (
    STEP,
    build_time_law,
    dynamic_mu,
    real_times,
    reference_motion,
    timed_mu,
)
from mmstab.core.problem import problem_from_dict
from mmstab.outputs.simulate import controller_settings, loop_settings
from mmstab.physics.closed_loop import run_closed_loop
from mmstab.stability.dynamic import robot_mu

#: The swing of random route pair 5 that tipped in MuJoCo: the turret 5.76 -> 2.09 rad with
#: the arm out (shoulder 0.2, elbow 0.24 rad), here in 0.6 s on the ramp's 0.1 rad slope.
ARM_FROM, ARM_TO = [5.76, 0.2, 0.24, 0.0], [2.09, 0.2, 0.24, 0.0]


def ramp(slope: float = 0.1, **controller: object) -> mmstab.Problem:
    data = yaml.safe_load((ROOT / "problems" / "ramp.yaml").read_text())
    data["terrain"]["slope"] = slope
    data["controller"].update(controller)
    return problem_from_dict(data, ROOT / "problems" / "ramp.yaml")


class Standing:
    """A base path that stands still at one pose (x, y, heading) in M."""

    def __init__(self, pose: list[float]):
        self.pose = np.asarray(pose, dtype=float)

    def pose_at(self, u: object) -> np.ndarray:
        return np.tile(self.pose, (np.atleast_1d(np.asarray(u)).size, 1))


class SwingPlan(NamedTuple):
    """A roadmap-like plan: hold ``ARM_FROM``, swing to ``ARM_TO`` in ``swing`` [s]."""

    fractions: np.ndarray
    target_com: np.ndarray
    postures: np.ndarray
    moves: tuple[np.ndarray, ...]


def swing_plan(robot: mmstab.Robot, start: float, swing: float, lap: float) -> SwingPlan:
    q = np.array([ARM_FROM, ARM_FROM, ARM_TO])
    moves = (q[[2, 0]], q[[0, 0]], q[[0, 2]])  # straight moves; the last closes the lap
    f = np.array([0.0, start / lap, (start + swing) / lap])
    return SwingPlan(f, robot.arm_com(q), q, moves)


def turret_swing(problem: mmstab.Problem, swing: float, lap: float = 10.0):
    """The posture reference of one turret swing over [1, 1 + swing] s, at rest elsewhere."""
    robot = problem.robot
    plan = swing_plan(robot, 1.0, swing, lap)
    ref = posture_reference(plan.fractions, plan.postures, robot.joint_lower,
                            robot.joint_upper, linear=True)  # fmt: skip
    return plan, ref


def test_body_accelerations_of_a_turret_swing_by_hand() -> None:
    problem = ramp(slope=0.0)
    _, ref = turret_swing(problem, 0.6)
    tau = np.array([1.1, 1.3, 1.45])  # within the swing, its smoothstep u = tau' / h
    m = reference_motion(problem.robot, Standing([0.3, -0.2, 0.4]), problem.terrain, ref, 10.0, tau)
    u = (tau - 1.0) / 0.6
    delta = ARM_TO[0] - ARM_FROM[0]
    rate = delta * 6 * u * (1 - u) / 0.6  # θ̇ [rad/s]
    acc = delta * 6 * (1 - 2 * u) / 0.6**2  # θ̈ [rad/s^2]
    rho = np.linalg.norm(m.positions[:, 1:, :2] - [0.12, 0.0], axis=2)  # from the turret axis
    want = rho * np.sqrt(acc**2 + rate**4)[:, None]  # tangential and centripetal
    got = np.linalg.norm(m.acceleration[:, 1:], axis=2)  # central differences over STEP
    np.testing.assert_allclose(got, want, rtol=3e-3, atol=1e-9)  # 0.15 % at most
    np.testing.assert_allclose(m.acceleration[:, 1:, 2], 0.0, atol=1e-9)  # a level swing
    assert np.allclose(m.acceleration[:, 0], 0.0)  # the base stands still


@pytest.mark.parametrize("wrench", [None, [0.0, 20.0, -30.0, 1.0, 0.0, 2.0]])
def test_the_dynamic_mu_at_rest_is_the_static_mu(wrench) -> None:
    problem = ramp(slope=0.25)
    robot = problem.robot
    if wrench is not None:
        robot = dataclasses.replace(robot, tool_wrench=np.array(wrench))
    _, ref = turret_swing(problem, 0.6)
    tau = np.linspace(0.0, 10.0, 201)
    m = reference_motion(robot, Standing([0.0, 0.0, 0.7]), problem.terrain, ref, 10.0, tau)
    q = ref(tau / 10.0).value
    static = robot_mu(robot, m.gravity, q)
    np.testing.assert_allclose(dynamic_mu(robot, m, np.zeros_like(m.acceleration)), static,
                               rtol=0, atol=1e-9)  # fmt: skip
    # the reference timed at zero speed (λ → 0): its dynamic μ tends to the static one
    slow = timed_mu(robot, m, np.full_like(tau, 1e-4))
    np.testing.assert_allclose(slow, static, rtol=0, atol=1e-4)
    moving = tau[(tau > 1.0) & (tau < 1.6)]
    assert np.all(np.abs(timed_mu(robot, m, np.ones_like(tau)) - static)[np.isin(tau, moving)]
                  > 0)  # fmt: skip


def test_the_time_law_of_one_swing_meets_the_bound_and_no_more() -> None:
    problem = ramp()
    robot = problem.robot
    plan, ref = turret_swing(problem, 0.6)
    path = Standing([0.0, 0.0, 0.0])  # heading +x_S: the arm swings over the downhill side
    law = build_time_law(robot, path, problem.terrain, ref, 10.0, plan.fractions, 0.5, (0.5, 9.0))
    assert law.factors.size == 3 and law.factors[0] == law.factors[2] == 1.0
    k = law.factors[1]
    assert 0.3 < k < 0.7  # 0.49
    m = reference_motion(robot, path, problem.terrain, ref, 10.0, law.tau)
    static = dynamic_mu(robot, m, np.zeros_like(m.acceleration))
    swing = (law.tau >= 1.0 - 1.5 * STEP) & (law.tau <= 1.6 + 1.5 * STEP)
    bound = 0.5 * static[swing]

    def mu_at(x: float) -> np.ndarray:
        return dynamic_mu(robot, m, x * x * m.acceleration)[swing]

    assert mu_at(1.0).min() < 0 < bound.min()  # at the plan's speed the measure says it tips
    assert np.all(mu_at(k) >= bound)  # slowed by k it keeps half its static μ
    assert np.any(mu_at(1.05 * k) < bound)  # and k is the largest factor that does
    assert law.below_bound == 0 and law.mu_dynamic_min_before < 0 < law.mu_dynamic_min
    # the swing takes 0.6 / k s and the base eases in and out: the lap is longer by more
    assert law.t[-1] - law.tau[-1] > 0.6 / k - 0.6
    # the law's time maps back and forth, and λ is the rate of τ
    t = np.arange(0.0, 25.0, 1e-3)  # over two laps and a bit
    tau, speed = law.nominal(t)
    np.testing.assert_allclose([law.real_time(x) for x in tau[::500]], t[::500], atol=1e-9)
    np.testing.assert_allclose(np.gradient(tau, t)[1:-1], speed[1:-1], atol=5e-4)  # kinks: 3e-4
    assert real_times(np.array([0.0, 1.0]), np.array([0.5, 0.5]))[-1] == pytest.approx(2.0)


@pytest.mark.mujoco
def test_a_fast_turret_swing_tips_in_mujoco_and_not_when_timed() -> None:
    runs = {}
    for fraction in (None, 0.5):
        problem = ramp(lap_time=100.0, duration=4.0, dynamic_fraction=fraction)
        plan = swing_plan(problem.robot, 2.0, 0.6, 100.0)
        cs = controller_settings(problem)
        step = build_controller(problem.robot, cs).step
        state0 = initial_state(problem.base_path, problem.robot.stowed)
        runs[fraction] = run_closed_loop(problem, plan, step, cs, loop_settings(problem), state0)
    off, on = runs[None], runs[0.5]
    # untimed, the swing lifts the uphill track from 2.16 s: the contacts' μ stays <= 0 past
    # physics.tip_hold (about 1 s, then it falls back onto both): a tip; 0.35 rad off rest at 2.5 s
    assert off.timing is None and off.tip_cause == "support lost" and 2.1 < off.tipped < 2.3
    assert off.disagreement is not None and 2.4 < off.disagreement < 2.6
    assert on.timing is not None and on.timing["mu_dynamic_min_before"] < 0
    assert on.tipped is None and np.nanmax(on.tilt_error) < 0.1  # 0.36 rad -> 0.03 rad
    assert on.t[-1] > 4.5  # the run lasts until the reference's nominal 4 s: 5.02 s
