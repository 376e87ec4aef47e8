"""Never a stale "safe": what a live node may answer, in pure Python (no ROS needed).

A node on a robot (``mmstab node``, :mod:`mmstab.runs.online.node`) answers each elevation
map with the online loop's step (:meth:`~mmstab.runs.online.follow.Follower.update`) only
when its inputs are fresh and whole; otherwise it answers **stale** and says why. The rules,
each one tested without ROS (``tests/online/test_node_guard.py``):

* a map older than ``max_map_age`` [s] (wall clock now minus its header stamp) is stale;
* a map whose frame no transform joins to the odometry's is stale;
* odometry whose newest stamp is more than ``odom_timeout`` [s] before the map's stamp
  (it stopped) is stale; none at all is stale;
* a malformed map, odometry or joint state is stale (the reason is the message's fault);
* a map stamp that goes back (the publisher restarted, or a recording looped): the node
  forgets the odometry, joint states and transforms received before it and the loop's time
  base, and answers stale until fresh odometry arrives;
* no map for ``max_map_age`` of wall time: the watchdog publishes stale.

A stale answer carries every verdict at level ``STALE``, never the last ``OK``: a consumer
that reads only the levels can never take an old answer for a new one. Each reason is
logged once when it starts (and again every ``log_period`` [s] while it lasts); a fresh
answer ends it (:class:`ReasonLog`).

The verdicts of a fresh answer (:func:`verdicts`): ``tip`` (μ below the margin: ERROR),
``slide`` (the support tilts beyond atan(friction): ERROR), ``step`` (the tracks cannot
climb the step ahead with this arm: ERROR; the ground ahead not on the map: WARN),
``high-centred`` (the chassis touches the ground: ERROR), ``arm-contact`` (the arm, as it is
now at the robot's rest on the map, in the map's ground: ERROR; over an unknown cell: WARN)
and ``coverage`` (the map does not cover the robot's footprint: ERROR, and then the five
measures are STALE: the map cannot say).
"""

from __future__ import annotations

import math
from typing import NamedTuple

#: diagnostic_msgs/DiagnosticStatus levels.
OK, WARN, ERROR, STALE = 0, 1, 2, 3
#: ``stalls`` of :func:`verdicts` when the ground ahead is not on the map.
UNMAPPED = "unmapped"
#: The verdicts every answer carries, in order.
VERDICTS = ("tip", "slide", "step", "high-centred", "arm-contact", "coverage")


class GuardSettings(NamedTuple):
    """When a live input is too old.

    Attributes:
        max_map_age: a map older than this (wall clock minus its stamp) is stale [s];
            also the watchdog's period without any map [s].
        odom_timeout: odometry whose newest stamp is older than the map's by more than this
            has stopped [s].
        odom_wait: how long a map waits for the odometry of its stamp to arrive [s].
        log_period: a lasting reason is logged again after this long [s].
    """

    max_map_age: float = 0.5
    odom_timeout: float = 0.2
    odom_wait: float = 0.05
    log_period: float = 10.0


class Verdict(NamedTuple):
    """One verdict of an answer.

    Attributes:
        name: one of :data:`VERDICTS`.
        level: OK, WARN, ERROR or STALE (diagnostic_msgs levels).
        message: what it says (the reason, when stale).
    """

    name: str
    level: int
    message: str


def stale_verdicts(reason: str) -> list[Verdict]:
    """Every verdict at level STALE with ``reason``: the answer when inputs are not fresh."""
    return [Verdict(name, STALE, f"stale: {reason}") for name in VERDICTS]


def verdicts(
    covered: bool,
    mu: float,
    margin: float,
    tilt: float,
    friction: float,
    stalls: bool | str | None,
    high_centred: bool,
    arm_height: float,
) -> list[Verdict]:
    """The verdicts of a fresh answer (module text).

    Args:
        covered: the map covers the robot's footprint.
        mu: μ now [N rad] (NaN when not covered).
        margin: μ below it tips (``planner.margin``) [N rad].
        tilt: the support's tilt on the map [rad].
        friction: the tracks' friction [-]; they slide beyond atan(friction).
        stalls: the tracks cannot climb the step ahead with this arm (None: no step ahead;
            :data:`UNMAPPED`: the ground ahead is not on the map, a WARN).
        high_centred: the rested chassis touches the ground.
        arm_height: the arm's least height above the map's ground [m] (< 0: in it; NaN:
            over an unknown cell).
    """
    if not covered or not math.isfinite(mu):
        why = "the map does not cover the robot's footprint"
        return [Verdict(n, STALE, f"not covered: {why}") for n in VERDICTS[:-1]] + [
            Verdict("coverage", ERROR, f"not covered: {why}")
        ]
    critical = math.atan(friction)
    out = [
        Verdict("tip", ERROR, f"tips: mu {mu:.1f} N rad < margin {margin:g}")
        if mu < margin
        else Verdict("tip", OK, f"holds: mu {mu:.1f} N rad"),
        Verdict(
            "slide",
            ERROR if tilt > critical else OK,
            f"tilt {math.degrees(tilt):.1f} deg "
            f"{'beyond' if tilt > critical else 'within'} {math.degrees(critical):.1f} deg",
        ),
    ]
    if stalls is None:
        out.append(Verdict("step", OK, "no step ahead"))
    elif stalls == UNMAPPED:
        out.append(Verdict("step", WARN, "the ground ahead is not mapped"))
    else:
        out.append(
            Verdict(
                "step",
                ERROR if stalls else OK,
                "stalls at the step ahead" if stalls else "climbs the step ahead",
            )
        )
    out.append(
        Verdict("high-centred", ERROR, "the chassis touches the ground")
        if high_centred
        else Verdict("high-centred", OK, "on its tracks")
    )
    if not math.isfinite(arm_height):
        out.append(Verdict("arm-contact", WARN, "the ground under the arm is not mapped"))
    elif arm_height < 0.0:
        out.append(
            Verdict("arm-contact", ERROR, f"the arm {100 * -arm_height:.1f} cm in the ground")
        )
    else:
        out.append(
            Verdict("arm-contact", OK, f"the arm {100 * arm_height:.1f} cm above the ground")
        )
    out.append(Verdict("coverage", OK, "covered"))
    return out


class ReasonLog:
    """Say each reason once when it starts, again every ``period`` [s] while it lasts."""

    def __init__(self, period: float) -> None:
        self.period = period
        self.last: dict[str, float] = {}

    def say(self, key: str, now: float) -> bool:
        """Whether reason ``key`` is to be logged at wall time ``now`` [s]."""
        t = self.last.get(key)
        if t is not None and now - t < self.period:
            return False
        self.last[key] = now
        return True

    def clear(self) -> list[str]:
        """A fresh answer: the reasons that were active (to log their end), forgotten."""
        gone = list(self.last)
        self.last.clear()
        return gone


def map_fault(
    settings: GuardSettings,
    now: float,
    stamp: float,
    newest_odom: float | None,
) -> str | None:
    """Why a map cannot be answered fresh from the times alone, or None.

    Args:
        settings: the limits.
        now: wall clock [s] (the same clock as the stamps).
        stamp: the map's header stamp [s].
        newest_odom: the stamp of the newest odometry received [s] (None: none yet).
    """
    age = now - stamp
    if age > settings.max_map_age:
        return f"map is {age:.2f} s old (max_map_age {settings.max_map_age:g} s)"
    if newest_odom is None:
        return "no odometry received"
    lag = stamp - newest_odom
    if lag > settings.odom_timeout:
        limit = settings.odom_timeout
        return f"odometry stopped: newest {lag:.2f} s before the map (odom_timeout {limit:g} s)"
    return None
