"""The closed-loop simulation: :func:`simulate` (see :mod:`mmstab.runs.tracking`)."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.control.approach import run_reference
from mmstab.control.controller import (
    ARM,
    PLUGINS,
    ControllerParams,
    ControllerSettings,
    QPStatus,
    build_controller,
    quiet_stdout,
)
from mmstab.control.posture import PostureReference
from mmstab.control.reference import initial_state
from mmstab.control.tasks import build_task_model
from mmstab.core.files import MmstabError, UnstableError
from mmstab.core.problem import Problem
from mmstab.model.robot import FloatArray
from mmstab.runs.tracking.backend import StepBackend, as_backend, build_advance
from mmstab.runs.tracking.run import (
    Failure,
    InitialArm,
    Tipping,
    TrackingPlan,
    TrackingRun,
    check_plan,
    state_names,
    task_batch,
)
from mmstab.stability.dynamic import robot_mu
from mmstab.stability.static import robot_force_angle, stability_along
from mmstab.terrain import wrap_angle

_PROGRESS_CHUNK = 500  # steps between progress-bar updates


def _describe_nonfinite(state: FloatArray) -> str:
    names = state_names(len(state) - 5)
    bad = [names[i] for i in np.flatnonzero(~np.isfinite(state))]
    return ", ".join(bad) if bad else "none"


def simulate(
    problem: Problem,
    plan: TrackingPlan,
    *,
    plugin: str | None = None,
    step: ca.Function | StepBackend | None = None,
    duration: float | None = None,
    progress: bool = True,
    initial_arm: InitialArm = "stowed",
    state0: ArrayLike | None = None,
    settings: ControllerSettings | None = None,
    posture: PostureReference | None = None,
) -> TrackingRun:
    """Simulate the tracking controller around the problem's circle.

    Args:
        problem: the problem (robot, ramp, circle, ``controller`` section).
        plan: the arm plan: ``fractions`` (K,), body-frame ``target_com`` (K, 3) [m] and
            ``postures`` (K, 4) [rad] (the posture task's reference).
        plugin: QP plugin (one of :data:`mmstab.control.controller.PLUGINS`); default the problem's.
        step: the controller step to use instead of the interpreted ``Controller.step``: a
            CasADi Function with its signature, or a :class:`StepBackend`.
        duration: simulated time [s]; default the problem's ``controller.duration``.
        progress: show a progress bar (stderr).
        initial_arm: ``stowed`` (default) or ``planned`` (the plan's first posture).
        state0: the initial state (9,) instead of :func:`mmstab.control.reference.initial_state`
            (the path's start pose, the arm as ``initial_arm`` says).
        settings: controller settings instead of the problem's section (``plugin`` still
            overrides their plugin).
        posture: the lap's posture reference, if already built; default
            :func:`mmstab.control.posture.build_posture_reference` of the plan, checked (and
            repaired)
            at every control period of a lap. The start-up approach (``approach_time``) is
            built from the initial arm posture (:func:`mmstab.control.approach.arm_references`).

    Returns:
        The recorded run; it stops at the first sample where the robot would tip over
        (μ < 0 with the arm as it moved; ``tipped`` says when and where).

    Raises:
        UnstableError: the robot would tip over at the initial state.
        MmstabError: bad plan, plugin, duration, step signature or initial state, or a state
            that becomes non-finite during the run (naming the time and the components).
    """
    robot = problem.robot
    if settings is None:
        settings = ControllerSettings.from_section(problem.section("controller"))
        if problem.route is not None:  # a route sets its own period and length (routes.path)
            settings = dataclasses.replace(
                settings, lap_time=problem.route.lap_time, duration=problem.route.duration
            )
    if plugin is not None:
        if plugin not in PLUGINS:
            raise MmstabError(f"unknown QP plugin {plugin!r}; choose one of {PLUGINS}")
        settings = dataclasses.replace(settings, plugin=plugin)
    duration = settings.duration if duration is None else float(duration)
    if not np.isfinite(duration) or duration < settings.dt:
        raise MmstabError(f"duration {duration} s must be at least dt = {settings.dt} s")
    if initial_arm not in ("stowed", "planned"):
        raise MmstabError(f"initial_arm must be 'stowed' or 'planned', got {initial_arm!r}")
    check_plan(plan, robot)
    if state0 is None:
        arm = robot.stowed if initial_arm == "stowed" else np.asarray(plan.postures)[0]
        s0 = initial_state(problem.base_path, arm)
    else:
        s0 = np.asarray(state0, dtype=float)
    if s0.shape != (5 + robot.arm_joints,):
        raise MmstabError(f"initial state must be ({5 + robot.arm_joints},), got {s0.shape}")
    if not np.all(np.isfinite(s0)):
        raise MmstabError(f"initial state is not finite ({_describe_nonfinite(s0)})")

    def mu_of(states: FloatArray) -> FloatArray:  # μ with the arm as it is [N rad]
        gravity = problem.terrain.gravity_body(states[:, :3])
        if robot.tool_wrench is not None:  # payload.wrench: at the tool points
            return robot_mu(robot, gravity, states[:, ARM])
        com = np.atleast_2d(robot.arm_com(states[:, ARM]))
        return robot_force_angle(robot, gravity, com).mu

    def first_tip(chunk: FloatArray) -> int | None:  # first sample with μ < 0 (the robot tips)
        bad = np.flatnonzero(mu_of(chunk) < 0)
        return int(bad[0]) if bad.size else None

    mu0 = mu_of(s0[None])
    if mu0[0] < 0:
        raise UnstableError(
            f"the robot would tip over at t = 0 s, at the start: base at ({s0[0]:.3f}, "
            f"{s0[1]:.3f}) m heading {s0[2]:.3f} rad, mu = {mu0[0]:.4g} N rad"
        )

    t_build = time.perf_counter()
    if step is None:
        controller = build_controller(robot, settings)
        backend = StepBackend(controller.step, "interpreted")
        model = controller.model
    else:
        backend = as_backend(step)
        model = build_task_model(robot, settings.base_offset)
    params = ControllerParams.from_settings(robot, settings).pack()
    steps = max(int(round(duration / settings.dt)), 1)
    t = np.asarray(np.arange(steps + 1) * settings.dt, dtype=np.float64)
    arm, ref = run_reference(
        robot, problem.base_path, problem.terrain, plan, s0[ARM], settings, t, posture
    )
    reference = ref.pack()
    if not np.all(np.isfinite(reference)):
        raise MmstabError("the task reference is not finite")
    advance = build_advance(model, backend.function)
    build_seconds = time.perf_counter() - t_build

    states, qdots, statuses, wall = _run_loop(
        advance,
        s0,
        reference,
        params,
        steps,
        settings.dt,
        progress,
        first_tip,
    )
    t, n = t[: len(states)], len(states)  # shorter when the robot tipped
    ref = ref._replace(**{k: np.asarray(v)[:n] for k, v in ref._asdict().items()})

    xi, com_B = task_batch(model, problem.terrain, states)
    mu = stability_along(robot, problem.terrain, states[:, :3], com_B)
    if robot.tool_wrench is not None:
        mu = mu._replace(reconfigured=mu_of(states))
    failed = np.flatnonzero(statuses != QPStatus.SUCCESS)
    return TrackingRun(
        t=t,
        state=states,
        qdot=qdots,
        status=statuses,
        xi=xi,
        xi_des=ref.xi_des,
        xi_dot_ref=ref.xi_dot_ref,
        q_ref=ref.q_ref,
        posture_error=ref.q_ref - states[:, ARM],
        base_error=np.linalg.norm(ref.xi_des[:, :2] - xi[:, :2], axis=1),
        heading_error=wrap_angle(ref.xi_des[:, 2] - xi[:, 2]),
        arm_com_error=np.linalg.norm(ref.xi_des[:, 3:] - xi[:, 3:], axis=1),
        arm_com_body=com_B,
        mu=mu,
        failures=tuple(Failure(int(k), float(t[k]), QPStatus(int(statuses[k]))) for k in failed),
        posture=arm.posture,
        approach=arm.approach,
        dt=settings.dt,
        lap_time=settings.lap_time,
        qdot_limit=ControllerParams.from_settings(robot, settings).qdot_max,
        q_lower=robot.joint_lower,
        q_upper=robot.joint_upper,
        plugin=settings.plugin,
        backend=backend.name,
        initial_arm=initial_arm if state0 is None else "given",
        wall_seconds=wall,
        build_seconds=build_seconds,
        tipped=None
        if n == steps + 1
        else Tipping(n - 1, float(t[-1]), states[-1, :3].copy(), float(mu.reconfigured[-1])),
    )


def _run_loop(
    advance: ca.Function,
    state0: FloatArray,
    reference: FloatArray,
    params: FloatArray,
    steps: int,
    dt: float,
    progress: bool,
    first_tip: Callable[[FloatArray], int | None] | None = None,
) -> tuple[FloatArray, FloatArray, NDArray[np.int8], float]:
    """The control loop: ``steps`` calls of ``advance`` on buffers bound once.

    Args:
        advance: from :func:`build_advance`.
        state0: initial state (5 + n,), n the arm's joints (9 for the 4-DoF arm).
        reference: packed :class:`~mmstab.control.layout.StepReference` per sample
            (steps+1, 15 + 2n); row k is used in period k.
        params: packed controller parameters (18 + 6n,).
        steps: number of control periods.
        dt: control period [s] (for messages).
        progress: show a progress bar.
        first_tip: states (m, 5 + n) -> index of the first that tips over, or None; checked
            after every chunk of steps: the run stops at that sample (shorter arrays).

    Returns:
        (states (m+1, 5 + n), applied q̇ (m, 2 + n) [rad/s], statuses (m,), wall time [s]), m = steps
        unless the robot tipped.

    Raises:
        MmstabError: the state became non-finite.
    """
    from tqdm import tqdm

    n_state, n_joints = advance.size1_in(0), advance.size1_out(1)
    states = np.empty((steps + 1, n_state))
    qdots = np.empty((steps, n_joints))
    statuses = np.empty(steps, dtype=np.int8)
    states[0] = state0
    s_buf, r_buf, p_buf = state0.copy(), np.zeros(advance.size1_in(1)), params.copy()
    nxt, qd, st, fin = np.zeros(n_state), np.zeros(n_joints), np.zeros(1), np.zeros(1)
    bar = tqdm(total=steps, desc="tracking", unit="step", disable=not progress, leave=False)
    # C-level stdout silenced: the plugin's banner when its memory is set up (qpOASES), and
    # OSQP's polish line
    with quiet_stdout():
        buffer: Any
        buffer, evaluate = advance.buffer()
        for i, a in enumerate((s_buf, r_buf, p_buf)):
            buffer.set_arg(i, memoryview(a))  # type: ignore[arg-type]
        for i, a in enumerate((nxt, qd, st, fin)):
            buffer.set_res(i, memoryview(a))  # type: ignore[arg-type]
        start = time.perf_counter()
        for k0 in range(0, steps, _PROGRESS_CHUNK):
            k1 = min(k0 + _PROGRESS_CHUNK, steps)
            for k in range(k0, k1):
                r_buf[:] = reference[k]
                evaluate()
                if not fin[0]:
                    bar.close()
                    raise MmstabError(
                        f"the state became non-finite at t = {(k + 1) * dt:.6g} s (step {k + 1}: "
                        f"{_describe_nonfinite(nxt)}); stopping the run"
                    )
                statuses[k] = st[0]
                qdots[k] = qd
                states[k + 1] = nxt
                s_buf[:] = nxt
            bar.update(k1 - k0)
            tip = None if first_tip is None else first_tip(states[k0 + 1 : k1 + 1])
            if tip is not None:
                m = k0 + 1 + tip  # the sample where it tips: the run's last
                states, qdots, statuses = states[: m + 1], qdots[:m], statuses[:m]
                break
    wall = time.perf_counter() - start
    bar.close()
    return states, qdots, statuses, wall
