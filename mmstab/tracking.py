"""Closed-loop trajectory tracking on the ramp (paper Section II-E and III; DESIGN.md §6).

:func:`simulate` drives the controller step (:mod:`mmstab.controller`, Eq. 7-8) around the
problem's circle while the arm CoM follows a plan's body-frame CoM targets and the posture task
holds the arm near the plan's postures (:func:`mmstab.reference.task_reference`; the posture
reference is checked for self-collision and repaired first, :mod:`mmstab.posture`), and records
everything the paper's Fig. 9-12 show.

**Plant.** The base is the nonholonomic tracked vehicle of :class:`mmstab.controller.TaskModel`:
over one control period dt the sprocket speeds are constant, so the base drives an exact arc
on the slope plane (no sideways motion); the joints integrate q̇·dt. The plant is kinematic,
as the paper's: the commanded joint speeds are the actual ones (no slip, no dynamics).

**One step = one CasADi call.** The controller step Function (state, reference, params) ->
(q̇, status, objective) and the integrator are composed into one ``advance`` Function, called
through ``Function.buffer()`` on preallocated arrays. The composition applies q̇ only when the
step reports SUCCESS (else q̇ = 0: hold still, whatever the backend returned) and flags a
non-finite next state. Any Function with :class:`StepBackend`'s signature can be the step: the
interpreted ``Controller.step`` (default) or the code-generated library loaded with
``casadi.external`` (issue 6).

**Failures.** A step that fails (status != SUCCESS: infeasible bounds, solver not certified)
holds still for that period; every such step is recorded (:attr:`TrackingRun.failures`). A
non-finite state stops the run with :class:`~mmstab.config.MmstabError`, naming the time and the
state components at fault.

**Initial state.** The base starts on the reference start pose (the circle at s = 0), sprocket
angles zero. The arm starts ``stowed`` by default (the robot arrives with its arm folded, as
the paper's Fig. 11(a) suggests) or at the plan's first posture (``initial_arm="planned"``).
For the first ``approach_time`` seconds the arm's references follow a collision-free path
from that posture onto the lap's (:class:`mmstab.approach.Approach`); with ``approach_time: 0``
they are the lap's from t = 0, a step the arm takes at saturated joint speeds, through the
body on the default problem.

**Stability.** After the loop, vectorised over every recorded sample: μ with the arm as it
moved (``reconfigured``), with the arm held stowed on the same base trajectory (``stowed``)
and with the arm removed (``arm_removed``, the base alone), gravity from each recorded heading.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any, Literal, NamedTuple, Protocol

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.approach import Approach, run_reference
from mmstab.config import MmstabError
from mmstab.controller import (
    ARM,
    ARM_JOINTS,
    JOINT_COUNT,
    PARAMS_SIZE,
    PLUGINS,
    REFERENCE_SIZE,
    STATE_SIZE,
    ControllerParams,
    ControllerSettings,
    QPStatus,
    TaskModel,
    build_controller,
    quiet_stdout,
)
from mmstab.ik import COM_TOLERANCE
from mmstab.posture import PostureReference
from mmstab.problem import Problem
from mmstab.reference import PlanLike
from mmstab.robot import FloatArray, Robot
from mmstab.stability import robot_force_angle
from mmstab.terrain import Terrain, wrap_angle

#: Names of the state components, for messages and saved arrays.
STATE_NAMES = (
    "x",
    "y",
    "heading",
    "theta_l",
    "theta_r",
    "theta_0",
    "theta_1",
    "theta_2",
    "theta_3",
)
#: Names of the joints (q̇ columns), as in the summary.
JOINT_NAMES = ("track_left", "track_right", "link0", "link1", "link2", "link3")
InitialArm = Literal["stowed", "planned"]
_PROGRESS_CHUNK = 500  # steps between progress-bar updates
#: The transient ends once the arm-CoM error stays within this share of its initial value.
TRANSIENT_FRACTION = 0.01


class TrackingPlan(PlanLike, Protocol):
    """What :func:`simulate` needs of a plan (:class:`mmstab.planner.Plan` has it)."""

    @property
    def postures(self) -> FloatArray:
        """Arm postures realising the targets (K, 4) [rad]: the posture task's reference."""
        ...


# ------------------------------------------------------------------------------- the backend
class StepBackend(NamedTuple):
    """A controller step to simulate with.

    Attributes:
        function: CasADi Function (state (9), reference (23) = [ξ_des, ξ̇_ref, q_ref, q̇_ref, ground],
            params (42))
            -> (qdot (6) [rad/s], status (a :class:`QPStatus` value), ...), the signature of
            :attr:`mmstab.controller.Controller.step`; on failure it should return q̇ = 0 (the
            simulation holds still on any status but SUCCESS regardless).
        name: how it was made (``interpreted``, ``generated``, ``custom``), for the records.
    """

    function: ca.Function
    name: str

    def check(self) -> None:
        """Raise :class:`MmstabError` unless the Function has the step's signature."""
        f = self.function
        sizes_in = [f.size_in(i) for i in range(f.n_in())]
        expected = [(STATE_SIZE, 1), (REFERENCE_SIZE, 1), (PARAMS_SIZE, 1)]
        if sizes_in != expected:
            raise MmstabError(
                f"step Function {f.name()!r} takes {sizes_in}; expected {expected} "
                "(state, reference, params)"
            )
        if f.n_out() < 2 or f.size_out(0) != (JOINT_COUNT, 1) or f.size_out(1) != (1, 1):
            raise MmstabError(
                f"step Function {f.name()!r} must return qdot ({JOINT_COUNT}, 1) and a status "
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
        Function (state (9), reference (23), params (42)) -> (state_next (9), qdot (6)
        [rad/s] as applied, status, finite): ``qdot`` is the step's answer when its status is
        SUCCESS and zero otherwise; ``finite`` is 1 when every component of ``state_next`` is
        finite. dt [s] is read from the parameters (``ControllerParams.dt``).
    """
    state = ca.MX.sym("state", STATE_SIZE)
    ref = ca.MX.sym("reference", REFERENCE_SIZE)
    p = ca.MX.sym("params", PARAMS_SIZE)
    out = step(state, ref, p)
    qdot_raw, status = out[0], out[1]
    ok = status == float(QPStatus.SUCCESS)
    qdot = ca.if_else(ok, qdot_raw, ca.MX.zeros(JOINT_COUNT))
    nxt = model.f_integrate(state, qdot, ControllerParams.unpack(p).dt)
    finite = ca.mmin(ca.fabs(nxt) < ca.inf)  # NaN compares false
    return ca.Function(
        "advance",
        [state, ref, p],
        [nxt, qdot, status, finite],
        ["state", "reference", "params"],
        ["state_next", "qdot", "status", "finite"],
    )


# ----------------------------------------------------------------------------------- results
class Failure(NamedTuple):
    """One control period that held still: step index, time [s], status."""

    step: int
    time: float
    status: QPStatus


class Stability(NamedTuple):
    """Force-angle μ [N rad] along a run, per recorded sample (N+1,).

    Attributes:
        reconfigured: with the arm as it moved.
        arm_removed: the base alone.
        stowed: with the arm held stowed on the same base trajectory.
    """

    reconfigured: FloatArray
    arm_removed: FloatArray
    stowed: FloatArray


@dataclasses.dataclass(frozen=True)
class TrackingRun:
    """A simulated run: N control periods, N+1 samples.

    Attributes:
        t: sample times (N+1,) [s].
        state: states (N+1, 9): base pose in S [m, m, rad], sprockets and arm joints [rad].
        qdot: joint speeds applied over each period (N, 6) [rad/s] (zero when it failed).
        status: the step's :class:`QPStatus` per period (N,).
        xi: task ξ in S (N+1, 6) [m, m, rad, m, m, m].
        xi_des: reference ξ_des in S (N+1, 6).
        xi_dot_ref: reference rate (N+1, 6) [m/s, rad/s].
        q_ref: arm posture reference (N+1, 4) [rad].
        posture_error: q_ref − q_arm (N+1, 4) [rad].
        base_error: distance of the base control point from its reference (N+1,) [m].
        heading_error: wrapped heading error γ_des − γ (N+1,) [rad].
        arm_com_error: distance of the arm CoM from its reference (N+1,) [m].
        arm_com_body: arm CoM in the body frame (N+1, 3) [m].
        mu: stability along the run.
        failures: every period that held still, in order.
        posture: the posture reference (knots, via postures, its collision check).
        approach: the arm's start-up reference (None when ``approach_time`` is 0).
        dt: control period [s].
        lap_time: time of one lap of the reference [s].
        qdot_limit: joint speed limits (6,) [rad/s].
        q_lower: arm joint lower limits (4,) [rad].
        q_upper: arm joint upper limits (4,) [rad].
        plugin: the QP plugin of the settings.
        backend: ``interpreted``, ``generated`` or ``custom``.
        initial_arm: ``stowed`` or ``planned``.
        wall_seconds: wall time of the control loop [s].
        build_seconds: wall time to build the controller and the reference [s].
    """

    t: FloatArray
    state: FloatArray
    qdot: FloatArray
    status: NDArray[np.int8]
    xi: FloatArray
    xi_des: FloatArray
    xi_dot_ref: FloatArray
    q_ref: FloatArray
    posture_error: FloatArray
    base_error: FloatArray
    heading_error: FloatArray
    arm_com_error: FloatArray
    arm_com_body: FloatArray
    mu: Stability
    failures: tuple[Failure, ...]
    posture: PostureReference
    approach: Approach | None
    dt: float
    lap_time: float
    qdot_limit: FloatArray
    q_lower: FloatArray
    q_upper: FloatArray
    plugin: str
    backend: str
    initial_arm: str
    wall_seconds: float
    build_seconds: float

    @property
    def steps(self) -> int:
        """Number of control periods N."""
        return int(self.qdot.shape[0])

    @property
    def us_per_step(self) -> float:
        """Mean wall time of one control period (step + integration + logging) [µs]."""
        return self.wall_seconds / max(self.steps, 1) * 1e6


# ---------------------------------------------------------------------------- post-processing
def task_batch(
    model: TaskModel, terrain: Terrain, states: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """ξ for many states: the controller's task map (``TaskModel.f_task``) mapped over them.

    Args:
        model: the task kinematics.
        terrain: the ground (the local ground of each state's pose).
        states: states (N, 9) [m, m, rad, rad...].

    Returns:
        (ξ (N, 6) in M [m, m, rad, m, m, m], arm CoM in the body frame (N, 3) [m]).
    """
    s = np.atleast_2d(np.asarray(states, dtype=float))
    xi = model.task_batch(s, terrain.local_ground(s[:, :3]))
    return xi, np.atleast_2d(model.robot.arm_com(s[:, ARM]))


def stability_along(problem: Problem, poses: ArrayLike, arm_com_body: ArrayLike) -> Stability:
    """μ along a base trajectory: with the given arm CoMs, the arm removed, the arm stowed.

    Args:
        problem: the problem (robot and terrain).
        poses: base poses (N, 3) in the map frame M [m, m, rad].
        arm_com_body: arm CoM in the body frame per sample (N, 3) [m].
    """
    robot = problem.robot
    gravity = problem.terrain.gravity_body(poses)
    stowed = np.broadcast_to(robot.arm_com(robot.stowed), gravity.shape)
    return Stability(
        reconfigured=robot_force_angle(robot, gravity, arm_com_body).mu,
        arm_removed=robot_force_angle(robot, gravity, None).mu,
        stowed=robot_force_angle(robot, gravity, stowed).mu,
    )


# ------------------------------------------------------------------------------- simulation
def _check_plan(plan: TrackingPlan, robot: Robot) -> None:
    try:
        fractions = np.asarray(plan.fractions, dtype=float)
        target = np.asarray(plan.target_com, dtype=float)
    except (AttributeError, TypeError, ValueError) as exc:
        raise MmstabError(f"plan: needs fractions (K,) and target_com (K, 3): {exc}") from None
    if fractions.ndim != 1 or fractions.size == 0 or target.shape != (fractions.size, 3):
        raise MmstabError(
            f"plan: fractions {fractions.shape} and target_com {target.shape} do not match"
        )
    if not (np.all(np.isfinite(fractions)) and np.all(np.isfinite(target))):
        raise MmstabError("plan: fractions and target_com must be finite")
    if fractions[0] < 0 or fractions[-1] >= 1 or np.any(np.diff(fractions) <= 0):
        raise MmstabError("plan: fractions must increase strictly within [0, 1)")
    try:
        postures = np.asarray(plan.postures, dtype=float)
    except (AttributeError, TypeError, ValueError) as exc:
        raise MmstabError(f"plan: the posture task needs postures (K, 4): {exc}") from None
    if postures.shape != (fractions.size, ARM_JOINTS):
        raise MmstabError(
            f"plan: postures {postures.shape} do not match fractions {fractions.shape} "
            f"(the posture task needs one arm posture (4,) per fraction)"
        )
    outside = (postures < robot.joint_lower) | (postures > robot.joint_upper)
    if not np.all(np.isfinite(postures)) or outside.any():
        raise MmstabError("plan: postures must be finite and within the joint limits")
    gap = float(np.linalg.norm(robot.arm_com(postures) - target, axis=1).max())
    if gap > COM_TOLERANCE:
        raise MmstabError(
            f"plan: the postures do not realise target_com (largest gap {gap:.3g} m > "
            f"{COM_TOLERANCE} m); the arm references are built from the postures"
        )


def initial_state(problem: Problem, plan: TrackingPlan, initial_arm: InitialArm) -> FloatArray:
    """The run's first state: base on the reference start pose, sprockets at 0, arm as chosen.

    Args:
        problem: the problem (circle, robot).
        plan: the plan (its first posture, for ``initial_arm="planned"``).
        initial_arm: ``stowed`` (the robot's folded posture) or ``planned``.
    """
    pose = problem.circle.pose_at(0.0)[0]
    arm = problem.robot.stowed if initial_arm == "stowed" else np.asarray(plan.postures)[0]
    return np.r_[pose, 0.0, 0.0, np.asarray(arm, dtype=float)]


def _describe_nonfinite(state: FloatArray) -> str:
    bad = [STATE_NAMES[i] for i in np.flatnonzero(~np.isfinite(state))]
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
        plugin: QP plugin (one of :data:`mmstab.controller.PLUGINS`); default the problem's.
        step: the controller step to use instead of the interpreted ``Controller.step``: a
            CasADi Function with its signature, or a :class:`StepBackend`.
        duration: simulated time [s]; default the problem's ``controller.duration``.
        progress: show a progress bar (stderr).
        initial_arm: ``stowed`` (default) or ``planned`` (the plan's first posture).
        state0: the initial state (9,) instead of :func:`initial_state`.
        settings: controller settings instead of the problem's section (``plugin`` still
            overrides their plugin).
        posture: the lap's posture reference, if already built; default
            :func:`mmstab.posture.build_posture_reference` of the plan, checked (and repaired)
            at every control period of a lap. The start-up approach (``approach_time``) is
            built from the initial arm posture (:func:`mmstab.approach.arm_references`).

    Returns:
        The recorded run.

    Raises:
        MmstabError: bad plan, plugin, duration, step signature or initial state, or a state
            that becomes non-finite during the run (naming the time and the components).
    """
    robot = problem.robot
    if settings is None:
        settings = ControllerSettings.from_section(problem.section("controller"))
    if plugin is not None:
        if plugin not in PLUGINS:
            raise MmstabError(f"unknown QP plugin {plugin!r}; choose one of {PLUGINS}")
        settings = dataclasses.replace(settings, plugin=plugin)
    duration = settings.duration if duration is None else float(duration)
    if not np.isfinite(duration) or duration < settings.dt:
        raise MmstabError(f"duration {duration} s must be at least dt = {settings.dt} s")
    if initial_arm not in ("stowed", "planned"):
        raise MmstabError(f"initial_arm must be 'stowed' or 'planned', got {initial_arm!r}")
    _check_plan(plan, robot)
    s0 = initial_state(problem, plan, initial_arm) if state0 is None else np.asarray(state0, float)
    if s0.shape != (STATE_SIZE,):
        raise MmstabError(f"initial state must have shape ({STATE_SIZE},), got {s0.shape}")
    if not np.all(np.isfinite(s0)):
        raise MmstabError(f"initial state is not finite ({_describe_nonfinite(s0)})")

    t_build = time.perf_counter()
    if step is None:
        controller = build_controller(robot, settings)
        backend = StepBackend(controller.step, "interpreted")
        model = controller.model
    else:
        backend = as_backend(step)
        model = TaskModel(robot, settings.base_offset)
    params = ControllerParams.from_settings(robot, settings).pack()
    steps = max(int(round(duration / settings.dt)), 1)
    t = np.asarray(np.arange(steps + 1) * settings.dt, dtype=np.float64)
    arm, ref = run_reference(
        robot, problem.circle, problem.terrain, plan, s0[ARM], settings, t, posture
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
    )

    xi, com_B = task_batch(model, problem.terrain, states)
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
        mu=stability_along(problem, states[:, :3], com_B),
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
    )


def _run_loop(
    advance: ca.Function,
    state0: FloatArray,
    reference: FloatArray,
    params: FloatArray,
    steps: int,
    dt: float,
    progress: bool,
) -> tuple[FloatArray, FloatArray, NDArray[np.int8], float]:
    """The control loop: ``steps`` calls of ``advance`` on buffers bound once.

    Args:
        advance: from :func:`build_advance`.
        state0: initial state (9,).
        reference: packed :class:`~mmstab.tasks.StepReference` per sample (steps+1, 23); row
            k is used in period k.
        params: packed controller parameters (42,).
        steps: number of control periods.
        dt: control period [s] (for messages).
        progress: show a progress bar.

    Returns:
        (states (steps+1, 9), applied q̇ (steps, 6) [rad/s], statuses (steps,), wall time [s]).

    Raises:
        MmstabError: the state became non-finite.
    """
    from tqdm import tqdm

    states = np.empty((steps + 1, STATE_SIZE))
    qdots = np.empty((steps, JOINT_COUNT))
    statuses = np.empty(steps, dtype=np.int8)
    states[0] = state0
    s_buf, r_buf, p_buf = state0.copy(), np.zeros(REFERENCE_SIZE), params.copy()
    nxt, qd, st, fin = np.zeros(STATE_SIZE), np.zeros(JOINT_COUNT), np.zeros(1), np.zeros(1)
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
    wall = time.perf_counter() - start
    bar.close()
    return states, qdots, statuses, wall


def transient_end(run: TrackingRun) -> int:
    """The sample where the initial transient ends (0 when the arm starts on its reference).

    With a start-up approach, the first sample at or after its end. Without one, the first
    index from which the arm-CoM error stays within :data:`TRANSIENT_FRACTION` of its initial
    value.
    """
    if run.approach is not None:
        return int(np.searchsorted(run.t, run.approach.duration - 0.5 * run.dt))
    e = run.arm_com_error
    above = np.flatnonzero(e > TRANSIENT_FRACTION * e[0])
    return int(above[-1] + 1) if above.size and e[0] > 0 else 0


def summarize(run: TrackingRun) -> dict[str, Any]:
    """The run's headline numbers (the keys of ``results/tracking/summary.json``).

    Besides the whole-run numbers, ``after_transient`` repeats errors, mean joint speeds and
    μ from :func:`transient_end` on: the initial reconfiguration (from the stowed arm)
    dominates the whole-run maxima and minima (with an approach: the approach is the transient).
    ``posture_reference`` is the posture
    reference's collision check and via postures (:meth:`PostureReference.summary`).
    """
    names = JOINT_NAMES

    def arm_dict(values: FloatArray) -> dict[str, float]:
        return dict(zip(names[2:], np.asarray(values, dtype=float).tolist(), strict=True))

    limit = run.qdot_limit
    saturated = np.isclose(np.abs(run.qdot), limit, rtol=0, atol=1e-9)
    cases = run.mu._asdict()
    k = min(transient_end(run), run.steps - 1)
    after = {
        "start_s": float(run.t[k]),
        "base_error_max_m": float(run.base_error[k:].max()),
        "arm_com_error_max_m": float(run.arm_com_error[k:].max()),
        "posture_error_max_abs_rad": arm_dict(np.abs(run.posture_error[k:]).max(axis=0)),
        "qdot_mean_abs": dict(zip(names, np.abs(run.qdot[k:]).mean(axis=0).tolist(), strict=True)),
        "mu_min": {name: float(v[k:].min()) for name, v in cases.items()},
        "mu_mean": {name: float(v[k:].mean()) for name, v in cases.items()},
    }
    return {
        "base_error_max_m": float(run.base_error.max()),
        "base_error_final_m": float(run.base_error[-1]),
        "arm_com_error_max_m": float(run.arm_com_error.max()),
        "arm_com_error_final_m": float(run.arm_com_error[-1]),
        "heading_error_max_abs_rad": float(np.abs(run.heading_error).max()),
        "posture_error_max_abs_rad": arm_dict(np.abs(run.posture_error).max(axis=0)),
        "posture_error_final_abs_rad": arm_dict(np.abs(run.posture_error[-1])),
        "qdot_max_abs": dict(zip(names, np.abs(run.qdot).max(axis=0).tolist(), strict=True)),
        "qdot_mean_abs": dict(zip(names, np.abs(run.qdot).mean(axis=0).tolist(), strict=True)),
        "qdot_limit": dict(zip(names, limit.tolist(), strict=True)),
        "saturated_steps": dict(zip(names, saturated.sum(axis=0).tolist(), strict=True)),
        "last_saturated_time_s": float(run.t[np.flatnonzero(saturated.any(axis=1))[-1]])
        if saturated.any()
        else None,
        "mean_track_speed_left": float(run.qdot[:, 0].mean()),
        "mean_track_speed_right": float(run.qdot[:, 1].mean()),
        "right_track_faster_share": float(np.mean(run.qdot[:, 1] > run.qdot[:, 0])),
        "mu_min": {name: float(v.min()) for name, v in cases.items()},
        "mu_mean": {name: float(v.mean()) for name, v in cases.items()},
        "after_transient": after,
        "qp_failures": len(run.failures),
        "qp_failure_events": [
            {"step": f.step, "time_s": f.time, "status": f.status.name} for f in run.failures
        ],
        "steps": run.steps,
        "dt_s": run.dt,
        "duration_s": float(run.t[-1]),
        "wall_seconds": run.wall_seconds,
        "build_seconds": run.build_seconds,
        "us_per_step": run.us_per_step,
        "plugin": run.plugin,
        "backend": run.backend,
        "initial_arm": run.initial_arm,
        "posture_reference": run.posture.summary(run.lap_time),
        "approach": None if run.approach is None else run.approach.summary(),
    }
