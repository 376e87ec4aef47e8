"""Whole closed-loop runs without per-step Python overhead.

:func:`rollout` runs the tracking closed loop (controller step, then the exact-arc motion of
the base and the joints over dt) on a precomputed reference sequence, with one of three
backends that compute the same thing:

- ``"python"``: a step-by-step Python loop of :meth:`Controller.solve` (the ``step``
  Function) and ``model.integrate`` (``f_integrate``); the reference implementation.
- ``"casadi"``: :func:`mmstab.codegen.rollout_chunk` (the closed-loop step rolled over
  :data:`~mmstab.codegen.ROLLOUT_CHUNK` steps with ``mapaccum``), interpreted by CasADi's
  virtual machine; Python only loops over chunks.
- ``"generated"``: the same chunk compiled to C (:func:`mmstab.codegen.generate`, cached) and
  called through ``casadi.external``.

The inputs of a run (:class:`RunInputs`: parameters, initial state, reference table) are also
what the standalone C example reads (:func:`write_run_file`), so the Python and the C closed
loops can be compared number for number.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import casadi as ca
import numpy as np

from mmstab.codegen import (
    ROLLOUT_CHUNK,
    ROLLOUT_NAME,
    CodegenSettings,
    generate,
    rollout_chunk,
)
from mmstab.control.approach import run_reference
from mmstab.control.controller import (
    ARM,
    Controller,
    ControllerParams,
    ControllerSettings,
    QPStatus,
    StepReference,
    build_controller,
)
from mmstab.control.posture import PosturePlan, PostureReference
from mmstab.control.reference import initial_state
from mmstab.core.files import _atomic
from mmstab.model.robot import FloatArray, Robot

if TYPE_CHECKING:
    from mmstab.core.problem import Problem

BACKENDS = ("python", "casadi", "generated")
RUN_FILE_MAGIC = b"MMSTRUN2"  #: first 8 bytes of a run file (embedded/run_file.h)


class ExamplePlan(NamedTuple):
    """A plan-like arm reference: body-frame CoM targets of chosen postures along the lap.

    Attributes:
        fractions: path fractions (K,) increasing in [0, 1).
        target_com: arm-CoM targets in the body frame (K, 3) [m] (FK of ``postures``).
        postures: the arm postures (K, 4) [rad] that realise them.
    """

    fractions: FloatArray
    target_com: FloatArray
    postures: FloatArray


#: Arm postures of :func:`example_plan` at 8 evenly spread path fractions f [rad]: the turret
#: swings 2.6 ± 0.6 sin(2π f) (the arm moves from one side to the other along the lap, as a
#: stability plan does on a slope); shoulder, elbow and wrist stay at 0.3, −0.5, 0.2.
EXAMPLE_POSTURES = np.column_stack(
    [
        2.6 + 0.6 * np.sin(2 * np.pi * np.arange(8) / 8),
        np.tile([0.3, -0.5, 0.2], (8, 1)),
    ]
)


def example_plan(robot: Robot, postures: FloatArray = EXAMPLE_POSTURES) -> ExamplePlan:
    """A plan with the arm-CoM targets of ``postures`` (K, 4) [rad], evenly spread on the lap.

    Stands in for :func:`mmstab.planner.plan_path` where a run should not depend on the
    planner (benchmarks, the embedded example, tests).
    """
    postures = np.atleast_2d(np.asarray(postures, dtype=float))
    fractions = np.arange(len(postures)) / len(postures)
    return ExamplePlan(fractions, robot.arm_com(postures), postures)


class RunInputs(NamedTuple):
    """Everything a closed-loop run reads (also the content of a run file).

    Attributes:
        dt: control period = integration step [s].
        params: the controller's packed parameters (42,).
        state0: initial state (9,) [m, m, rad, rad...].
        reference: packed :class:`~mmstab.control.layout.StepReference` ``[ξ_des, ξ̇_ref, q_ref,
            q̇_ref]`` at t_k = k dt, k = 0..steps (steps + 1, 23), the arm CoM in the frame of
            ``controller.arm_com_frame``; the last row is only used to measure the final
            tracking error.
    """

    dt: float
    params: FloatArray
    state0: FloatArray
    reference: FloatArray

    @property
    def steps(self) -> int:
        """Number of control steps."""
        return len(self.reference) - 1


def codegen_plugin(problem: Problem) -> str:
    """The problem's code-generation plugin (``codegen.plugin``)."""
    return CodegenSettings.from_section(problem.section("codegen")).plugin


def controller_settings(problem: Problem, plugin: str | None = None) -> ControllerSettings:
    """The problem's controller settings with ``plugin`` (default ``codegen.plugin``)."""
    settings = ControllerSettings.from_section(problem.section("controller"))
    return dataclasses.replace(settings, plugin=plugin or codegen_plugin(problem))


def run_inputs(
    problem: Problem,
    plan: PosturePlan,
    *,
    steps: int | None = None,
    state0: FloatArray | None = None,
    settings: ControllerSettings | None = None,
    posture: PostureReference | None = None,
) -> RunInputs:
    """The inputs of a closed-loop run of a problem with a plan.

    Args:
        problem: the problem (robot, circle, controller settings).
        plan: the arm reference (``fractions``, ``target_com``, ``postures``), e.g. the
            planner's ``Plan``.
        steps: control steps (default ``controller.duration / controller.dt``).
        state0: initial state (9,) (default :func:`mmstab.control.reference.initial_state` with the
            plan's first posture, or the stowed arm for a plan without postures).
        settings: controller settings (default the problem's).
        posture: the lap's posture reference (default
            :func:`mmstab.control.posture.build_posture_reference` of the plan, checked at every
            control period of a lap, as in the simulation); the start-up approach is built
            from ``state0``'s arm (:func:`mmstab.control.approach.arm_references`).
    """
    settings = settings or ControllerSettings.from_section(problem.section("controller"))
    n = int(round(settings.duration / settings.dt)) if steps is None else int(steps)
    if n < 1:
        raise ValueError(f"a run needs at least one step, got {n}")
    t = np.arange(n + 1) * settings.dt
    if state0 is None:
        postures = getattr(plan, "postures", None)
        arm = problem.robot.stowed if postures is None else np.asarray(postures)[0]
        state0 = initial_state(problem.circle, arm)
    x0 = np.asarray(state0, dtype=float)
    n_state = 5 + problem.robot.arm_joints
    if x0.shape != (n_state,):
        raise ValueError(f"state0 must have shape ({n_state},), got {x0.shape}")
    reference = run_reference(
        problem.robot, problem.circle, problem.terrain, plan, x0[ARM], settings, t, posture
    ).control
    return RunInputs(
        dt=settings.dt,
        params=ControllerParams.from_settings(problem.robot, settings).pack(),
        state0=x0,
        reference=reference.pack(),
    )


# ------------------------------------------------------------------------------------ rollout
class Rollout(NamedTuple):
    """A closed-loop run.

    Attributes:
        times: t_k = k dt (steps + 1,) [s].
        states: states at t_k (steps + 1, 5 + n), n the arm's joints.
        qdot: joint speeds applied over [t_k, t_k+1) (steps, 2 + n) [rad/s].
        status: :class:`QPStatus` of each step (steps,).
        errors: tracking error ξ_des − ξ at t_k (steps + 1, 6), heading wrapped to (−π, π]; the
            arm-CoM rows in the controller's frame (``controller.arm_com_frame``).
        backend: the backend that ran it.
    """

    times: FloatArray
    states: FloatArray
    qdot: FloatArray
    status: np.ndarray
    errors: FloatArray
    backend: str

    @property
    def failures(self) -> int:
        """Steps that returned the safe action (status != SUCCESS)."""
        return int(np.count_nonzero(self.status != QPStatus.SUCCESS))


def tracking_errors(ctrl: Controller, states: FloatArray, reference: FloatArray) -> FloatArray:
    """ξ_des − ξ(state) per row (N, 6), heading error wrapped to (−π, π].

    ξ is evaluated with each row's local ground, as the controller's step sees it.
    """
    ref = StepReference.unpack(reference)
    e = ref.xi_des - ctrl.model.task_batch(states, ref.ground)
    e[:, 2] = np.arctan2(np.sin(e[:, 2]), np.cos(e[:, 2]))
    return e


def _python_loop(ctrl: Controller, inputs: RunInputs) -> tuple[FloatArray, ...]:
    n = inputs.steps
    lay = ctrl.layout
    states, qdot, status = np.empty((n + 1, lay.state)), np.empty((n, lay.joints)), np.empty(n)
    states[0] = inputs.state0
    ctrl.set_params(ControllerParams.unpack(inputs.params))
    ref = inputs.reference
    for k in range(n):
        res = ctrl.solve(states[k], *StepReference.unpack(ref[k]))
        qdot[k], status[k] = res.qdot, res.status
        states[k + 1] = ctrl.model.integrate(states[k], res.qdot, inputs.dt)
    return states, qdot, status


def _chunk_loop(chunk: ca.Function, inputs: RunInputs) -> tuple[FloatArray, ...]:
    n, size = inputs.steps, chunk.size2_in(1)
    chunks = -(-n // size)
    refs = inputs.reference[:n]
    pad = chunks * size - n  # the last chunk runs on past the end, on the last reference row
    padded = np.vstack([refs, np.repeat(refs[-1:], pad, axis=0)])
    n_state, n_joints = chunk.size1_in(0), chunk.size1_out(1)
    states, qdot, status = np.empty((n_state, n + 1)), np.empty((n_joints, n)), np.empty(n)
    states[:, 0] = inputs.state0
    # buffer evaluation on preallocated arrays (no DM conversions per chunk)
    buf: Any
    buf, run = chunk.buffer()
    x0, p = np.array(inputs.state0), np.array(inputs.params)
    r = np.empty((size, chunk.size1_in(1)))
    out_x, out_q, out_s = (
        np.empty((size, n_state)),
        np.empty((size, n_joints)),
        np.empty(size),
    )
    for i, a in enumerate((x0, r, p)):
        buf.set_arg(i, memoryview(a))  # type: ignore[arg-type]
    for i, a in enumerate((out_x, out_q, out_s)):
        buf.set_res(i, memoryview(a))  # type: ignore[arg-type]
    for c in range(chunks):
        r[:] = padded[c * size : (c + 1) * size]  # row-major (size, 23) = column-major 23 x size
        run()
        m = min(size, n - c * size)
        k = c * size
        states[:, k + 1 : k + 1 + m] = out_x[:m].T
        qdot[:, k : k + m], status[k : k + m] = out_q[:m].T, out_s[:m]
        x0[:] = out_x[size - 1]
    return states.T, qdot.T, status


def rollout(
    problem: Problem,
    plan: PosturePlan,
    *,
    backend: str = "generated",
    steps: int | None = None,
    state0: FloatArray | None = None,
    plugin: str | None = None,
    inputs: RunInputs | None = None,
    out_dir: str | os.PathLike[str] | None = None,
) -> Rollout:
    """Run the closed loop over a precomputed reference sequence.

    Args:
        problem: the problem (robot, circle, ``controller:``, ``codegen:``).
        plan: the arm reference (``fractions``, ``target_com``, ``postures``; e.g. the
            planner's ``Plan``).
        backend: ``"python"`` (step loop), ``"casadi"`` (interpreted chunks) or
            ``"generated"`` (compiled chunks).
        steps: control steps (default ``controller.duration / controller.dt``).
        state0: initial state (9,) (default :func:`mmstab.control.reference.initial_state` with the
            plan's first posture, or the stowed arm for a plan without postures).
        plugin: QP plugin (default ``codegen.plugin``); the same for every backend.
        inputs: the run's inputs, if already computed (then ``steps``/``state0`` are ignored).
        out_dir: where the generated backend's library lives (default ``codegen.directory``).

    Returns:
        The trajectory; every backend gives the same one (to round-off).

    Raises:
        ValueError: an unknown backend, or a state0 that is not (9,).
        MmstabError: code generation failed (generated backend).
    """
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; choose one of {BACKENDS}")
    settings = controller_settings(problem, plugin)
    if inputs is None:
        inputs = run_inputs(problem, plan, steps=steps, state0=state0, settings=settings)
    ctrl = build_controller(problem.robot, settings)
    if backend == "python":
        states, qdot, status = _python_loop(ctrl, inputs)
    elif backend == "casadi":
        states, qdot, status = _chunk_loop(rollout_chunk(ctrl, ROLLOUT_CHUNK), inputs)
    else:
        gen = generate(problem, out_dir, settings.plugin)
        states, qdot, status = _chunk_loop(gen.load(ROLLOUT_NAME), inputs)
    return Rollout(
        times=np.arange(inputs.steps + 1, dtype=np.float64) * inputs.dt,
        states=states,
        qdot=qdot,
        status=status.astype(int),
        errors=tracking_errors(ctrl, states, inputs.reference),
        backend=backend,
    )


# ----------------------------------------------------------------------------------- run file
def run_file_path(directory: str | os.PathLike[str]) -> Path:
    """The example's run file in a folder: ``DIR/run.bin``."""
    return Path(directory) / "run.bin"


def write_run_file(path: str | os.PathLike[str], inputs: RunInputs) -> Path:
    """Write a run's inputs for the C example (format: ``embedded/run_file.h``), atomically.

    Layout, little-endian: 8-byte magic ``MMSTRUN2``; int64 steps, state size, reference size,
    parameter count; float64 dt; params; state0; reference rows
    (steps + 1, 23), row-major.
    """
    sizes = np.array(
        [
            inputs.steps,
            len(inputs.state0),
            inputs.reference.shape[1],
            len(inputs.params),
        ],
        dtype="<i8",
    )
    body = [np.array([inputs.dt]), inputs.params, inputs.state0, inputs.reference]
    data = RUN_FILE_MAGIC + sizes.tobytes()
    data += b"".join(np.ascontiguousarray(a, dtype="<f8").tobytes() for a in body)

    def write(tmp: Path) -> None:
        tmp.write_bytes(data)

    return _atomic(Path(path), write)
