"""The arm's moves between planned nodes: their map-independent part computed ahead.

A move into pose k (:meth:`RoadmapHorizon.move`) is computed once per pair of nodes, on the
map of the update that first needs it (the robot past pose k - 1): a shortest roadmap path
and its cut above the support plane, checked against the ground under the arm at poses
k - 1 and k on that map, the path searched again without the nodes found too low
(:func:`~mmstab.planner.searches.roadmap.moves.ground_move`). The paths and cuts do not
depend on the map, and they are the costly part: up to 35 ms a move on the rough route (the
collision tests of the cuts, the searches again), on top of that map's update. Here the move runs
ahead on the maps that re-scored no pose, on the latest map, a step (a path, a cut test) at
a time, for at most :data:`MOVE_BUDGET` a map (a step may run past it), the nearest planned
pair first; its paths and cuts are kept by the set of nodes masked
(:data:`~mmstab.planner.searches.roadmap.moves.Tries`), its answer dropped. The map that needs the
move runs it again with them: only its checks run, and the searches again where that map
masks other nodes. So every move is the one the map that needs it would compute alone.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Generator

from mmstab.model.collision import CollisionChecker
from mmstab.model.robot import FloatArray, Robot
from mmstab.planner.ground.under_arm import GroundUnderArm
from mmstab.planner.searches.roadmap.moves import Tries, ground_move_steps
from mmstab.workspace.roadmap import Roadmap

#: Time a map that re-scored no pose spends on the moves ahead [s] (a step may run past
#: it: 1-5 ms on the rough route).
MOVE_BUDGET = 0.003

Pair = tuple[int, int]
#: The ground under the arm at a pair's two poses on the latest map (None: not covered).
UnderOf = Callable[[Pair], GroundUnderArm | None]


class MovesAhead:
    """The planned moves' paths and cuts, computed a step at a time (module text).

    Args:
        robot: the robot.
        roadmap: the posture roadmap.
        checker: the robot's collision checker.
        ground: ``planner.ground_clearance`` [m] (the moves' nodes and cuts above the plane).
    """

    def __init__(
        self, robot: Robot, roadmap: Roadmap, checker: CollisionChecker, ground: float | None
    ) -> None:
        self.robot, self.roadmap, self.checker, self.ground = robot, roadmap, checker, ground
        self.tries: dict[Pair, Tries] = {}
        self.running: dict[Pair, Generator[None, None, FloatArray | None]] = {}
        self.queue: list[Pair] = []
        self.ran: set[Pair] = set()  # run to the end once: their tries are ready

    def want(self, pairs: list[Pair]) -> None:
        """The pairs of nodes (from, to) whose moves are needed next, nearest first.

        A pair no longer wanted (its nodes chosen again) is dropped, its tries too.
        """
        wanted = set(pairs)
        self.queue = [p for p in dict.fromkeys(pairs) if p not in self.ran]
        self.running = {p: g for p, g in self.running.items() if p in wanted}
        self.tries = {p: t for p, t in self.tries.items() if p in wanted}
        self.ran &= wanted

    def advance(self, seconds: float, under_of: UnderOf) -> int:
        """Step the wanted pairs' moves for ``seconds`` [s] on the latest map; the steps taken.

        One step at least (while a pair is wanted). ``under_of``: the ground under the arm
        at a pair's poses on the latest map.
        """
        end, steps = time.perf_counter() + seconds, 0
        while self.queue and (steps == 0 or time.perf_counter() < end):
            p = self.queue[0]
            if p not in self.running:
                under = under_of(p)
                tries = self.tries.setdefault(p, {})
                self.running[p] = ground_move_steps(
                    self.robot, self.roadmap, self.checker, *p, self.ground, under,
                    tuple(range(len(under))) if under is not None else (), tries=tries,
                )  # fmt: skip
            try:
                next(self.running[p])
            except StopIteration:  # its answer is the map's that needs it: not kept
                del self.running[p]
                self.ran.add(self.queue.pop(0))
            steps += 1
        return steps

    def take(self, a: int, b: int) -> Tries:
        """The tries of the move a -> b computed so far (forgotten here: used once)."""
        p = (a, b)
        self.queue = [x for x in self.queue if x != p]
        self.running.pop(p, None)
        self.ran.discard(p)
        return self.tries.pop(p, {})
