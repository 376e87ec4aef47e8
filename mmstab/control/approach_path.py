"""The approach's path and its timing: straight checked moves at rest at each knot.

A roadmap plan's start-up move and the lap's checked moves it joins are followed as straight
pieces (:func:`eased_polyline`), each rest to rest and given time by the square root of its
time at the joint-speed limits (the same peak acceleration for all), the whole lengthened
until no piece passes :data:`APPROACH_PEAK_SPEED` of the limits (:func:`approach_duration`).
Other plans' approaches follow a spline at the quintic rest-to-rest scaling
(:func:`time_scaling`), lengthened where the straight move would pass the joint-speed limits
(:func:`straight_approach_duration`).

The base drives while the arm approaches, for ``controller.approach_time`` or, when the
move needs longer, until the base reaches the plan's second pose at the latest: by then the
arm must be on the plan, whose poses were checked with the plan's arm. An approach that
needs longer, or cannot catch the lap at all (a lap that keeps moving its arm faster than
the approach), takes the plan's first move alone, onto the first posture, while the base
waits at the path's start (:class:`ApproachTime` ``base_wait``): the move was checked
there, and the lap then starts from its first posture.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.control.posture import PostureReference, piece_times
from mmstab.control.reference import PathSample
from mmstab.control.timing import JOINT_SPEED_SHARE
from mmstab.model.robot import FloatArray, Robot

#: Largest share of the joint-speed limits a roadmap plan's start-up move runs at (its
#: smoothstep peak); the approach is lengthened beyond ``approach_time`` when needed. The
#: tracked arm lags a fast posture reference where the arm-CoM task leaves it free (the
#: posture task's weight is 10x the joints' regularisation there), in proportion to the
#: speed: at 0.5 random route pair 10's arm still came within 1.1 mm of the track, at 0.3
#: it keeps 3 mm.
APPROACH_PEAK_SPEED = 0.3
#: Peak of the quintic rest-to-rest scaling's rate, max dσ/dτ (:func:`time_scaling`).
QUINTIC_PEAK = 1.875
#: Rounds of :func:`approach_duration`'s lengthening.
APPROACH_ROUNDS = 8
#: The lengthening has caught the lap when its last round added less than this share [-]:
#: it converges geometrically (random laps: within 3e-4 after the rounds), while a lap that
#: keeps its arm moving faster than the approach grows it by a factor each round.
CAUGHT = 0.01


def time_scaling(tau: ArrayLike) -> PathSample:
    """Quintic rest-to-rest time scaling σ(τ) = 10τ³ − 15τ⁴ + 6τ⁵ on τ ∈ [0, 1], and dσ/dτ.

    σ' and σ'' vanish at both ends, so a path followed at σ starts and stops at rest.
    """
    u = np.clip(np.asarray(tau, dtype=float), 0.0, 1.0)
    return PathSample(u**3 * (10 - 15 * u + 6 * u**2), 30 * u**2 * (1 - u) ** 2)


def eased_polyline(knots: FloatArray, postures: FloatArray) -> Any:
    """Straight moves between ``postures`` (M, 4) [rad] at ``knots`` (M,) in [0, 1].

    At rest at each knot: each piece is followed at the cubic smoothstep 3τ² − 2τ³ (τ the
    piece's fraction), so the path stays on the checked straight moves and its rate is
    continuous (0 at the knots). Returns ``path(u, nu=0)``: postures (nu 0) or d/du (nu 1) at u.
    """
    h, step = np.diff(knots), np.diff(postures, axis=0)

    def path(u: ArrayLike, nu: int = 0) -> FloatArray:
        ua = np.atleast_1d(np.asarray(u, dtype=float))
        k = np.clip(np.searchsorted(knots, ua, side="right") - 1, 0, len(h) - 1)
        tau = np.clip((ua - knots[k]) / h[k], 0.0, 1.0)
        if nu:
            out = (6 * tau * (1 - tau) / h[k])[:, None] * step[k]
        else:
            out = postures[k] + (tau * tau * (3 - 2 * tau))[:, None] * step[k]
        return out[0] if np.ndim(u) == 0 else out

    return path


def move_duration(robot: Robot, move: FloatArray) -> float:
    """Shortest time [s] of a roadmap move (n, 4) [rad] at :data:`APPROACH_PEAK_SPEED`.

    Its straight pieces run rest to rest (smoothstep, peak 1.5 times the mean speed), each
    given time in proportion to the square root of its time at the joint-speed limits a_i
    (:func:`~mmstab.control.posture.piece_times`: the same peak acceleration for all). Over
    T, piece i then lasts T √a_i / Σ√a and peaks at 1.5 √a_i Σ√a / T of the limits, so the
    longest piece keeps ``APPROACH_PEAK_SPEED`` with T = 1.5 √a_max Σ√a / APPROACH_PEAK_SPEED.
    On random route pair 10 the start-up move (4 rad on the elbow and the turret) in 1 s ran
    the elbow at 9 of its 12.6 rad/s; the arm lagged by 0.1 rad and touched the right track.
    """
    q = np.asarray(move, dtype=float)
    at_limit = (np.abs(np.diff(q, axis=0)) / robot.joint_velocity).max(axis=1)
    if at_limit.size == 0:
        return 0.0
    root = np.sqrt(at_limit)
    return float(1.5 * root.max() * root.sum() / APPROACH_PEAK_SPEED)


def roadmap_approach_knots(
    robot: Robot, move: FloatArray, posture: PostureReference, s_end: float
) -> tuple[FloatArray, FloatArray]:
    """The approach of a roadmap plan: its first move, then the lap's knots up to ``s_end``.

    The plan's move from the start posture onto its first posture (checked), then the lap
    reference's knots in (0, ``s_end``) and its posture at ``s_end`` (the lap's checked
    moves): knots (M,) in [0, 1], each piece's share the square root of its time at the
    joint-speed limits (:func:`~mmstab.control.posture.piece_times`: the same peak
    acceleration for all; in proportion to the time itself a 0.23 rad piece of random route
    pair 27's approach took 0.09 s, 170 rad/s², and the tracked turret overshot its end by
    0.024 rad into the body), and the postures (M, 4) [rad].
    """
    inside = (posture.fractions > 0) & (posture.fractions < s_end)
    q = np.vstack([move, posture.postures[inside], posture(s_end).value])
    keep = np.r_[True, np.abs(np.diff(q, axis=0)).max(axis=1) > 1e-12]
    q = q[keep]
    tau = piece_times(robot, q)
    return tau / tau[-1], q


class ApproachTime(NamedTuple):
    """How long a run's start-up approach lasts, and how long the base waits meanwhile.

    The approach takes ``duration`` [s] of real time; the base waits at the path's start
    for the first ``base_wait`` [s] of it, then drives, so the approach meets the lap at the
    nominal time ``duration - base_wait`` [s].

    Attributes:
        duration: the approach's length [s].
        base_wait: the base's wait at the start [s] (0: it drives all along).
    """

    duration: float
    base_wait: float = 0.0

    @property
    def meets(self) -> float:
        """The nominal time [s] at which the approach meets the lap."""
        return self.duration - self.base_wait


def _timed(
    needed: Callable[[float], float],
    first: float,
    least: float,
    lap_time: float,
    latest: float | None,
) -> ApproachTime:
    """An approach's time, lengthened until it needs no more, else the base's wait.

    Args:
        needed: the time [s] an approach that meets the lap at fraction s needs.
        first: the time [s] to start lengthening from.
        least: ``controller.approach_time`` [s]: the base always drives through it.
        lap_time: the lap's time [s].
        latest: when the base reaches the plan's second pose [s] (None: the lap's end).

    Returns:
        The lengthened approach when it caught the lap (its last round added less than
        :data:`CAUGHT`) by ``latest`` or within ``least``; else the approach onto the lap's
        start (``needed(0)``, at least ``least``), the base waiting all along.
    """
    latest = lap_time if latest is None else min(latest, lap_time)
    duration = previous = first
    for _ in range(APPROACH_ROUNDS):
        more = needed(duration / lap_time)
        if more <= duration * (1 + 1e-9):
            previous = duration
            break
        previous, duration = duration, more
    caught = duration <= previous * (1 + CAUGHT)  # else the lap's arm keeps ahead
    if caught and (duration <= least * (1 + 1e-9) or duration <= latest):
        return ApproachTime(duration)
    waiting = max(least, needed(0.0))
    return ApproachTime(waiting, waiting)


def approach_duration(
    robot: Robot,
    move: FloatArray,
    posture: PostureReference,
    least: float,
    lap_time: float,
    latest: float | None = None,
) -> ApproachTime:
    """A roadmap plan's approach time [s]: at least ``least`` [s], long enough for its pieces.

    The approach runs the plan's first move and the lap's checked moves up to where it meets
    the lap (:func:`roadmap_approach_knots`), so the pieces to time depend on the time: it is
    lengthened until every piece, the lap's too, keeps :data:`APPROACH_PEAK_SPEED`
    (:func:`move_duration`), at most :data:`APPROACH_ROUNDS` times. A lap that moves its arm
    faster than that all along would lengthen it without end. Where the lengthening has
    not caught the lap (:data:`CAUGHT`), or catches it only after ``latest`` (and after
    ``least``), the approach is the plan's first move alone, onto the lap's start, and the
    base waits at the start meanwhile (:class:`ApproachTime`).

    Args:
        robot: the robot (joint-speed limits [rad/s]).
        move: the plan's move from the start posture (n, 4) [rad].
        posture: the lap's posture reference.
        least: ``controller.approach_time`` [s].
        lap_time: the lap's time [s].
        latest: when the base reaches the plan's second pose [s] (None: the lap's end).
    """

    def needed(s_end: float) -> float:
        return move_duration(robot, roadmap_approach_knots(robot, move, posture, s_end)[1])

    return _timed(needed, max(least, move_duration(robot, move)), least, lap_time, latest)


def base_wait_note(approach: ApproachTime) -> str | None:
    """The note a run gives when its base waits at the start for the arm, else None."""
    if approach.base_wait <= 0:
        return None
    return (
        f"the base waits {approach.base_wait:.1f} s at the path's start while the arm "
        "unfolds onto the plan's first posture: on the move, the start-up approach (at "
        f"most {APPROACH_PEAK_SPEED:g} of the joints' speed limits, or the straight move's "
        f"{JOINT_SPEED_SHARE:g}) would not bring the arm onto the plan before the base "
        "reached the plan's second pose (docs/tracking.md, Approach)"
    )


def straight_approach_duration(
    robot: Robot,
    q0: FloatArray,
    posture: PostureReference,
    least: float,
    lap_time: float,
    latest: float | None = None,
) -> ApproachTime:
    """A straight approach's time [s]: at least ``least`` [s], within the joint-speed limits.

    The approach from ``q0`` ends on the lap's reference at s = T / lap_time, which moves
    with T; the straight move is timed by the quintic scaling (peak rate 1.875 times the
    mean), lengthened until no joint passes ``JOINT_SPEED_SHARE`` of its limit (the lap's
    rule, :mod:`mmstab.control.timing`), at most :data:`APPROACH_ROUNDS` times; where that
    has not caught the lap, or catches it only after ``latest``, it ends on the lap's start
    and the base waits meanwhile, as in :func:`approach_duration`. A user's
    3-joint arm (1 rad/s joints) ran its 1.7 rad turret move in 1 s at 3 times its limit;
    saturated, the arm lagged off the checked path and its forearm touched a flipper. The
    shipped problems' approaches keep their ``approach_time``.

    Args:
        robot: the robot (joint-speed limits [rad/s]).
        q0: the arm's initial posture (n,) [rad].
        posture: the lap's posture reference.
        least: ``controller.approach_time`` [s].
        lap_time: the lap's time [s].
        latest: when the base reaches the plan's second pose [s] (None: the lap's end).
    """
    q0 = np.asarray(q0, dtype=float)

    def needed(s_end: float) -> float:
        at_limit = float((np.abs(posture(s_end).value[0] - q0) / robot.joint_velocity).max())
        return QUINTIC_PEAK * at_limit / JOINT_SPEED_SHARE

    return _timed(needed, least, least, lap_time, latest)
