"""``method: roadmap``: postures along a path chosen on the posture roadmap.

Like ``method: sequence`` (:mod:`mmstab.planner.searches.sequence`) it maximises Eq. 6 summed along
the path, each pose's motion term against the previous pose's choice, by dynamic
programming over poses x candidate postures. The candidates are the roadmap's nodes
(:mod:`mmstab.workspace.roadmap`) in the component of the arm's start posture (the stowed
arm), each pose's ``sequence_candidates`` best by Eq. 6's stability term spread over the
turret, with a stable posture only (μ > 0). Any two nodes of a component are joined by a
roadmap path of checked collision-free moves, so every move the search chooses is
feasible by construction: no lazy check, no round limit; the search is exact on the
candidates. When some pose has no stable candidate (or the turret window leaves no
sequence), :class:`NoPlanError` names the pose. The chosen moves' roadmap paths come with
the answer, for the controller (:mod:`~mmstab.planner.searches.roadmap.moves`). Per pose (a
caller planning one pose) :class:`RoadmapSearch` is the exhaustive reference.
"""

from __future__ import annotations

import time
from dataclasses import fields
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from mmstab.core.files import MmstabError
from mmstab.model.robot import FloatArray, Robot
from mmstab.planner.candidates import NodeClearance, NodeClusters, node_clusters
from mmstab.planner.climbing import ClimbPlan, climb_exclusions, climb_plan
from mmstab.planner.fitness import pose_fitness, same_axes, support_polygons_at
from mmstab.planner.ground.under_arm import GroundUnderArm
from mmstab.planner.grounded import ground_graph
from mmstab.planner.motion import motion_cost
from mmstab.planner.searches.base import PathChoice, PathTask, PoseChoice, PoseTask
from mmstab.planner.searches.exhaustive import ExhaustiveSearch
from mmstab.planner.searches.roadmap.moves import (  # noqa: F401 (the moves' names, as before)
    ASTAR_EXPANSIONS,
    astar,
    ground_move,
    roadmap_move,
    start_tree,
)
from mmstab.planner.searches.roadmap.rounds import (  # noqa: F401 (the search's names, as before)
    Mover,
    NoPlanError,
    OneMu,
    Rounds,
    best_sequence,
)
from mmstab.planner.searches.sequence import _turret_bins
from mmstab.planner.settings import PlannerSettings
from mmstab.planner.turning import SlideLimit, slide_exclusions, turn_chords
from mmstab.terrain import Terrain
from mmstab.workspace.kept import kept_arrays
from mmstab.workspace.roadmap import Roadmap, load_or_build_roadmap

#: Turret-angle bins over which each pose's candidates are spread.
TURRET_BINS = 24


class RoadmapSequence(NamedTuple):
    """The chosen roadmap nodes along the path.

    Attributes:
        nodes: the chosen node per pose (K,).
        postures: their postures (K, 4) [rad].
        com: their arm CoMs, body frame (K, 3) [m].
        fitness: Eq. 6 per pose, the previous pose's choice as previous CoM (K,).
        mu: force-angle measure per pose [N rad] (K,), on the basis the pose was ranked
            on (the stowed arm's support, or the one μ: :class:`~.rounds.OneMu`).
        total: the sum of ``fitness``.
        moves: the roadmap path into each pose's posture (K arrays (n, 4) [rad]): from
            the start posture (open path) or from the last pose (closed).
        seconds: wall time [s].
        turns: the turns priced over ``planner.turn_slide`` with the first choice, and the
            poses that chose again (:func:`mmstab.planner.turning.slide_exclusions`' records).
    """

    nodes: NDArray[np.intp]
    postures: FloatArray
    com: FloatArray
    fitness: FloatArray
    mu: FloatArray
    total: float
    moves: tuple[FloatArray, ...]
    seconds: float
    turns: tuple[dict[str, Any], ...] = ()


def node_coms(robot: Robot, roadmap: Roadmap) -> FloatArray:
    """Arm CoMs of the roadmap's nodes, body frame (N, 3) [m] (kept with the roadmap).

    ``robot`` is the roadmap's own (its cache key holds the robot's hash).
    """
    return np.asarray(roadmap.node_com)


class ComponentView(NamedTuple):
    """What every plan from one roadmap component needs, computed once and kept.

    Attributes:
        reach: the component's nodes (N,).
        samples: their arm CoMs, body frame (N, 3) [m].
        diameter: the CoMs' largest extent along an axis [m] (Eq. 6's ``d_workspace``).
        bins: turret bin of each (N,).
        clusters: the nodes grouped for the candidates' bounds.
        joint_span: the postures' L1 extent, Σ_j (max q_j − min q_j) [rad] (the
            ``motion_cost: joints`` normaliser).
    """

    reach: NDArray[np.intp]
    samples: FloatArray
    diameter: float
    bins: NDArray[np.intp]
    clusters: NodeClusters
    joint_span: float


def component_view(
    robot: Robot, roadmap: Roadmap, start: int, ground: float | None = None
) -> ComponentView:
    """The :class:`ComponentView` of node ``start``'s component (kept with the roadmap).

    With ``ground`` [m]: the component among the nodes whose arm stays that far above the
    support plane (:func:`mmstab.planner.grounded.ground_graph`). Kept in memory and beside
    the roadmap's cache file (:mod:`mmstab.workspace.kept`).
    """
    views = getattr(roadmap, "_views", None)
    if views is None:
        views = {}
        object.__setattr__(roadmap, "_views", views)
    component = ground_graph(roadmap, ground).component
    comp = (int(component[start]), ground)
    if comp not in views:

        def compute() -> dict[str, np.ndarray]:
            reach = np.flatnonzero(component == comp[0])
            samples = node_coms(robot, roadmap)[reach]
            bins = _turret_bins(roadmap.nodes_q[reach, 0], TURRET_BINS)
            clusters = node_clusters(samples, bins, TURRET_BINS)
            return {
                "reach": reach, "bins": bins,
                "diameter": np.float64(np.ptp(samples, axis=0).max() if len(samples) > 1 else 1),
                "joint_span": np.float64(max(np.ptp(roadmap.nodes_q[reach], axis=0).sum(), 1e-9)),
                **{f"clusters.{f.name}": getattr(clusters, f.name) for f in fields(clusters)},
            }  # fmt: skip

        ground_tag = None if ground is None else float(ground)
        a = kept_arrays(roadmap, f"view-{comp[0]}-{ground_tag!r}", compute)
        cl = {c.name: a[f"clusters.{c.name}"] for c in fields(NodeClusters)}
        views[comp] = ComponentView(
            reach=a["reach"],
            samples=node_coms(robot, roadmap)[a["reach"]],
            diameter=float(a["diameter"]),
            bins=a["bins"],
            clusters=NodeClusters(**cl),
            joint_span=float(a["joint_span"]),
        )
    return views[comp]


def solve_roadmap_sequence(
    robot: Robot,
    gravity_body: FloatArray,
    roadmap: Roadmap,
    settings: PlannerSettings,
    mu_max: float,
    closed: bool,
    poses: FloatArray,
    start_q: FloatArray | None = None,
    under: GroundUnderArm | None = None,
    climb: ClimbPlan | None = None,
    polygons: list[FloatArray] | None = None,
    slide: SlideLimit | None = None,
    terrain: Terrain | None = None,
) -> RoadmapSequence:
    """Choose one reachable roadmap node per pose (module text).

    Args:
        robot: the robot.
        gravity_body: gravity in the body frame at each pose (K, 3) [m/s^2].
        roadmap: the posture roadmap.
        settings: planner settings (weights, ``turret_window``, ``sequence_candidates``).
        mu_max: Eq. 6's normaliser [N rad].
        closed: the path is a loop (the last pose's choice is the first's previous).
        poses: base poses (K, 3) [m, m, rad], for the message when no plan exists.
        start_q: the arm's start posture (4,) [rad]; default the stowed arm.
        under: the ground under the arm at each pose: a node too low above it at pose k is
            no candidate there, a move too low at the poses it joins is not chosen.
        polygons: each pose's support polygon in B (n, 3) [m]
            (:func:`mmstab.planner.pose.support_polygons_at`); None: the tracks' rectangle.
        climb: the climb limit along the poses: at a constrained pose only nodes whose
            overall CoM lets the tracks climb its step (:mod:`mmstab.planner.climbing`).
        slide: the slide limit at the turns: where the chosen postures' turn slides more,
            the poses either side keep only postures whose turn does not, and the path is
            searched again (:mod:`mmstab.planner.turning`).
        terrain: the ground the poses rest on, with ``polygons``: the candidates are ranked
            on the stowed arm's support (one polygon per pose: fast), and where a chosen
            posture's μ on its own loaded support (the one μ the plan reports,
            :func:`mmstab.stability.support.loaded_mu`) falls more than
            :data:`~.rounds.ONE_MU_SLACK` below that and the stowed arm's, the pose's
            candidates are ranked on their one μ and the path is searched again
            (:class:`~.rounds.OneMu`).

    Raises:
        NoPlanError: some pose has no reachable stable posture (the message names it).
    """
    t0 = time.perf_counter()
    if robot.tool_wrench is not None:
        raise MmstabError("planner: method roadmap does not take payload.wrench yet")
    start_q = robot.stowed if start_q is None else np.asarray(start_q, dtype=float)
    start = roadmap.connect(start_q, robot)
    view = component_view(robot, roadmap, start, settings.ground_clearance)
    reach, samples, diameter = view.reach, view.samples, view.diameter
    g = np.atleast_2d(np.asarray(gravity_body, dtype=float))
    K, M = len(g), min(settings.sequence_candidates, len(reach))
    stowed = robot.arm_com(start_q)
    stab = settings._replace(w_motion=0.0)
    polys: list[Any] = [None] * K if polygons is None else list(polygons)
    fits = same_axes([
        pose_fitness(robot, gk, stowed, stab, mu_max, diameter, pk).linear()
        for gk, pk in zip(g, polys, strict=True)
    ])  # fmt: skip
    ground = settings.ground_clearance
    clear = NodeClearance(roadmap, reach, ground, under)
    if climb is not None:
        clear.excluded.update(climb_exclusions(robot, climb, samples, clear.eligible(), fits))
    cost = motion_cost(roadmap.nodes_q[reach], samples, (diameter, view.joint_span), settings)
    stowed_mu = np.array([f.mu(stowed)[0] for f in fits])  # on its own support: the one μ
    one = OneMu(robot, terrain if polygons is not None else None, poses, samples,
                stab.w_stability / mu_max, stowed_mu)  # fmt: skip
    rounds = Rounds(fits, view, M, clear, cost, closed, Mover(robot, roadmap, int(start), ground,
                    under), one, cost.point_of(robot, start_q), roadmap.nodes_q[reach, 0],
                    settings, poses)  # fmt: skip
    got = rounds.on_one_mu(rounds.search())
    turns: list[dict[str, Any]] = []
    if slide is not None and slide.chords:
        chosen_com = samples[got.cand[np.arange(K), got.path]]
        excluded, turns = slide_exclusions(
            robot, slide.terrain, slide.chords, chosen_com, slide.limit, samples,
            clear.eligible(), fits, slide.model,
        )  # fmt: skip
        if excluded:  # the poses either side of a sliding turn: searched again
            for k, mask in excluded.items():
                clear.excluded[k] = clear.excluded[k] | mask if k in clear.excluded else mask
            try:  # the other poses' candidates stand (route_candidates)
                got = rounds.on_one_mu(rounds.search(np.fromiter(excluded, dtype=np.intp)))
            except NoPlanError:  # no path with them: the first answer, its turns reported
                for t in turns:
                    t["poses"] = []
    moves, path = got.moves, got.path
    if not closed or K == 1:  # from the start posture itself onto its node
        first = np.vstack([start_q, moves[0]])
        moves[0] = first if np.linalg.norm(first[1] - first[0]) > 1e-12 else first[1:]
    chosen = got.cand[np.arange(K), path]
    fitness = got.value[np.arange(K), path].copy()
    for i, (a, b) in enumerate(rounds.pairs):
        fitness[b] -= got.motion[i][path[a], path[b]]
    return RoadmapSequence(
        nodes=got.nodes,
        postures=roadmap.nodes_q[got.nodes].copy(),
        com=samples[chosen].copy(),
        fitness=fitness,
        mu=got.mu[np.arange(K), path].copy(),
        total=float(fitness.sum()),
        moves=tuple(moves),
        seconds=time.perf_counter() - t0,
        turns=tuple(turns),
    )


class RoadmapSearch:
    """The whole path over the posture roadmap's component reachable from the stowed arm."""

    def choose(self, task: PoseTask) -> PoseChoice:
        """The exhaustive answer at a single pose."""
        return ExhaustiveSearch().choose(task)

    def choose_path(self, task: PathTask) -> PathChoice:
        """The chosen nodes' CoMs, postures and the roadmap moves into them."""
        if task.region.workspace is None:
            raise MmstabError("planner: method roadmap needs the labelled workspace V")
        roadmap = load_or_build_roadmap(task.robot, task.region.workspace)
        poses = np.zeros((len(task.gravity_body), 3)) if task.poses is None else task.poses
        under = None
        if task.terrain is not None and task.poses is not None:  # the ground under the arm
            margin = task.settings.attitude_margin or 0.0
            under = GroundUnderArm(task.robot, task.terrain, task.poses, margin=margin)
        elif task.settings.attitude_margin:
            raise MmstabError("planner.attitude_margin: needs a terrain and a route")
        climb = None
        if task.settings.climb and task.terrain is not None and task.poses is not None:
            climb = climb_plan(task.robot, task.terrain, task.poses, task.closed)
        polygons = None
        if task.terrain is not None and task.poses is not None:  # the loaded support
            polygons = support_polygons_at(task.robot, task.terrain, task.poses)
        slide = None
        limit = task.settings.turn_slide
        if limit is not None and task.terrain is not None and task.poses is not None:
            chords = turn_chords(task.terrain, task.poses, task.closed)
            model = task.settings.slide_model
            slide = SlideLimit(task.terrain, chords, limit, model) if chords else None
        seq = solve_roadmap_sequence(
            task.robot,
            task.gravity_body,
            roadmap,
            task.settings,
            task.mu_max,
            task.closed,
            poses,
            under=under,
            climb=climb,
            polygons=polygons,
            slide=slide,
            terrain=task.terrain,
        )
        return PathChoice(
            target_com=seq.com, postures=seq.postures, fitness=seq.fitness, mu=seq.mu,
            moves=seq.moves, turns=seq.turns,
        )  # fmt: skip
