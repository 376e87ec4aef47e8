"""The receding horizon on the posture roadmap (``online: {planner: roadmap}``).

The same horizon as :class:`~mmstab.runs.online.horizon.HorizonPlanner` (the route's planned
poses from behind the robot to ``online.horizon`` ahead, each rested on the latest map, a
pose re-scored when new or when the map turned its gravity by more than
``online.replan_tol``, what the map does not cover reported), but each pose's posture is a
node of the posture roadmap (:mod:`mmstab.workspace.roadmap`), chosen as the offline
``method: roadmap`` chooses it (:mod:`mmstab.planner.searches.roadmap`):

- a pose's candidates are its best reachable nodes by Eq. 6's stability term, spread over
  the turret, each clear of the robot; they are scored once per ground the pose gets and
  kept while the map confirms it (the warm start: nothing is searched twice);
- after an update that re-scored a pose, the choices from the first re-scored pose to the
  last covered one are made again, exactly, by dynamic programming over the kept
  candidates (Eq. 6's motion term between consecutive choices, the turret window), from
  the previous pose's choice (or, at the start, the arm's posture);
- the posture reference between two planned poses runs along the roadmap path between
  their nodes (shortcut where free), so the arm's commanded moves are collision-free by
  construction, as offline;
- the arm keeps ``planner.ground_clearance`` above the ground under it on the map
  (:mod:`mmstab.planner.ground.map_ground`, through tilts of ``planner.attitude_margin``): a
  pose is scored with that map's ground at it, and every map measures each planned pose's
  chosen node again; a node now too low re-scores its pose though its gravity stands;
- a re-plan (the scoring and the choice after it) is computed on the data of the map that
  triggered it, in order, but a step at a time in the maps' spare time, and lands (becomes
  the plan the step reads and the maps check) on a fixed later map, unless the step is
  about to read a pose it replaces as invalid (:mod:`mmstab.runs.online.replan_jobs`).
"""

from __future__ import annotations

import time
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from mmstab.core.files import MmstabError
from mmstab.model.collision import CollisionChecker
from mmstab.model.robot import FloatArray, Robot
from mmstab.planner.candidates import Candidates, NodeClearance, route_candidates
from mmstab.planner.fitness import LinearFitness, pose_fitness, same_axes, support_polygons_at
from mmstab.planner.ground.map_ground import ArmGround, MapGround
from mmstab.planner.ground.under_arm import KeptPieces
from mmstab.planner.grounded import shortcut_above
from mmstab.planner.motion import motion_cost, transitions
from mmstab.planner.searches import roadmap as rp
from mmstab.planner.searches.roadmap.moves import ground_move
from mmstab.planner.settings import PlannerSettings
from mmstab.runs.online.ground_choice import clearance_on, forbid_low
from mmstab.runs.online.horizon import (
    HorizonPose,
    HorizonUpdate,
    Rested,
    horizon_window,
    sort_poses,
)
from mmstab.runs.online.moves_ahead import MOVE_BUDGET, MovesAhead
from mmstab.runs.online.replan_jobs import LAND_AFTER, NEAR_POSES, Job, Jobs, pause
from mmstab.runs.online.replan_steps import PausedFitness, PausedGround, PausedPieces
from mmstab.stability.static import mu_max as stowed_flat_mu
from mmstab.terrain import Terrain
from mmstab.terrain.heightmap import Heightmap
from mmstab.terrain.heightmap_terrain import HeightmapTerrain
from mmstab.workspace.roadmap import Roadmap


class PoseCandidates(NamedTuple):
    """One pose's candidate nodes on the ground it was scored on.

    Attributes:
        gravity_body: gravity in B there [m/s^2].
        rows: rows of the reachable nodes (M,).
        value: Eq. 6's stability term of each (-inf: unstable or not clear) (M,).
        mu: μ of each [N rad] (M,).
        scored_at: the update's time [s].
    """

    gravity_body: FloatArray
    rows: NDArray[np.intp]
    value: FloatArray
    mu: FloatArray
    scored_at: float


class Landed(NamedTuple):
    """What a re-plan's choice sets, landed at once or later (:mod:`replan_jobs`).

    Attributes:
        nodes: the chosen node per pose.
        plans: the plan per pose.
        start_q: the arm's posture before the chain, when the pose before it has no node.
    """

    nodes: dict[int, int]
    plans: dict[int, HorizonPose]
    start_q: dict[int, FloatArray]


class RoadmapHorizon:
    """The horizon's plans on the posture roadmap, updated map by map (module text).

    Args:
        robot: the robot.
        roadmap: the posture roadmap of the robot's V.
        settings: the planner settings (weights, ``turret_window``, ``sequence_candidates``).
        s_grid: arc lengths of the route's planned poses (K,) [m].
        poses_grid: those poses (K, 3) in the map frame [m, m, rad].
        replan_tol: gravity change that re-scores a pose [rad].
    """

    def __init__(
        self,
        robot: Robot,
        roadmap: Roadmap,
        settings: PlannerSettings,
        s_grid: FloatArray,
        poses_grid: FloatArray,
        replan_tol: float,
    ) -> None:
        if robot.tool_wrench is not None:
            raise MmstabError("online: planner roadmap does not take payload.wrench yet")
        self.robot, self.roadmap, self.settings = robot, roadmap, settings
        self.s_grid, self.poses_grid, self.replan_tol = s_grid, poses_grid, replan_tol
        self.mu_max = stowed_flat_mu(robot)
        start = roadmap.connect(robot.stowed, robot)
        self.view = rp.component_view(robot, roadmap, start, settings.ground_clearance)
        self.reach, self.samples = self.view.reach, self.view.samples
        span = (self.view.diameter, self.view.joint_span)
        self.cost = motion_cost(roadmap.nodes_q[self.reach], self.samples, span, settings)
        self.clear = NodeClearance(roadmap, self.reach, settings.ground_clearance)
        self.count = min(settings.sequence_candidates, len(self.reach))
        self.candidates: dict[int, PoseCandidates] = {}
        # the landed plans: what the step reads and every map checks (replan_jobs)
        self.plans: dict[int, HorizonPose] = {}
        self.nodes: dict[int, int] = {}  # the chosen node per planned pose
        self.start_q: dict[int, FloatArray] = {}  # the arm's posture before an unplanned k-1
        # the re-plans' answers as computed, in their order (landed or not)
        self.chosen = Landed({}, {}, {})
        self.known: dict[int, FloatArray] = {}  # the gravity each pose is (to be) scored on
        self.jobs: Jobs[Landed] = Jobs()
        self.maps = 0  # updates so far
        self._moves: dict[tuple[int, int], FloatArray] = {}
        self._checker = CollisionChecker(robot)
        self.ahead = MovesAhead(robot, roadmap, self._checker, settings.ground_clearance)
        self._arm: tuple[ArmGround, KeptPieces] | None = None  # built on the first map
        self.unknown: set[int] = set()  # poses scored with unknown cells in the arm's reach
        #: poses re-scored for the ground under the arm (gravity unchanged); scorings with
        #: unknown cells in the arm's reach; of those, re-scored once the reach was mapped
        #: and the planned poses whose chosen arm passed over unknown cells, summed over maps
        self.arm_ground = {
            "ground_rescored": 0, "reach_unknown": 0, "unknown_rescored": 0, "over_unknown": 0,
            "moves_plane_only": 0,
        }  # fmt: skip
        self._ground: MapGround | None = None  # the latest map's
        self._spare: tuple[list[int], MapGround | None] = ([], None)  # for the spare time

    def warm_up(self, tilt: float = 0.3) -> None:
        """Score flat ground and ground tilted by ``tilt`` [rad] four ways, before the first map.

        The first scoring pays for first uses (the candidates' arrays and caches): a robot
        pays them before it drives, not on its first map (27 -> 18 ms on the rough route).
        With the ground check, the tilted grounds are also scored on a flat 4 m map with the
        ground under the arm (its pieces, their arrays), then forgotten.
        """
        c, s = np.cos(tilt), np.sin(tilt)
        down = np.array([[0, 0, -1], [s, 0, -c], [-s, 0, -c], [0, s, -c], [0, -s, -c]])
        self._candidates(9.81 * down)
        if self.settings.ground_clearance is None:
            return
        flat = Heightmap.build(np.zeros((81, 81)), 0.05, np.array([-2.0, -2.0]), "warm-up")
        terrain = HeightmapTerrain(flat)
        arm = self._arm_on(terrain)
        ks = list(range(-len(down), 0))  # no route pose's index
        flat_ground = MapGround(arm[0], terrain, dict.fromkeys(ks, np.eye(4)), len(self.reach))
        self._score(ks, 9.81 * down, 0.0, flat_ground)
        for k in ks:
            del self.candidates[k]
        self.unknown.clear()
        self.arm_ground = dict.fromkeys(self.arm_ground, 0)

    def _arm_on(self, terrain: HeightmapTerrain) -> tuple[ArmGround, KeptPieces]:
        """The arm's pieces for the ground check (built once) and their kept body frames."""
        if self._arm is None:
            arm = ArmGround.of(self.robot, terrain, self.settings.attitude_margin or 0.0)
            self._arm = arm, PausedPieces(arm.base, self.roadmap.nodes_q)  # by node, as offline
        return self._arm

    def _candidates(
        self,
        gravity: FloatArray,
        clear: NodeClearance | None = None,
        polygons: list[FloatArray] | None = None,
    ) -> Candidates:
        """Each pose's candidates at gravities (n, 3) [m/s^2] in B, in one batch.

        ``polygons``: each pose's support polygon in B (None: the tracks' rectangle).
        """
        clear = self.clear if clear is None else clear
        stab = self.settings._replace(w_motion=0.0)
        stowed = self.robot.arm_com(self.robot.stowed)
        d = self.view.diameter
        polys: list[Any] = [None] * len(gravity) if polygons is None else list(polygons)
        fits: list[LinearFitness] = [
            PausedFitness(*f)
            for f in same_axes([
                pose_fitness(self.robot, g, stowed, stab, self.mu_max, d, p).linear()
                for g, p in zip(gravity, polys, strict=True)
            ])
        ]  # fmt: skip
        v = self.view
        pause()
        return route_candidates(fits, self.samples, v.bins, v.clusters, self.count, clear)

    def window(self, s_now: float, ahead: float) -> list[int]:
        """Grid indices from the pose at or behind ``s_now`` [m] to ``ahead`` [m] past it."""
        return horizon_window(self.s_grid, s_now, ahead)

    def update(
        self,
        terrain: Terrain,
        ks: list[int],
        rested: Rested,
        now: float,
        arm_com: FloatArray,
        arm_q: FloatArray,
    ) -> HorizonUpdate:
        """Queue the re-plans of the poses whose ground changed; land those due.

        A re-plan scores the poses, then chooses again from the first of them
        (:meth:`_replan`); it is computed in the maps' spare time (:meth:`spare`) and lands
        :data:`~mmstab.runs.online.replan_jobs.LAND_AFTER` maps later, or at once when one
        of its poses without a valid landed plan is among the horizon's first
        :data:`~mmstab.runs.online.replan_jobs.NEAR_POSES` (module text).

        Args:
            terrain: the latest map (the ground under the arm; the rests are ``rested``).
            ks: the horizon's grid indices, in driving order.
            rested: those poses rested on the map.
            now: the update's time [s].
            arm_com: the arm's CoM now, body frame [m].
            arm_q: the arm's posture now [rad].
        """
        self.maps += 1
        changes = sort_poses(ks, rested, self.known, self.replan_tol)
        ground = self._ground = self._map_ground(terrain, ks, rested)
        valid: set[int] = set()  # re-scored for their mapped reach, their landed node clear
        if ground is not None:
            again, mapped = self._recheck(ground, changes.kept)
            valid = (mapped & set(self.nodes)) - self.jobs.replacing()
            kept = tuple(k for k in changes.kept if k not in again | mapped)
            changes = HorizonUpdate(
                tuple(k for k in ks if k not in kept and k not in changes.uncovered),
                kept,
                changes.uncovered,
            )
        replanned = list(changes.replanned)
        near, at_once = set(ks[:NEAR_POSES]), False
        for landed in self.jobs.due(self.maps, near):
            self._land(landed)
        if replanned:
            g = rested.gravity_body[[ks.index(k) for k in replanned]]
            self.known.update(zip(replanned, g, strict=True))
            self._note_reach(replanned, ground)
            invalid = frozenset(replanned) - valid
            compute = lambda: self._replan(terrain, ks, replanned, g, now, ground, arm_q)  # noqa: E731
            touches = frozenset(k for k in ks if k >= replanned[0] - 1)
            self.jobs.add(Job(compute, self.maps + LAND_AFTER, invalid, touches))
            at_once = self.jobs.budget is None or bool(invalid & near)
            if at_once:  # the step reads it soon: this one (and those before) now
                for landed in self.jobs.due(self.maps, near, everything=True):
                    self._land(landed)
        self._spare = (ks, None if at_once else ground)
        return changes

    def spare(self, until: float) -> None:
        """The map's spare time, after its step: the re-plans' steps, else the moves ahead.

        The queued re-plans' steps until ``until`` (:func:`time.thread_time` [s]; one step
        at least); then, on a map that re-scored no pose at once, the moves ahead
        (``moves_ahead``) for the time left, or :data:`MOVE_BUDGET` with no re-plan queued:
        the moves between the landed nodes and between the re-plans' nodes not landed yet,
        nearest first.
        """
        ks, ground = self._spare
        queued = self.jobs.pending()
        if queued:
            self.jobs.advance(until)
        left = until - time.thread_time() if queued else MOVE_BUDGET
        if ground is None or left <= 0:
            return
        at: dict[tuple[int, int], list[int]] = {}
        for k in ks:
            for n in (self.nodes, self.chosen.nodes):
                if k - 1 in n and k in n:
                    at.setdefault((n[k - 1], n[k]), [k - 1, k])
        self.ahead.want([p for p in at if p not in self._moves])
        self.ahead.advance(
            left, lambda p: ground.under(at[p]) if set(at[p]) <= set(ground.M_T_B) else None
        )

    def settle(self) -> None:
        """Land every queued re-plan (at the end of a run)."""
        for landed in self.jobs.due(self.maps, set(), everything=True):
            self._land(landed)

    def _land(self, landed: Landed) -> None:
        """A re-plan's answers become the plans the step reads."""
        self.nodes.update(landed.nodes)
        self.plans.update(landed.plans)
        self.start_q.update(landed.start_q)

    def _replan(
        self,
        terrain: Terrain,
        ks: list[int],
        replanned: list[int],
        gravity: FloatArray,
        now: float,
        ground: MapGround | None,
        arm_q: FloatArray,
    ) -> Landed:
        """Score poses ``replanned`` on their map, then choose again from the first of them.

        Args: as :meth:`update`'s on the map that triggered it; ``gravity`` (n, 3) [m/s^2]
        of each pose there.
        """
        # ranked on each pose's loaded support on this map (the offline planner's basis)
        polygons = support_polygons_at(self.robot, terrain, self.poses_grid[replanned])
        pause()
        self._score_only(replanned, gravity, now, ground, polygons)
        pause()
        first = replanned[0]
        if ground is not None and ks[0] < first - 1 and first - 1 in self.candidates:
            first -= 1  # ahead of the robot: the move into ``first`` must clear both grounds
        chain = [k for k in ks if k >= first and k in self.candidates]
        chain = chain[: next((i for i, k in enumerate(chain) if k != first + i), len(chain))]
        return self._choose(chain, arm_q, now, ground)

    def _map_ground(self, terrain: Terrain, ks: list[int], rested: Rested) -> MapGround | None:
        """The ground under the arm at the covered horizon poses on this map (None: off)."""
        if self.settings.ground_clearance is None or not isinstance(terrain, HeightmapTerrain):
            return None
        arm = self._arm_on(terrain)
        M_T_B = {k: rested.G_T_B[i] for i, k in enumerate(ks) if rested.covered[i]}
        return PausedGround(arm[0], terrain, M_T_B, len(self.reach), self._ground)  # M = G

    def _recheck(self, ground: MapGround, kept: tuple[int, ...]) -> tuple[set[int], set[int]]:
        """The kept poses to score again: their node now too low; their reach now mapped.

        Their landed nodes are checked (the ones the step reads), but for the poses a queued
        re-plan replaces as invalid (it lands before the step reads them).
        """
        assert self._arm is not None
        replacing = self.jobs.replacing()  # their landed node known too low: not again
        ks = [k for k in kept if k in self.nodes and k not in replacing]
        again: set[int] = set()
        if ks:
            rows = np.asarray([self.nodes[k] for k in ks], dtype=np.intp)  # kept's rows: nodes
            clearance = self.settings.ground_clearance
            assert clearance is not None  # (no MapGround without it)
            clear = ground.node_clear(ks, rows, self._arm[1], clearance)
            again = {k for k, ok in zip(ks, clear, strict=True) if not ok}
            self.arm_ground["ground_rescored"] += len(again)
            self.arm_ground["over_unknown"] += len(set(ground.over_unknown) - again)
        mapped = {k for k in kept if k in self.unknown and not ground.reach(k)[0]} - again
        self.arm_ground["unknown_rescored"] += len(mapped)
        return again, mapped

    def _score(
        self,
        ks: list[int],
        gravity: FloatArray,
        now: float,
        ground: MapGround | None = None,
        polygons: list[FloatArray] | None = None,
    ) -> None:
        """Score the candidates of poses ``ks`` at gravities (n, 3) [m/s^2], in one batch.

        With ``ground``: each node also ``ground_clearance`` above the map under the arm;
        ``polygons``: the poses' support polygons in B (None: the tracks' rectangle).
        """
        self._note_reach(ks, ground)
        self._score_only(ks, gravity, now, ground, polygons)

    def _note_reach(self, ks: list[int], ground: MapGround | None) -> None:
        """Note the poses ``ks`` scored with unknown cells in the arm's reach (scored again)."""
        if ground is None or self._arm is None:
            return
        for k in ks:  # candidates cut to the mapped side: scored again once it is mapped
            if ground.reach(k)[0]:
                self.unknown.add(k)
                self.arm_ground["reach_unknown"] += 1
            else:
                self.unknown.discard(k)

    def _score_only(
        self,
        ks: list[int],
        gravity: FloatArray,
        now: float,
        ground: MapGround | None = None,
        polygons: list[FloatArray] | None = None,
    ) -> None:
        """:meth:`_score` without noting the unknown cells in reach."""
        clear = None
        if ground is not None and self._arm is not None:
            clear = clearance_on(self.clear, ground, ks, self._arm[1])
            pause()
        rows, value, mu = self._candidates(gravity, clear, polygons)
        for i, k in enumerate(ks):
            self.candidates[k] = PoseCandidates(gravity[i], rows[i], value[i], mu[i], now)

    def _choose(
        self, chain: list[int], arm_q: FloatArray, now: float, ground: MapGround | None = None
    ) -> Landed:
        """Choose the nodes of the consecutive poses ``chain`` after pose ``chain[0] - 1``.

        With ``ground``: a move's ends must clear the ground at both poses it joins. After
        the re-plans before it (:attr:`chosen`); returns what it chose, to land.
        """
        out = Landed({}, {}, {})
        cands = [self.candidates[k] for k in chain]
        cand = np.array([c.rows for c in cands])
        value = np.array([c.value for c in cands])
        before = self.chosen.nodes.get(chain[0] - 1)
        cost = self.cost
        if before is None:  # from the arm as it is
            start = cost.point_of(self.robot, np.asarray(arm_q, dtype=float))
        else:  # from the previous pose's node
            start = cost.points[int(np.searchsorted(self.reach, before))]
        value[0] = value[0] - cost.from_point(cand[0], start)
        turret = self.roadmap.nodes_q[self.reach, 0]
        window = self.settings.turret_window
        if before is not None and window is not None:
            far = np.abs(turret[cand[0]] - self.roadmap.nodes_q[before, 0]) > window + 1e-9
            value[0] = np.where(far, -np.inf, value[0])
        pairs = [(i, i + 1) for i in range(len(chain) - 1)]
        motion, allowed = transitions(
            cost.points, turret, cand, pairs, cost.weight, window, cost.metric
        )
        pause()
        if ground is not None:
            behind = chain[0] - 1 in self.chosen.nodes  # its node fixed: must clear its ground
            assert self._arm is not None
            forbid_low(self.clear, ground, self._arm[1], chain, cand, value, allowed, behind)
            pause()
        path, total = rp.best_sequence(value, motion, allowed, False)
        if not np.isfinite(total):  # keep the last plans; the loop reports the pose
            return out
        if before is None:
            out.start_q[chain[0]] = np.array(arm_q, dtype=float)
        for i, k in enumerate(chain):
            row = int(cand[i, path[i]])
            node = int(self.reach[row])
            q = self.roadmap.nodes_q[node].copy()
            mu = float(cands[i].mu[path[i]])
            out.nodes[k] = node
            out.plans[k] = HorizonPose(
                k, float(self.s_grid[k]), self.poses_grid[k], cands[i].gravity_body,
                self.samples[row].copy(), q, mu, True, now,
            )  # fmt: skip
        for mine, new in zip(self.chosen, out, strict=True):
            mine.update(new)  # type: ignore[attr-defined]
        return out

    def move(self, k: int) -> FloatArray:
        """The arm's move into pose ``k``'s posture (n, 4) [rad], along the roadmap.

        From pose ``k - 1``'s node, or from the arm's posture when ``k - 1`` was not planned
        (then joined to its nearest clear node). Computed once per pair of nodes, on the map
        of the update that first needs it: above the ground under the arm at both poses it
        joins (:func:`~mmstab.planner.searches.roadmap.moves.ground_move`, as offline) where one is
        found, else above the support plane only (counted: ``moves_plane_only``).
        """
        b = self.nodes[k]
        a = self.nodes.get(k - 1)
        if a is None:
            q0 = self.start_q.get(k, self.robot.stowed)
            a = self.roadmap.connect(q0, self.robot)
            head = np.asarray(q0, dtype=float)[None]
        else:
            head = np.zeros((0, self.roadmap.nodes_q.shape[1]))
        key = (a, b)
        if key not in self._moves:
            plane = self.arm_ground["moves_plane_only"]
            moved = self._move(a, b, [j for j in (k - 1, k) if j in self.nodes])
            if self.arm_ground["moves_plane_only"] > plane and self._land_touching({k - 1, k}):
                # not taken: a queued re-plan chooses these poses again (landed now)
                self.arm_ground["moves_plane_only"] = plane
                return self.move(k)
            self._moves[key] = moved
        return np.vstack([head, self._moves[key]])

    def _land_touching(self, poses: set[int]) -> bool:
        """Land the queued re-plans up to the last that may choose one of ``poses`` again."""
        landed = self.jobs.due(self.maps, set(), touching=poses)
        for x in landed:
            self._land(x)
        return bool(landed)

    def _move(self, a: int, b: int, ks: list[int]) -> FloatArray:
        """The roadmap move a -> b (n, 4) [rad], above the ground at poses ``ks`` if it can."""
        ground, g = self.settings.ground_clearance, self._ground
        ks = [k for k in ks if g is not None and k in g.M_T_B]
        if g is not None and ks and ground is not None:
            move = ground_move(
                self.robot, self.roadmap, self._checker, a, b, ground, g.under(ks),
                tuple(range(len(ks))), tries=self.ahead.take(a, b),
            )  # fmt: skip
            if move is not None:
                return move
            self.arm_ground["moves_plane_only"] += 1
        path = rp.roadmap_move(self.roadmap, a, b, ground=ground)
        return shortcut_above(self.robot, self.roadmap, self._checker, path, ground)

    def reference(
        self, s: float, spacing: float
    ) -> tuple[FloatArray | None, FloatArray | None, float]:
        """The planned arm CoM [m], posture [rad] and μ [N rad] at ``s`` [m].

        Between planned poses k - 1 and k the posture runs along the roadmap move into k, by
        the share of the way from ``s_{k-1}`` to ``s_k``; the CoM and μ are interpolated.
        """
        at = self.schedule(s, spacing)
        if at is None:
            return None, None, float("nan")
        k, share = at
        p = self.plans[k]
        prev = self.plans.get(k - 1)
        if prev is None or share >= 1.0:
            return p.target_com, p.q, p.mu
        q_ref = along(self.move(k), share)
        com = prev.target_com + share * (p.target_com - prev.target_com)
        return com, q_ref, prev.mu + share * (p.mu - prev.mu)

    def schedule(self, s: float, spacing: float) -> tuple[int, float] | None:
        """Where the plan has the arm at ``s`` [m] (None: no plan near ``s``).

        Returns:
            The planned pose k whose move the arm is on, and the share of that move made (1:
            on pose k's posture).
        """
        ks = sorted(k for k in self.plans if abs(self.plans[k].s - s) <= 2 * spacing)
        if not ks:
            return None
        ahead = [k for k in ks if self.plans[k].s >= s]
        k = ahead[0] if ahead else ks[-1]
        p, prev = self.plans[k], self.plans.get(k - 1)
        if prev is None or s >= p.s:
            return k, 1.0
        return k, float(np.clip((s - prev.s) / max(p.s - prev.s, 1e-9), 0.0, 1.0))

    def move_key(self, k: int) -> tuple[int | None, int]:
        """The nodes pose ``k``'s move joins (None: from the arm's posture then)."""
        return self.nodes.get(k - 1), self.nodes[k]


def along(path: FloatArray, share: float) -> FloatArray:
    """The point at ``share`` in [0, 1] of a polyline's length (n, d)."""
    if len(path) == 1:
        return path[0].copy()
    seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
    total = float(seg.sum())
    if total <= 0.0:
        return path[-1].copy()
    d = share * total
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    i = int(np.clip(np.searchsorted(cum, d, side="right") - 1, 0, len(seg) - 1))
    t = (d - cum[i]) / seg[i] if seg[i] > 0 else 0.0
    return path[i] + t * (path[i + 1] - path[i])


def pursue(
    path: FloatArray, q: FloatArray, reached: float, ahead: float, cap: float = np.inf
) -> tuple[FloatArray, float]:
    """A point ``ahead`` along a polyline (n, d) beyond the arm's posture ``q`` (d,) on it.

    ``q`` is projected onto the polyline no earlier than arc length ``reached`` (the way
    made so far: the arm does not go back); the point is ``ahead`` further on, no further
    than arc length ``cap`` nor the polyline's end. Arc lengths in the polyline's units
    (rad for postures).

    Returns:
        The point (d,) and the new ``reached``.
    """
    if len(path) == 1:
        return path[0].copy(), 0.0
    seg = np.diff(path, axis=0)
    length = np.linalg.norm(seg, axis=1)
    cum = np.concatenate([[0.0], np.cumsum(length)])
    total = float(cum[-1])
    if total <= 0.0:
        return path[-1].copy(), 0.0
    t = np.clip(np.einsum("ij,ij->i", q - path[:-1], seg) / np.maximum(length**2, 1e-18), 0, 1)
    foot = path[:-1] + t[:, None] * seg
    dist = np.where(cum[1:] >= reached, np.linalg.norm(foot - q, axis=1), np.inf)
    i = int(np.argmin(dist))
    made = max(float(cum[i] + t[i] * length[i]), reached)
    return along(path, min(made + ahead, cap, total) / total), made
