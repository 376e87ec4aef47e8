"""The reference governor of the closed loop (``physics.governor``): the reference waits for a
base that falls behind, and leaves a base that keeps up alone, to the bit."""

from __future__ import annotations

import dataclasses
import subprocess
import sys

import numpy as np
import pytest
import yaml
from conftest import ROOT

import mmstab
from mmstab import app
from mmstab.control.layout import StepReference
from mmstab.control.reference import initial_state
from mmstab.outputs.simulate import controller_settings, loop_settings
from mmstab.physics.closed_loop import run_closed_loop
from mmstab.physics.governor import GovernorSettings, ReferenceClock, clock_rate

OFFSET = 0.2  # [m]
SLICES = StepReference.offsets(4)


def test_clock_rate_by_hand() -> None:
    g = GovernorSettings(slow=0.2, stop=0.6, wait_limit=1.0)
    assert [clock_rate(e, g) for e in (0.0, 0.2, 0.3, 0.4, 0.6, 2.0)] == pytest.approx(
        [1.0, 1.0, 0.75, 0.5, 0.0, 0.0]
    )
    assert clock_rate(5.0, None) == 1.0


def _table(rng: np.random.Generator, rows: int) -> np.ndarray:
    return rng.normal(size=(rows, StepReference.size(4)))


def _on_its_point(row: np.ndarray, off: float = 0.0, pitch: float = 0.0) -> np.ndarray:
    """A body (M_T_B) whose control point is ``off`` [m] to the left of the row's base
    reference, pitched by ``pitch`` [rad] (its point then sits offset * cos(pitch) ahead)."""
    heading = 0.3
    c, s = np.cos(heading), np.sin(heading)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ np.array(
        [[np.cos(pitch), 0.0, np.sin(pitch)], [0.0, 1.0, 0.0], [-np.sin(pitch), 0.0, np.cos(pitch)]]
    )
    M_T_B = np.eye(4)
    M_T_B[:3, :3] = R
    point = np.r_[row[SLICES["xi_des"]][:2] + [0.0, off], 0.0]
    M_T_B[:3, 3] = point - OFFSET * R[:, 0]
    return M_T_B


def test_a_base_that_keeps_up_gets_the_table_row_for_row(rng) -> None:
    control, errors = _table(rng, 30), _table(rng, 30)
    clock = ReferenceClock(control, errors, OFFSET, GovernorSettings(), dt=0.01)
    assert clock.max_steps == 29 + 1000
    for k in range(30):
        # 0.249 m off, the body pitched 0.5 rad: its point 0.18 m ahead in plan, not 0.2 m
        c, e = clock.rows(_on_its_point(errors[k], off=0.249, pitch=0.5))
        assert np.array_equal(c, control[k]) and np.array_equal(e, errors[k])
        assert clock.done == (k == 29) and not clock.stalled(k)
        clock.advance()


def test_a_base_behind_slows_the_reference_and_its_rates(rng) -> None:
    control, errors = _table(rng, 10), _table(rng, 10)
    x, h = SLICES["xi_des"].start, SLICES["xi_des"].start + 2
    for t in (control, errors):  # the base reference along x, 1 cm a row; the heading
        t[:, x : x + 2] = np.c_[0.01 * np.arange(10), np.zeros(10)]  # crosses +-pi
        t[:, h] = np.angle(np.exp(1j * (np.pi - 0.02 + 0.05 * np.arange(10))))
    clock = ReferenceClock(control, errors, OFFSET, GovernorSettings(0.25, 0.5, 0.1), dt=0.01)
    clock.rows(_on_its_point(errors[0], off=0.375))  # halfway from slow to stop
    assert clock.rate == pytest.approx(0.5)
    clock.advance()
    assert clock.row == pytest.approx(0.5)
    c, e = clock.rows(_on_its_point(errors[0], off=0.375))  # 0.375 m sideways, 5 mm back
    assert clock.rate == pytest.approx((0.5 - np.hypot(0.375, 0.005)) / 0.25)
    mid, r = 0.5 * (errors[0] + errors[1]), clock.rate
    rates = np.r_[np.arange(SLICES["xi_dot_ref"].start, SLICES["xi_dot_ref"].stop),
                  np.arange(SLICES["q_dot_ref"].start, SLICES["q_dot_ref"].stop)]  # fmt: skip
    still = np.setdiff1d(np.arange(len(mid)), np.r_[rates, h])
    assert e[still] == pytest.approx(mid[still], abs=1e-12)
    assert e[rates] == pytest.approx(r * mid[rates], abs=1e-12)
    assert c[rates] == pytest.approx(r * 0.5 * (control[0] + control[1])[rates], abs=1e-12)
    # the heading the short way across +-pi: 0.025 rad past row 0's, not back through zero
    assert np.angle(np.exp(1j * (e[h] - errors[0, h]))) == pytest.approx(0.025, abs=1e-12)


def test_a_base_that_never_comes_stalls_after_the_wait_limit(rng) -> None:
    control, errors = _table(rng, 10), _table(rng, 10)
    clock = ReferenceClock(control, errors, OFFSET, GovernorSettings(0.25, 0.5, 0.05), dt=0.01)
    for k in range(3):  # on time, then stopped 1 m off
        clock.rows(_on_its_point(errors[k]))
        clock.advance()
    for k in range(3, 20):
        c, _ = clock.rows(_on_its_point(errors[3], off=1.0))
        xi = SLICES["xi_des"]
        assert clock.rate == 0.0 and np.array_equal(c[xi], control[3, xi])
        assert np.all(c[SLICES["xi_dot_ref"]] == 0.0)
        assert clock.stalled(k) == (k > 3 + 5)
        clock.advance()
    assert not clock.done


@pytest.fixture(scope="module")
def ramp():
    problem = mmstab.load_problem(ROOT / "problems" / "ramp.yaml")
    cs = controller_settings(problem)
    step = mmstab.control.controller.build_controller(problem.robot, cs).step
    state0 = initial_state(problem.base_path, problem.robot.stowed)
    return problem, app.plan(problem), cs, step, state0


def _run(ramp, duration: float, governor: GovernorSettings | None, track_kv: float | None = None):
    problem, plan, cs, step, state0 = ramp
    loop = dataclasses.replace(loop_settings(problem), duration=duration, governor=governor)
    model = loop.model_settings()
    if track_kv is not None:
        model = dataclasses.replace(model, track_kv=track_kv)
    return run_closed_loop(problem, plan, step, cs, loop, state0, model)


@pytest.mark.mujoco
def test_the_default_governor_leaves_a_run_that_keeps_up_alone(ramp) -> None:
    a, b = _run(ramp, 0.6, GovernorSettings()), _run(ramp, 0.6, None)
    assert np.array_equal(a.state, b.state) and np.array_equal(a.qdot, b.qdot)
    assert np.array_equal(a.base_error, b.base_error)
    assert a.reference_wait_s == 0.0 and a.stalled is None


@pytest.mark.mujoco
def test_weak_tracks_fall_behind_and_the_reference_waits_for_them(ramp) -> None:
    """Track servos at 0.5 % of their gain cannot drive the lap's speed up the ramp: on time
    the base falls 33 cm behind in 4 s; governed, its error stays near ``stop`` (the weak base
    rolls back a little while its reference waits: 11.3 cm) until the reference has waited
    ``wait_limit`` and the run ends stalled."""
    g = GovernorSettings(slow=0.05, stop=0.1, wait_limit=1.0)
    governed, on_time = _run(ramp, 4.0, g, track_kv=10.0), _run(ramp, 4.0, None, track_kv=10.0)
    assert on_time.stalled is None and on_time.base_error.max() > 0.3
    assert governed.base_error.max() < g.stop + 0.02
    assert governed.reference_wait_s == pytest.approx(g.wait_limit, abs=0.01)
    assert governed.stalled == pytest.approx(governed.t[-1]) and governed.t[-1] < 4.0
    assert governed.tipped is None
    # held on its tracks, not its chassis: stuck
    assert governed.stall is not None and governed.stall["cause"] == "stuck"
    assert governed.stall["touching"]["tracks"] == 1.0
    assert governed.stall["chassis_resting"] == 0.0 and on_time.stall is None


def test_the_governor_section_is_checked(tmp_path) -> None:
    data = yaml.safe_load((ROOT / "problems" / "ramp.yaml").read_text())
    data["robot"] = str((ROOT / "problems" / data["robot"]).resolve())
    for governor, ok in (({"slow": 0.5, "stop": 0.3}, False), ({"slow": "x"}, False),
                         (None, True), ({"stop": 0.8}, True)):  # fmt: skip
        data["physics"] = {"governor": governor}
        path = tmp_path / "p.yaml"
        path.write_text(yaml.safe_dump(data))
        if ok:
            s = loop_settings(mmstab.load_problem(path))
            assert s.governor == (None if governor is None else GovernorSettings(stop=0.8))
            continue
        cmd = [sys.executable, "-m", "mmstab", "plan", str(path)]  # (rest checks no physics)
        out = subprocess.run(cmd, capture_output=True, text=True)
        assert out.returncode == 2 and out.stderr.count("\n") == 1, out.stderr
        assert "p.yaml" in out.stderr and "physics.governor" in out.stderr, out.stderr
