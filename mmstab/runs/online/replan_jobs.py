"""The horizon's re-plans run a step at a time within a per-map budget, and land on a fixed map.

A re-plan (poses scored on a map, then the choices from them made again,
:class:`~mmstab.runs.online.roadmap_horizon.RoadmapHorizon`) costs 10-20 ms of one map,
five to ten times a map that only confirms the horizon. Most are not needed at once: a pose
that enters the horizon 2 m ahead, or one whose arm's reach the map has just covered (its
node still clear of the ground), is not what the step reads before the robot gets there.
So a re-plan is a :class:`Job`:

- it is **computed** as a coroutine (a greenlet: it hands control back between its steps,
  nothing runs concurrently), on the data of the map that triggered it (the map, its rests,
  its ground under the arm, the arm's posture) and after the re-plans triggered before it,
  so it computes what re-planning at once would (the same candidates, the same choices);
  every map gives the queued jobs its spare time after its answer, :data:`SPARE_BUDGET`
  (one step at least; a step may run past it);
- it **lands** (its answers become the plans the step reads and every map checks) on a
  fixed map: :data:`LAND_AFTER` maps after its trigger, or earlier when the robot comes
  near one of its poses whose last landed plan the map made invalid (a new pose, its
  gravity turned, its node too low: within the first :data:`NEAR_POSES` of the horizon),
  and then with every job before it. A re-plan triggered with such a pose already near
  lands on its own map (computed at once). Until a job lands, the step uses the last
  landed plans; the maps check them against the ground under the arm as before.

When a job lands depends on the map count, never on the clock: the same recording gives
the same answers. The steps are where the computation calls back into the loop's code
(:func:`pause`): the pose's fitness per round of the candidates' search, the ground check
per pose measured, between the re-choice's parts.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Generic, TypeVar

from greenlet import greenlet

#: Each map's spare time, after its answer [s]: the loop's processor time
#: (:func:`time.thread_time`, so that other processes on its core do not starve the
#: re-plans) in which the queued re-plans' steps run, then the moves ahead; one step at
#: least per map, and a step may run past it (up to ~4 ms with the arm kept clear through
#: 12 deg of body tilt). The answer does not wait for it; a re-plan not computed by the map
#: it lands on is computed there, before the answer. 10 ms on the rough route, one core:
#: with 6 ms the 12 deg margin's re-plans were still running when they landed (p99 from
#: map to answer 25 ms; 12 ms: 6.5 ms), the loop's time per map up to 18 ms at p99.
SPARE_BUDGET = 0.010
#: Maps after its trigger on which a deferred re-plan lands.
LAND_AFTER = 8
#: The horizon's first poses (the one behind the robot, the next two ahead): a re-plan of
#: a pose without a valid landed plan lands before the pose is among them.
NEAR_POSES = 3

T = TypeVar("T")


class _Step(greenlet):
    """A job's coroutine (:func:`pause` hands control back only inside one)."""


_FORCED = [False]  # jobs being computed to the end (landing): their pauses do nothing


def stepped() -> bool:
    """Whether a job is running a step at a time (:func:`pause` ends its step)."""
    return isinstance(greenlet.getcurrent(), _Step) and not _FORCED[0]


def pause() -> None:
    """End a step of the running job (nothing outside a job, or when it must finish now)."""
    if stepped():
        greenlet.getcurrent().parent.switch()


@dataclass
class Job(Generic[T]):
    """One re-plan.

    Attributes:
        compute: the computation; returns what lands.
        land_at: the map (the horizon's count of updates) on which it lands.
        invalid: the poses whose landed plan it replaces because it is not valid any more.
        touches: the poses whose plans it may change.
        answer: what landed returns (None until computed).
    """

    compute: Callable[[], T]
    land_at: int
    invalid: frozenset[int]
    touches: frozenset[int] = frozenset()
    answer: T | None = None
    _let: _Step | None = None
    done: bool = False


class Jobs(Generic[T]):
    """The queued re-plans, computed in order (module text).

    Args:
        budget: :data:`SPARE_BUDGET` [s]; None: every job is computed and lands at once.
    """

    def __init__(self, budget: float | None = SPARE_BUDGET) -> None:
        self.budget = budget
        self.queue: list[Job[T]] = []
        self.steps = 0  # steps run, over the run

    def add(self, job: Job[T]) -> None:
        """Queue a job (computed after the ones before it)."""
        self.queue.append(job)

    def pending(self) -> bool:
        """Whether a queued job is not computed yet."""
        return any(not j.done for j in self.queue)

    def replacing(self) -> set[int]:
        """The poses whose landed plans the queued jobs replace as invalid."""
        return set().union(*(j.invalid for j in self.queue))

    def step(self) -> bool:
        """One step of the first job not computed; False when all are."""
        job = next((j for j in self.queue if not j.done), None)
        if job is None:
            return False
        if job._let is None:
            job._let = _Step(run=job.compute)
        out = job._let.switch()
        if job._let.dead:
            job.answer, job.done, job._let = out, True, None
        self.steps += 1
        return True

    def advance(self, until: float) -> None:
        """Step the queued jobs until ``until`` [s] (:func:`time.thread_time`; one at least)."""
        first = True
        while (first or time.thread_time() < until) and self.step():
            first = False

    def due(
        self,
        index: int,
        near: set[int],
        everything: bool = False,
        touching: set[int] | None = None,
    ) -> list[T]:
        """Land the jobs due on map ``index``: computed now if not yet, in order.

        Due: its map reached, a pose of its ``invalid`` among ``near``, one of its
        ``touches`` in ``touching``, every job before a due one; with ``everything`` (or no
        budget) all of them.
        """
        last = -1
        for i, j in enumerate(self.queue):
            if (
                everything
                or self.budget is None
                or j.land_at <= index
                or j.invalid & near
                or (touching is not None and j.touches & touching)
            ):
                last = i
        _FORCED[0] = True  # each computed to its end in one go
        try:
            while any(not j.done for j in self.queue[: last + 1]):
                self.step()
        finally:
            _FORCED[0] = False
        landed, self.queue = self.queue[: last + 1], self.queue[last + 1 :]
        return [j.answer for j in landed if j.answer is not None]
