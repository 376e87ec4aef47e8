"""The arm's start-up approach, and the arm references of a run (lap + approach).

A run starts with the arm where it is (stowed, by default), not on the lap's posture
reference (:mod:`mmstab.control.posture`). Stepping the references there makes the arm jump at
saturated joint speeds, and on the default problem through a flipper, the body and a track.
:class:`Approach` is a collision-free joint path instead, from the initial posture onto the
lap's references over the first ``approach_time`` seconds, followed at a rest-to-rest time
scaling; its CoM is the arm-CoM reference meanwhile, as on the lap. The approach is longer
where its move needs it: a roadmap plan's pieces (:func:`approach_duration`), a straight
move within the joint-speed limits (:func:`straight_approach_duration`). The arm must be
on the lap by the plan's second pose: an approach that would need longer is the plan's first
move alone, and the base waits at the path's start meanwhile (:attr:`ArmReferences.hold`).
"""

from __future__ import annotations

import dataclasses
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.control.approach_path import (
    ApproachTime,
    approach_duration,
    base_wait_note,
    eased_polyline,
    roadmap_approach_knots,
    straight_approach_duration,
    time_scaling,
)
from mmstab.control.posture import (
    MAX_REPAIR_ROUNDS,
    PosturePlan,
    PostureReference,
    ViaPosture,
    body_frame_reference,
    build_posture_reference,
    posture_com,
    posture_samples,
)
from mmstab.control.reference import PathSample, StepReference, task_reference
from mmstab.control.timing import TimeLaw, build_time_law
from mmstab.core.masks import true_runs
from mmstab.core.notes import note
from mmstab.model.collision import CollisionChecker
from mmstab.model.collision_sequence import SequenceCollisions, sequence_collisions
from mmstab.model.robot import FloatArray, Robot
from mmstab.paths.base import BasePath
from mmstab.terrain import Terrain


def nearest_free(
    checker: CollisionChecker, robot: Robot, q: FloatArray, step: float
) -> FloatArray | None:
    """The collision-free posture nearest ``q`` along one joint at a time, if any.

    Candidates q ± k·step·e_j (k = 1, 2, …, within the joint limits) are checked in one batch;
    the one with the smallest move wins (ties: the lower joint index, + before −).

    Args:
        checker: the robot's collision checker.
        robot: the robot (joint limits).
        q: the colliding posture (4,) [rad].
        step: the move's resolution [rad].
    """
    lo, hi = robot.joint_lower, robot.joint_upper
    moves = np.arange(1, int(np.ceil(np.max(hi - lo) / step)) + 1) * step
    cand = []
    for k in moves:  # in order of the move, so the first free candidate is the nearest
        for j in range(q.size):
            for sign in (1.0, -1.0):
                c = q.copy()
                c[j] += sign * k
                if lo[j] <= c[j] <= hi[j]:
                    cand.append(c)
    if not cand:
        return None
    free = ~np.asarray(checker.collides(np.array(cand)), dtype=bool)
    return np.array(cand)[np.flatnonzero(free)[0]] if free.any() else None


@dataclasses.dataclass(frozen=True)
class Approach:
    """The arm's start-up reference: from the initial posture onto the lap's references.

    Over t ∈ [0, duration] the posture reference follows a path A(u) from the initial arm
    posture to q_ref(s_a) (s_a = (duration − base_wait) / lap_time), at the rest-to-rest
    time scaling u = σ(t / duration) (:func:`time_scaling`); A is a natural cubic spline
    through its knots (initial posture, via postures, end), straight when there are no via
    postures. As on the lap, the arm-CoM reference is the CoM of that posture, g_a^B(A(u)),
    so the CoM task and the posture task ask for the same motion, and it meets the lap's at
    t = duration. The path is checked at every control period and repaired with via
    postures (:func:`nearest_free`) where it collides.

    Attributes:
        duration: its length [s].
        knots: the path parameter of each knot (M,) in [0, 1].
        postures: the knots (M, 4) [rad].
        via: the via postures (``fraction`` is the path parameter u, ``interval`` in seconds).
        planned_check: the straight path, before any repair (x = time [s]).
        check: the path as used (x = time [s]).
        path: the spline A(u).
        robot: the robot (arm-CoM kinematics, joint limits).
        eased: A is an :func:`eased_polyline` (a roadmap plan's checked moves, at rest at
            each knot), followed at u = t / duration.
        base_wait: the base waits at the path's start for the approach's first
            ``base_wait`` [s], then drives: A ends on the lap at
            s_a = (duration − base_wait) / lap_time.
    """

    duration: float
    knots: FloatArray
    postures: FloatArray
    via: tuple[ViaPosture, ...]
    planned_check: SequenceCollisions
    check: SequenceCollisions
    path: Any
    robot: Robot
    eased: bool = False
    base_wait: float = 0.0

    def posture(self, t: ArrayLike) -> PathSample:
        """q_ref (N, 4) [rad] and its rate (N, 4) [rad/s] at times t (N,) [s]."""
        u, du = time_scaling(np.atleast_1d(np.asarray(t, dtype=float)) / self.duration)
        if self.eased:  # at rest at every knot already
            u = np.clip(np.atleast_1d(np.asarray(t, dtype=float)) / self.duration, 0.0, 1.0)
            du = np.where((u > 0) & (u < 1), 1.0, 0.0)
        q, dq = self.path(u), self.path(u, 1) * (du / self.duration)[:, None]
        lo, hi = self.robot.joint_lower, self.robot.joint_upper
        inside = (q >= lo) & (q <= hi)
        return PathSample(np.clip(q, lo, hi), np.where(inside, dq, 0.0))

    def com_body(self, t: ArrayLike) -> PathSample:
        """Body-frame arm-CoM reference (N, 3) [m] and its rate (N, 3) [m/s] at times t."""
        return posture_com(self.robot, self.posture(t))

    def summary(self) -> dict[str, Any]:
        """The report for ``summary.json``."""
        return {
            "duration_s": self.duration,
            "base_wait_s": self.base_wait,
            "start_posture": self.postures[0].tolist(),
            "end_posture": self.postures[-1].tolist(),
            "straight_path": self.planned_check._asdict(),
            "via_postures": [
                {"u": v.fraction, "posture": v.posture.tolist(), "repairs_s": list(v.interval)}
                for v in self.via
            ],
            "path": self.check._asdict(),
        }


def build_approach(
    robot: Robot,
    q0: ArrayLike,
    posture: PostureReference,
    duration: float,
    lap_time: float,
    dt: float,
    *,
    step: float = 0.05,
    move: FloatArray | None = None,
    base_wait: float = 0.0,
) -> Approach:
    """The start-up reference from the arm posture ``q0`` onto the lap's references.

    With ``move`` (a roadmap plan's checked move from ``q0`` onto its first posture) the
    path follows it and the lap's checked moves, at rest at each knot
    (:func:`roadmap_approach_knots`, :func:`eased_polyline`); else straight (repaired).

    Args:
        robot: the robot.
        q0: the arm's initial posture (4,) [rad].
        posture: the lap's posture reference.
        duration: the approach's length [s], > 0.
        lap_time: time of one lap [s].
        dt: control period [s]: the path is checked at every one.
        step: resolution of the via-posture search [rad] (:func:`nearest_free`).
        move: the plan's move from ``q0`` (n, 4) [rad], starting at ``q0``.
        base_wait: the base's wait at the path's start [s] (:class:`ApproachTime`): the
            approach ends on the lap at s = (duration − base_wait) / lap_time.

    Raises:
        ValueError: a duration that is not positive.
    """
    from scipy.interpolate import CubicSpline

    if not duration > 0:
        raise ValueError(f"the approach needs a positive duration, got {duration}")
    s_end = (duration - base_wait) / lap_time
    q_end = posture(s_end).value[0]
    knots, postures = np.array([0.0, 1.0]), np.vstack([np.asarray(q0, dtype=float), q_end])
    eased = move is not None and np.allclose(move[0], q0, atol=1e-9)
    if eased and move is not None:
        knots, postures = roadmap_approach_knots(robot, move, posture, s_end)
    t = np.arange(int(np.floor(duration / dt)) + 1) * dt
    checker = CollisionChecker(robot)
    unchecked = SequenceCollisions(0, 0, 0.0, [], {})

    def make(knots: FloatArray, postures: FloatArray) -> Approach:
        if eased:
            path = eased_polyline(knots, postures)
        else:
            path = CubicSpline(knots, postures, bc_type="natural")
        return Approach(
            duration, knots, postures, (), unchecked, unchecked, path, robot, eased, base_wait
        )

    approach = make(knots, postures)
    planned, hit = sequence_collisions(checker, t, approach.posture(t).value)
    check, via = planned, []
    for _ in range(MAX_REPAIR_ROUNDS):
        if not hit.any():
            break
        added = []
        for (a, b), interval in zip(true_runs(hit), check.intervals, strict=True):
            u_mid = float(time_scaling(0.5 * (t[a] + t[b - 1]) / duration).value)
            if np.min(np.abs(knots - u_mid)) < 1.0 / t.size:
                continue  # a knot already sits there (within one control period)
            q = nearest_free(checker, robot, approach.path(u_mid), step)
            if q is not None:
                pairs = tuple(checker.colliding_pairs(approach.path(u_mid)))
                added.append(ViaPosture(u_mid, q, (interval[0], interval[1]), pairs))
        if not added:
            break
        via.extend(added)
        order = np.argsort(np.r_[knots, [v.fraction for v in added]])
        knots = np.r_[knots, [v.fraction for v in added]][order]
        postures = np.vstack([postures, [v.posture for v in added]])[order]
        approach = make(knots, postures)
        check, hit = sequence_collisions(checker, t, approach.posture(t).value)
    return dataclasses.replace(approach, via=tuple(via), planned_check=planned, check=check)


class ArmReferences(NamedTuple):
    """The arm's references for a run: the lap's posture reference and the start-up approach.

    Attributes:
        posture: the lap's posture reference (checked and repaired).
        approach: the start-up reference (None when ``approach_time`` is 0).
        timing: the time law keeping the reference dynamically stable
            (:mod:`mmstab.control.timing`); None: ``dynamic_fraction`` null, or no ground.
    """

    posture: PostureReference
    approach: Approach | None
    timing: TimeLaw | None = None

    @property
    def hold(self) -> float:
        """Real time [s] the base waits at the path's start while the arm unfolds (0: none)."""
        return 0.0 if self.approach is None else self.approach.base_wait

    @property
    def retimed(self) -> bool:
        """Whether the references' nominal time differs from the real time."""
        return self.hold > 0 or bool(self.timing and self.timing.slows)

    def nominal(self, t: ArrayLike) -> PathSample:
        """Nominal times τ (N,) [s] of the references at real times t (N,) [s], and dτ/dt.

        τ stays 0 while the base waits (:attr:`hold`), then follows the time law (or τ = t)
        from the end of the wait.
        """
        moving = np.atleast_1d(np.asarray(t, dtype=float)) - self.hold
        if self.timing is not None and self.timing.slows:
            tau, speed = self.timing.nominal(np.maximum(moving, 0.0))
        else:
            tau, speed = np.maximum(moving, 0.0), np.ones_like(moving)
        return PathSample(tau, np.where(moving >= 0, speed, 0.0))

    def real_time(self, nominal: float) -> float:
        """The real time [s] a run needs to reach the nominal time [s] of its references."""
        moving = self.timing.real_time(nominal) if self.timing and self.timing.slows else nominal
        return self.hold + moving

    def timing_summary(self, run_end: float) -> dict[str, Any] | None:
        """The time law's report for a run that ended at real time ``run_end`` [s].

        The wait is left out (the approach's report has it); None without a time law.
        """
        if self.timing is None:
            return None
        return self.timing.summary(max(run_end - self.hold, 0.0))


def arm_references(
    robot: Robot,
    plan: PosturePlan,
    q0: ArrayLike,
    settings: Any,
    posture: PostureReference | None = None,
    ground: tuple[BasePath, Terrain] | None = None,
) -> ArmReferences:
    """The arm's references of a run starting with the arm at ``q0``.

    Args:
        robot: the robot.
        plan: the plan (``fractions``, ``target_com``, ``postures``).
        q0: the initial arm posture (4,) [rad].
        settings: the controller settings (``lap_time``, ``dt``, ``approach_time``) [s].
        posture: the lap's posture reference if already built (else built here, checked at
            every control period of a lap, :func:`posture_samples`).
        ground: the base path and the terrain: with them (and ``dynamic_fraction`` not
            None) the time law (:func:`mmstab.control.timing.build_time_law`) over the
            run's nominal ``duration`` [s].
    """
    if posture is None:
        samples = posture_samples(settings.lap_time, settings.dt)
        posture = build_posture_reference(robot, plan, samples)
    approach = None
    moves: tuple[FloatArray, ...] = tuple(getattr(plan, "moves", ()))
    move = moves[0] if moves and len(moves) == len(plan.postures) else None
    if settings.approach_time > 0:
        least, lap_time = settings.approach_time, settings.lap_time
        fractions = np.asarray(plan.fractions, dtype=float)
        latest = fractions[1] * lap_time if fractions.size > 1 else lap_time  # 2nd pose
        timed: ApproachTime
        if move is not None:  # lengthened when the plan's first move needs it
            timed = approach_duration(robot, move, posture, least, lap_time, latest)
        else:  # lengthened when the straight move would pass the joint-speed limits
            q0 = np.asarray(q0, dtype=float)
            timed = straight_approach_duration(robot, q0, posture, least, lap_time, latest)
        approach = build_approach(
            robot, q0, posture, timed.duration, lap_time, settings.dt, move=move,
            base_wait=timed.base_wait,
        )  # fmt: skip
        if (waits := base_wait_note(timed)) is not None:
            note(f"mmstab: note: {waits}")
    fraction = getattr(settings, "dynamic_fraction", None)
    if ground is None or fraction is None:
        return ArmReferences(posture, approach)
    start = 0.0 if approach is None else approach.duration - approach.base_wait
    window = (start, settings.duration)
    law = build_time_law(
        robot, *ground, posture, settings.lap_time, plan.fractions, fraction, window
    )
    return ArmReferences(posture, approach, law)


class RunReference(NamedTuple):
    """Everything a run tracks: the arm's references and the per-step references.

    Attributes:
        arm: the lap's posture reference and the start-up approach.
        step: the reference at each time (ξ_des, ξ̇_ref, q_ref, q̇_ref), arm CoM in M: what
            the run's errors are reported against.
        control: what the controller's step takes: ``step``, with the arm-CoM rows in B for
            ``arm_com_frame: body`` (:func:`mmstab.control.posture.body_frame_reference`).
    """

    arm: ArmReferences
    step: StepReference
    control: StepReference


def run_reference(
    robot: Robot,
    circle: BasePath,
    terrain: Terrain,
    plan: PosturePlan,
    q0: ArrayLike,
    settings: Any,
    t: ArrayLike,
    posture: PostureReference | None = None,
    arm: ArmReferences | None = None,
) -> RunReference:
    """The references of a run from the arm at ``q0``, at times ``t`` (simulation and rollout).

    Args:
        robot: the robot.
        circle: the base path (the circle or a route).
        terrain: the ground.
        plan: the plan (``fractions``, ``target_com``, ``postures``).
        q0: the initial arm posture (4,) [rad].
        settings: the controller settings (``lap_time``, ``dt``, ``approach_time``,
            ``base_offset``, ``arm_com_frame``).
        t: the times (T,) [s].
        posture: the lap's posture reference if already built.
        arm: the arm's references if already built (:func:`arm_references`, with the
            ground: its time law then times the references; ``t`` are real times).
    """
    if arm is None:
        arm = arm_references(robot, plan, q0, settings, posture, (circle, terrain))
    step = task_reference(
        circle,
        terrain,
        settings.lap_time,
        settings.base_offset,
        arm.posture.arm_reference(circle, terrain),
        arm.posture,
        np.asarray(t, dtype=float),
        arm.approach,
        arm.nominal if arm.retimed else None,
    )
    body = settings.arm_com_frame == "body"
    return RunReference(arm, step, body_frame_reference(robot, step) if body else step)
