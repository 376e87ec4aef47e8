"""A tracked run's verdicts beside its tip: the arm against the robot and the ground, the slide.

``mmstab track`` and :func:`mmstab.track` judge a run by the same checks, at the run's saved
samples (every :data:`SAVE_EVERY_S`): the arm's self-collision and least clearance
(:func:`arm_collisions`), the slip verdict of the base's poses and turns and, on a heightmap,
the arm against the ground at the tracked rests (:func:`arm_in_ground_run`); with the tip,
one verdict per limit (:func:`run_verdicts`), whose exit status is ``mmstab plan``'s rule
(:func:`mmstab.runs.plan_verdicts.exit_status`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from mmstab.model.collision import CollisionChecker
from mmstab.model.collision_sequence import sequence_collisions
from mmstab.model.robot import FloatArray, Robot
from mmstab.runs.arm_ground import arm_heights_at_rest, in_ground_in_time
from mmstab.runs.tracking.run import TrackingRun
from mmstab.runs.verdict import arm_collision_verdict, robot_turn_check, slip_verdict
from mmstab.runs.verdict_settings import VerdictSettings
from mmstab.stability.support import is_heightmap
from mmstab.terrain import Terrain

#: Sample spacing of the saved arrays (``run.npz``) and of the run's checks [s].
SAVE_EVERY_S = 0.01
#: Distance [m] below which the run's link clearances are measured exactly first: the least
#: is below it in every shipped run (the turret sits 1 cm above the body), and measuring
#: only the pairs that come that near takes a fifth of the time.
CLEARANCE_CULL = 0.05


#: Spacing of the run's samples the arm is measured against the ground at [s] (1.25 cm at
#: 0.25 m/s: denser than the plan's 5 cm samples).
GROUND_EVERY_S = 0.05


def saved_samples(run: TrackingRun, spacing: float) -> NDArray[np.int_]:
    """Indices of the run's samples ``spacing`` [s] apart, the last one included."""
    every = max(int(round(spacing / run.dt)), 1)
    return np.unique(np.r_[np.arange(0, run.t.size, every), run.t.size - 1])


def tracked_checks(
    robot: Robot, terrain: Terrain, settings: VerdictSettings, run: TrackingRun
) -> tuple[NDArray[np.int_], dict[str, Any], dict[str, Any], dict[str, Any] | None]:
    """The verdicts beside ``run.tipped``: the saved samples, arm self-collision, slip, ground.

    Args:
        robot: the robot.
        terrain: the ground.
        settings: the slide's limits (``slip_distance``, ``slip_window``, ...).
        run: the tracked run.

    Returns:
        The indices of the samples kept (every ``SAVE_EVERY_S``), the arm self-collision
        record (``summary.json``'s ``arm_self_collision``) and the slip verdict (``slip``),
        both checked at those samples, and the arm against the ground on a heightmap
        (``arm_in_ground``, :func:`arm_in_ground_run`; None elsewhere).
    """
    keep = saved_samples(run, SAVE_EVERY_S)
    collisions = arm_collisions(robot, run.t[keep], run.state[keep, 5:])
    arm_com = robot.arm_com(run.state[keep, 5:])
    turns = robot_turn_check(robot, settings, arm_com, run.t[keep])
    slip = slip_verdict(terrain, run.state[keep, :3], turns)
    return keep, collisions, slip, arm_in_ground_run(robot, terrain, run)


def run_verdicts(
    robot: Robot, terrain: Terrain, settings: VerdictSettings, run: TrackingRun
) -> dict[str, dict[str, Any]]:
    """A run's verdict per limit: ``tip``, ``slide``, ``arm_contact``.

    Each has ``verdict`` (``holds``, ``tips``, ``slides``, ``collides``), ``unsafe`` and the
    records ``mmstab track`` writes for it (``tipped``, ``slip``, ``arm_self_collision`` and
    ``arm_in_ground``: the arm touches the robot, or the ground at the tracked rest).

    Args:
        robot: the robot.
        terrain: the ground.
        settings: the slide's limits.
        run: the tracked run.
    """
    _, collisions, slip, in_ground = tracked_checks(robot, terrain, settings, run)
    tipped = None if run.tipped is None else run.tipped.summary()
    touches = not collisions["verdict"]["safe"] or bool(in_ground and in_ground["contact"])
    return {
        "tip": {"verdict": "tips" if tipped else "holds", "unsafe": tipped is not None,
                "tipped": tipped},
        "slide": {"verdict": "slides" if slip["slides"] else "holds",
                  "unsafe": bool(slip["slides"]), "slip": slip},
        "arm_contact": {"verdict": "collides" if touches else "holds", "unsafe": touches,
                        "arm_self_collision": collisions, "arm_in_ground": in_ground},
    }  # fmt: skip


def arm_collisions(robot: Robot, t: FloatArray, q_arm: FloatArray) -> dict[str, Any]:
    """Where the tracked arm intersects the base or itself.

    Eq. 7 has no collision constraint: the posture task keeps the arm near the planner's
    collision-free postures (and the posture reference is checked and repaired,
    :mod:`mmstab.control.posture`); this checks what the arm actually did.

    Args:
        robot: the robot (its collision geometry).
        t: sample times (N,) [s].
        q_arm: arm postures (N, 4) [rad].

    Returns:
        samples checked, colliding samples and share, the colliding time intervals [s]
        (from the first colliding sample to the first free one after it), the colliding
        pairs with the number of samples each, the minimum link clearance [m] and its time
        [s], and the verdict (:func:`mmstab.runs.verdict.arm_collision_verdict`).
    """
    checker = CollisionChecker(robot)
    report, _ = sequence_collisions(checker, t, q_arm)
    # exact below CLEARANCE_CULL: the least of them is the run's, else measured everywhere
    clearance = checker.clearance(q_arm, cull_above=CLEARANCE_CULL)
    if clearance.min() >= CLEARANCE_CULL:
        clearance = checker.clearance(q_arm)
    k = int(np.argmin(clearance))
    return {
        "samples": report.samples,
        "colliding_samples": report.colliding_samples,
        "colliding_share": report.colliding_share,
        "intervals_s": report.intervals,
        "pairs": report.pairs,
        "min_clearance_m": float(clearance[k]),
        "min_clearance_time_s": float(np.asarray(t)[k]),
        "verdict": arm_collision_verdict(report.colliding_samples, float(clearance[k])),
    }


def arm_in_ground_run(robot: Robot, terrain: Terrain, run: TrackingRun) -> dict[str, Any] | None:
    """Where the tracked arm is in the ground at the rest of the tracked base (a heightmap's).

    The plan's check (:func:`mmstab.runs.arm_ground.arm_in_ground_record`) on the run: at
    samples :data:`GROUND_EVERY_S` apart, the body at the rest of the tracked base pose under
    the tracked arm's CoM, the arm in its tracked posture, its least height above the ground
    (:func:`mmstab.runs.arm_ground.arm_heights_at_rest`).

    Args:
        robot: the robot.
        terrain: the ground.
        run: the tracked run.

    Returns:
        None off a heightmap; else :func:`mmstab.runs.arm_ground.in_ground_in_time`'s record.
    """
    if not is_heightmap(terrain):
        return None
    k = saved_samples(run, GROUND_EVERY_S)
    h = arm_heights_at_rest(robot, terrain, run.state[k, :3], run.state[k, 5:])
    return in_ground_in_time(h, run.t[k])
