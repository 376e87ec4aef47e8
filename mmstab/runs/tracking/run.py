"""What a tracking run records (:class:`TrackingRun`), and the checks of its inputs."""

from __future__ import annotations

import dataclasses
from typing import Any, Literal, NamedTuple, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.control.approach import Approach
from mmstab.control.controller import ARM, QPStatus, TaskModel
from mmstab.control.posture import PostureReference
from mmstab.control.reference import PlanLike
from mmstab.control.timing import TimeLaw
from mmstab.core.files import MmstabError
from mmstab.model.robot import FloatArray, Robot
from mmstab.stability.support import StabilityCases
from mmstab.terrain import Terrain
from mmstab.workspace.ik import COM_TOLERANCE


def state_names(arm_joints: int) -> tuple[str, ...]:
    """Names of the state components for an arm of ``arm_joints`` joints."""
    return ("x", "y", "heading", "theta_l", "theta_r", *(f"theta_{j}" for j in range(arm_joints)))


def joint_names(arm_joints: int) -> tuple[str, ...]:
    """Names of the joints (q̇ columns, as in the summary) for an arm of ``arm_joints`` joints."""
    return ("track_left", "track_right", *(f"link{j}" for j in range(arm_joints)))


#: Names of the state components of the 4-DoF arm's runs, for messages and saved arrays.
STATE_NAMES = state_names(4)
#: Names of the 4-DoF arm's joints (q̇ columns), as in the summary.
JOINT_NAMES = joint_names(4)
InitialArm = Literal["stowed", "planned"]
#: The transient ends once the arm-CoM error stays within this share of its initial value.
TRANSIENT_FRACTION = 0.01


class TrackingPlan(PlanLike, Protocol):
    """What :func:`simulate` needs of a plan (:class:`mmstab.planner.Plan` has it)."""

    @property
    def postures(self) -> FloatArray:
        """Arm postures realising the targets (K, 4) [rad]: the posture task's reference."""
        ...


# ----------------------------------------------------------------------------------- results
class Failure(NamedTuple):
    """One control period that held still: step index, time [s], status."""

    step: int
    time: float
    status: QPStatus


class Tipping(NamedTuple):
    """Where a run tipped over: the first sample with μ < 0 (the run stops there).

    Attributes:
        step: sample index.
        time: its time [s].
        pose: base pose (x, y, heading) in M [m, m, rad].
        mu: μ there (arm as it moved) [N rad].
    """

    step: int
    time: float
    pose: FloatArray
    mu: float

    def summary(self) -> dict[str, Any]:
        """The ``tipped`` record of ``summary.json``."""
        return {"step": self.step, "time_s": self.time, "pose": self.pose, "mu": self.mu}


@dataclasses.dataclass(frozen=True)
class TrackingRun:
    """A simulated run: N control periods, N+1 samples.

    Attributes:
        t: sample times (N+1,) [s].
        state: states (N+1, 5 + n): base pose in M [m, m, rad], sprockets and arm joints [rad].
        qdot: joint speeds applied over each period (N, 6) [rad/s] (zero when it failed).
        status: the step's :class:`QPStatus` per period (N,).
        xi: task ξ in M (N+1, 6) [m, m, rad, m, m, m].
        xi_des: reference ξ_des in M (N+1, 6).
        xi_dot_ref: reference rate (N+1, 6) [m/s, rad/s].
        q_ref: arm posture reference (N+1, n) [rad].
        posture_error: q_ref − q_arm (N+1, n) [rad].
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
        tipped: where the robot would tip over (μ < 0), the run's last sample; None if not.
        timing: the arm's time law (:mod:`mmstab.control.timing`), None when off.
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
    mu: StabilityCases
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
    tipped: Tipping | None = None
    timing: TimeLaw | None = None

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
        states: states (N, 5 + n) [m, m, rad, rad...].

    Returns:
        (ξ (N, 6) in M [m, m, rad, m, m, m], arm CoM in the body frame (N, 3) [m]).
    """
    s = np.atleast_2d(np.asarray(states, dtype=float))
    xi = model.task_batch(s, terrain.local_ground(s[:, :3]))
    return xi, np.atleast_2d(model.robot.arm_com(s[:, ARM]))


def check_plan(plan: TrackingPlan, robot: Robot) -> None:
    """Check a plan once, at the simulation's boundary.

    Raises:
        MmstabError: fractions, targets or postures of the wrong shape, not finite, outside
            the joint limits, or postures that do not realise the targets.
    """
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
        raise MmstabError(f"plan: the posture task needs postures (K, n): {exc}") from None
    n = robot.arm_joints
    if postures.shape != (fractions.size, n):
        raise MmstabError(
            f"plan: postures {postures.shape} do not match fractions {fractions.shape} "
            f"(the posture task needs one arm posture ({n},) per fraction)"
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
