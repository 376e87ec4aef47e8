"""The closed-loop simulation: :func:`simulate` (see :mod:`mmstab.runs.tracking`).

A run in three stages: the set-up (:func:`resolve_settings`, :func:`start_state`,
:func:`set_up`: settings, the initial state, the controller step and the references), the
loop (:func:`mmstab.runs.tracking.loop.run_loop`) and the record (:func:`record`).
"""

from __future__ import annotations

import dataclasses
import time
from typing import NamedTuple

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.control.approach import RunReference, arm_references, run_reference
from mmstab.control.controller import (
    ARM,
    PLUGINS,
    ControllerParams,
    ControllerSettings,
    QPStatus,
    build_controller,
)
from mmstab.control.posture import PostureReference
from mmstab.control.reference import initial_state
from mmstab.control.tasks import TaskModel, build_task_model
from mmstab.core.files import MmstabError, UnstableError
from mmstab.core.problem import Problem, Scene
from mmstab.model.robot import FloatArray
from mmstab.paths.base import BasePath
from mmstab.paths.route import RoutePath
from mmstab.runs.tip_rule import TIP_HOLD, RockCheck
from mmstab.runs.tracking.backend import StepBackend, as_backend, build_advance
from mmstab.runs.tracking.loop import describe_nonfinite, run_loop
from mmstab.runs.tracking.run import (
    Failure,
    InitialArm,
    Tipping,
    TrackingPlan,
    TrackingRun,
    check_plan,
    task_batch,
)
from mmstab.stability.support import posture_mu, stability_along
from mmstab.terrain import wrap_angle


def simulate(
    problem: Problem | Scene,
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
        The recorded run; it stops where the robot would tip over (:class:`TipWatch`: μ < 0
        with the arm as it moved, not caught by a rock, for :data:`TIP_HOLD`; ``tipped``
        says when and where the tip began).

    Raises:
        UnstableError: the robot would tip over at the initial state.
        MmstabError: bad plan, plugin, duration, step signature or initial state, or a state
            that becomes non-finite during the run (naming the time and the components).
    """
    settings, duration = resolve_settings(problem, plugin, duration, settings)
    s0 = start_state(problem, plan, initial_arm, state0)
    setup = set_up(problem, plan, step, settings, duration, s0, posture)
    states, qdots, statuses, wall = run_loop(
        setup.advance,
        s0,
        setup.packed,
        setup.params,
        setup.steps,
        settings.dt,
        progress,
        TipWatch(problem, settings.dt, setup.steps),
    )
    return record(
        problem,
        setup,
        Trajectory(states, qdots, statuses),
        initial_arm=initial_arm if state0 is None else "given",
        wall_seconds=wall,
    )


def resolve_settings(
    problem: Problem | Scene,
    plugin: str | None,
    duration: float | None,
    settings: ControllerSettings | None,
) -> tuple[ControllerSettings, float]:
    """The run's controller settings and duration [s] (checked; see :func:`simulate`)."""
    if settings is None:
        if not isinstance(problem, Problem):
            raise MmstabError("a run of a Scene needs its controller settings (settings=...)")
        settings = settings_for_path(
            ControllerSettings.from_section(problem.section("controller")), problem.base_path
        )
    if plugin is not None:
        if plugin not in PLUGINS:
            raise MmstabError(f"unknown QP plugin {plugin!r}; choose one of {PLUGINS}")
        settings = dataclasses.replace(settings, plugin=plugin)
    duration = settings.duration if duration is None else float(duration)
    if not np.isfinite(duration) or duration < settings.dt:
        raise MmstabError(f"duration {duration} s must be at least dt = {settings.dt} s")
    return settings, duration


def settings_for_path(settings: ControllerSettings, base_path: BasePath) -> ControllerSettings:
    """``settings`` for a run along ``base_path``: a route sets its own period and length."""
    if isinstance(base_path, RoutePath):  # its lap_time and duration (mmstab.paths.route)
        return dataclasses.replace(
            settings, lap_time=base_path.lap_time, duration=base_path.duration
        )
    return settings


def start_state(
    problem: Problem | Scene, plan: TrackingPlan, initial_arm: InitialArm, state0: ArrayLike | None
) -> FloatArray:
    """The initial state (5 + n,), checked: finite, the right size, the robot not tipping."""
    robot = problem.robot
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
        raise MmstabError(f"initial state is not finite ({describe_nonfinite(s0)})")
    mu0 = mu_with_arm(problem, s0[None])
    if mu0[0] < 0:
        raise UnstableError(
            f"the robot would tip over at t = 0 s, at the start: base at ({s0[0]:.3f}, "
            f"{s0[1]:.3f}) m heading {s0[2]:.3f} rad, mu = {mu0[0]:.4g} N rad"
        )
    return s0


def mu_with_arm(problem: Problem | Scene, states: FloatArray) -> FloatArray:
    """μ with the arm as it is at each state (m, 5 + n) [N rad] (m,).

    The one μ: on the contacts that carry the state's load, with the tool wrench if any.
    """
    return posture_mu(problem.robot, problem.terrain, states[:, :3], states[:, ARM])


class TipWatch:
    """The tracking run's tip-over check, chunk after chunk (``run_loop``'s ``first_tip``).

    The rule of :mod:`mmstab.runs.tip_rule`, on the run's samples: a sample is tipping where
    μ < 0 with the arm as it moved (the one μ) and no rock catches it (:class:`RockCheck`,
    the check ``mmstab plan`` makes along the path). The run tips where tipping samples
    last :data:`TIP_HOLD` on end (or to the run's end) and stops at the first of them.

    Args:
        problem: the problem (robot, ground, route).
        dt: the control period [s].
        samples: the run's states after the initial one (its steps).
    """

    def __init__(self, problem: Problem | Scene, dt: float, samples: int) -> None:
        self.problem, self.samples = problem, samples
        self.hold = max(int(round(TIP_HOLD / dt)), 1)
        self.seen = 0  # chunk samples checked so far
        self.start: int | None = None  # the ongoing tipping stretch's first sample
        self.rock = RockCheck(problem.robot, getattr(problem, "route", None))

    def tipping(self, chunk: FloatArray) -> NDArray[np.bool_]:
        """Which of the states (m, 5 + n) are tipping (class text)."""
        bad = mu_with_arm(self.problem, chunk) < 0
        if bad.any():
            arm = self.problem.robot.arm_com(chunk[bad][:, ARM])
            bad[bad] = ~self.rock.holds(self.problem.terrain, chunk[bad, :3], arm)
        return bad

    def __call__(self, chunk: FloatArray) -> int | None:
        """Where in ``chunk`` a tip begins (< 0: in an earlier chunk), or None."""
        base = self.seen
        self.seen += len(chunk)
        bad = self.tipping(chunk)
        if not bad.any():
            self.start = None
            return None
        for i in range(len(chunk)):
            if not bad[i]:
                self.start = None
                continue
            if self.start is None:
                self.start = base + i
            if base + i + 1 - self.start >= self.hold or base + i + 1 == self.samples:
                return self.start - base
        return None


class Setup(NamedTuple):
    """What the loop runs with (:func:`set_up`).

    Attributes:
        settings: the controller settings.
        backend: the controller step and its name.
        model: the task model (the task ξ of a state in M: the reported errors').
        params: packed controller parameters (18 + 6n,).
        steps: control periods to run.
        t: (steps + 1,) sample times [s].
        reference: the arm's references and the per-step references at ``t``.
        packed: ``reference.control`` packed (the step's input, the arm CoM in the frame of
            ``controller.arm_com_frame``), (steps + 1, 15 + 2n).
        advance: one control period (:func:`build_advance`).
        build_seconds: wall time of the set-up [s].
    """

    settings: ControllerSettings
    backend: StepBackend
    model: TaskModel
    params: FloatArray
    steps: int
    t: FloatArray
    reference: RunReference
    packed: FloatArray
    advance: ca.Function
    build_seconds: float


def set_up(
    problem: Problem | Scene,
    plan: TrackingPlan,
    step: ca.Function | StepBackend | None,
    settings: ControllerSettings,
    duration: float,
    s0: FloatArray,
    posture: PostureReference | None,
) -> Setup:
    """The controller step, its parameters, the references and ``advance`` (:func:`simulate`)."""
    robot = problem.robot
    t_build = time.perf_counter()
    backend = (
        StepBackend(build_controller(robot, settings).step, "interpreted")
        if step is None
        else as_backend(step)
    )
    model = build_task_model(robot, settings.base_offset)  # ξ in M, whatever the step tracks
    params = ControllerParams.from_settings(robot, settings).pack()
    ground = (problem.base_path, problem.terrain)
    nominal = dataclasses.replace(settings, duration=duration)  # the time law's window
    arm = arm_references(robot, plan, s0[ARM], nominal, posture, ground)
    steps = max(int(round(arm.real_time(duration) / settings.dt)), 1)  # the time law's added
    t = np.asarray(np.arange(steps + 1) * settings.dt, dtype=np.float64)
    reference = run_reference(robot, *ground, plan, s0[ARM], settings, t, posture, arm)
    packed = reference.control.pack()
    if not np.all(np.isfinite(packed)):
        raise MmstabError("the task reference is not finite")
    advance = build_advance(model, backend.function)
    build_seconds = time.perf_counter() - t_build
    return Setup(
        settings, backend, model, params, steps, t, reference, packed, advance, build_seconds
    )


class Trajectory(NamedTuple):
    """What the loop recorded: states (m + 1, 5 + n), q̇ (m, 2 + n) [rad/s], statuses (m,)."""

    states: FloatArray
    qdots: FloatArray
    statuses: NDArray[np.int8]


def record(
    problem: Problem | Scene,
    setup: Setup,
    run: Trajectory,
    *,
    initial_arm: str,
    wall_seconds: float,
) -> TrackingRun:
    """The :class:`TrackingRun` of a loop's trajectory: tasks, errors, μ, failures, tipping."""
    robot, settings, states, statuses = problem.robot, setup.settings, run.states, run.statuses
    t, n = setup.t[: len(states)], len(states)  # shorter when the robot tipped
    ref = setup.reference.step
    ref = ref._replace(**{k: np.asarray(v)[:n] for k, v in ref._asdict().items()})
    xi, com_B = task_batch(setup.model, problem.terrain, states)
    mu = stability_along(robot, problem.terrain, states[:, :3], com_B)
    if robot.tool_wrench is not None:
        mu = mu._replace(reconfigured=mu_with_arm(problem, states))
    failed = np.flatnonzero(statuses != QPStatus.SUCCESS)
    return TrackingRun(
        t=t,
        state=states,
        qdot=run.qdots,
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
        posture=setup.reference.arm.posture,
        approach=setup.reference.arm.approach,
        timing=setup.reference.arm.timing,
        dt=settings.dt,
        lap_time=settings.lap_time,
        qdot_limit=ControllerParams.from_settings(robot, settings).qdot_max,
        q_lower=robot.joint_lower,
        q_upper=robot.joint_upper,
        plugin=settings.plugin,
        backend=setup.backend.name,
        initial_arm=initial_arm,
        wall_seconds=wall_seconds,
        build_seconds=setup.build_seconds,
        tipped=None
        if n == setup.steps + 1
        else Tipping(n - 1, float(t[-1]), states[-1, :3].copy(), float(mu.reconfigured[-1])),
    )
