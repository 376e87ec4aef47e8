"""Stability planner (paper Section II-D, Eq. 6; DESIGN.md §5).

Per base pose on the ramp, CMA-ES (pycma, ask/tell) searches the arm CoM g_a (body
frame) inside the workspace V that maximises

    fitness = w_stability mu(g_a) / mu_max - w_motion |g_a - g_a_prev|^2 / d_workspace^2

(Eq. 6 with the DESIGN.md errata: the decision variable and the motion penalty are on
the *arm* CoM, the penalty is the squared Euclidean norm). Samples outside V are
discarded and re-asked. Two starts, the FK CoMs of link0 = 2.0 and 5.0 rad with the
other joints at zero; the better one is kept. No IK inside the loop (as in the paper);
after convergence :mod:`mmstab.ik` finds a collision-free posture that realises it.

The previous CoM of the first pose is the stowed arm's: the robot starts with its arm
folded. Every run draws from its own ``numpy.random.Generator``; the global NumPy state is
untouched.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple, Protocol

import cma
import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.config import ConfigError, MmstabError
from mmstab.problem import SECTION_CHECKS, Problem
from mmstab.robot import FloatArray, Robot
from mmstab.stability import base_polygon, force_angle_batch
from mmstab.stability import mu_max as stowed_flat_mu
from mmstab.terrain import Ramp


class CoMRegion(Protocol):
    """Where the arm CoM may be: the workspace V (``mmstab.workspace.Workspace``)."""

    @property
    def diameter(self) -> float:
        """Largest distance across the region [m]."""
        ...

    def contains(self, points: ArrayLike) -> NDArray[np.bool_]:
        """Membership of body-frame points (N, 3) [m]."""
        ...

    def violation(self, points: ArrayLike) -> FloatArray:
        """How far body-frame points (N, 3) lie outside the region, 0 inside [m]."""
        ...


class PlannerSettings(NamedTuple):
    """The ``planner`` section of a problem (see ``problems/ramp.yaml``).

    Attributes:
        w_stability: omega_1 of Eq. 6 (>= 0).
        w_motion: omega_2 of Eq. 6 (>= 0); w_stability + w_motion = 1.
        poses: number of base poses along the circle.
        starts: link0 angles of the two starts (other joints zero) [rad].
        sigma0: initial CMA step size [m].
        popsize: CMA population size.
        max_iterations: CMA iteration budget per start.
        tol_fitness: stop when the fitness changes less than this over recent iterations.
        tol_x: stop when the search distribution is narrower than this [m].
        max_resample: re-ask rounds per generation for samples outside V; those still
            outside are then ranked below the feasible ones (see ``ask_generation``).
        seed: seed of the planner's own random generator.
    """

    w_stability: float
    w_motion: float
    poses: int
    starts: tuple[float, ...]
    sigma0: float
    popsize: int
    max_iterations: int
    tol_fitness: float
    tol_x: float
    max_resample: int
    seed: int

    @classmethod
    def from_section(cls, cfg: dict[str, Any]) -> PlannerSettings:
        """Build from a validated ``planner`` section."""
        return cls(
            w_stability=float(cfg["w_stability"]),
            w_motion=float(cfg["w_motion"]),
            poses=int(cfg["poses"]),
            starts=tuple(float(s) for s in cfg["starts"]),
            sigma0=float(cfg["sigma0"]),
            popsize=int(cfg["popsize"]),
            max_iterations=int(cfg["max_iterations"]),
            tol_fitness=float(cfg["tol_fitness"]),
            tol_x=float(cfg["tol_x"]),
            max_resample=int(cfg["max_resample"]),
            seed=int(cfg["seed"]),
        )


def _check_section(path: Path, cfg: dict[str, Any]) -> None:
    if abs(cfg["w_stability"] + cfg["w_motion"] - 1.0) > 1e-9:
        raise ConfigError(path, "planner.w_motion", "w_stability + w_motion must equal 1")


SECTION_CHECKS["planner"] = _check_section


class Fitness(NamedTuple):
    """Eq. 6 for one base pose, evaluated for a whole population at once."""

    robot: Robot
    polygon: FloatArray  # ordered support polygon in B (n, 3) [m]
    gravity_body: FloatArray  # (3,) [m/s^2]
    previous_com: FloatArray  # (3,) body frame [m]
    mu_max: float  # [N rad]
    diameter: float  # [m]
    settings: PlannerSettings

    def mu(self, com_body: ArrayLike) -> FloatArray:
        """Force-angle measure for arm CoMs (N, 3) [m] -> (N,) [N rad] (as robot_force_angle)."""
        overall = self.robot.overall_com(np.atleast_2d(com_body))
        return force_angle_batch(
            self.polygon, overall, self.robot.total_mass * self.gravity_body
        ).mu

    def __call__(self, com_body: ArrayLike) -> FloatArray:
        """Fitness (to maximise) of arm CoMs (N, 3) [m] -> (N,)."""
        coms = np.atleast_2d(com_body)
        motion = np.sum((coms - self.previous_com) ** 2, axis=1) / self.diameter**2
        s = self.settings
        return s.w_stability * self.mu(coms) / self.mu_max - s.w_motion * motion


class SearchResult(NamedTuple):
    """One CMA-ES run from one start.

    Attributes:
        start_com: the start mean [m].
        best_com: best feasible arm CoM found [m].
        best_fitness: its fitness.
        history: best fitness of each iteration (I,).
        first_samples: the first population (popsize, 3) [m], feasible.
        evaluations: samples told to CMA-ES.
        resamples: samples discarded (re-asked) for lying outside V.
        iterations: CMA iterations.
    """

    start_com: FloatArray
    best_com: FloatArray
    best_fitness: float
    history: FloatArray
    first_samples: FloatArray
    evaluations: int
    resamples: int
    iterations: int


class Generation(NamedTuple):
    """One CMA generation: samples (popsize, 3) [m], their membership of V, re-asked count."""

    samples: FloatArray
    inside: NDArray[np.bool_]
    discarded: int


def ask_generation(es: Any, region: CoMRegion, rounds: int) -> Generation:
    """Ask a population; re-ask (discard) samples outside V for up to ``rounds`` rounds.

    The paper discards samples outside V. When the optimum lies in a thin part of V, pure
    rejection hides the constraint from CMA-ES (its step size never shrinks) and the
    feasible fraction collapses; so after ``rounds`` re-asks the samples still outside
    are kept and told ranked below every feasible one (see :func:`solve_start`).
    """
    X = np.array(es.ask())
    inside = region.contains(X)
    discarded = 0
    for _ in range(rounds):
        if inside.all():
            break
        k = int((~inside).sum())
        discarded += k
        X[~inside] = np.array(es.ask(k))
        inside = region.contains(X)
    return Generation(X, inside, discarded)


def ranking_values(
    fitness: FloatArray, inside: NDArray[np.bool_], violation: FloatArray, diameter: float
) -> FloatArray:
    """Values for pycma, which minimises.

    Inside V: -fitness. Outside: worse than every feasible sample, increasing with the
    distance to V, so CMA-ES learns where V ends without ever choosing such a sample.
    """
    values = -fitness.copy()
    worst = values[inside].max() if inside.any() else 0.0
    values[~inside] = worst + 1.0 + violation[~inside] / diameter
    return values


def solve_start(
    fitness: Fitness, region: CoMRegion, start_com: FloatArray, rng: np.random.Generator
) -> SearchResult:
    """Run CMA-ES (ask/tell) from one start CoM, keeping every told sample inside V.

    Args:
        fitness: Eq. 6 at this pose.
        region: the workspace V.
        start_com: initial mean, body frame (3,) [m].
        rng: the generator CMA draws from (its own, never NumPy's global one).
    """
    s = fitness.settings
    opts = {
        "seed": np.nan,  # pycma would otherwise reseed NumPy's global generator
        "randn": lambda *shape: rng.standard_normal(shape),
        "popsize": s.popsize,
        "maxiter": s.max_iterations,
        "tolfun": s.tol_fitness,
        "tolx": s.tol_x,
        "verbose": -9,
        "verb_log": 0,
        "verb_disp": 0,
    }
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # pycma warns about unused/odd settings
        es = cma.CMAEvolutionStrategy(list(start_com), s.sigma0, opts)
    best_com, best_f = np.asarray(start_com, float), -np.inf
    history, first, evaluations, resamples = [], None, 0, 0
    while not es.stop():
        gen = ask_generation(es, region, s.max_resample)
        if not gen.inside.any() and first is None:
            raise MmstabError(
                f"planner: no CMA-ES sample fell in the workspace V "
                f"({s.max_resample} re-asks from {np.round(start_com, 3)} m); V may be empty"
            )
        f = fitness(gen.samples)
        violation = region.violation(gen.samples) if not gen.inside.all() else np.zeros(len(f))
        es.tell(list(gen.samples), list(ranking_values(f, gen.inside, violation, fitness.diameter)))
        resamples += gen.discarded
        evaluations += len(f)
        feasible_f = np.where(gen.inside, f, -np.inf)
        if first is None:
            first = gen.samples[gen.inside].copy()
        k = int(np.argmax(feasible_f))
        if feasible_f[k] > best_f:
            best_f, best_com = float(feasible_f[k]), gen.samples[k].copy()
        history.append(best_f)
    return SearchResult(
        start_com=np.asarray(start_com, float),
        best_com=best_com,
        best_fitness=best_f,
        history=np.array(history),
        first_samples=first if first is not None else np.empty((0, 3)),
        evaluations=evaluations,
        resamples=resamples,
        iterations=int(es.countiter),
    )


class PoseTarget(NamedTuple):
    """The planner's answer at one base pose.

    Attributes:
        pose: base pose (x, y, heading) in S [m, m, rad].
        target_com: chosen arm CoM, body frame (3,) [m].
        fitness: its Eq. 6 fitness.
        mu: force-angle measure at the target [N rad].
        runs: the CMA-ES runs, one per start.
        best_start: index of the run kept.
        seconds: wall time of both runs [s].
    """

    pose: FloatArray
    target_com: FloatArray
    fitness: float
    mu: float
    runs: tuple[SearchResult, ...]
    best_start: int
    seconds: float


def start_coms(robot: Robot, region: CoMRegion, starts: tuple[float, ...]) -> FloatArray:
    """Start means of CMA-ES, body frame (S, 3) [m].

    The FK arm CoMs of link0 at each angle with the other joints at zero (paper); a start
    outside V (a coarse grid's hull may miss the stretched arm) moves to the nearest valid
    CoM inside V, when the region has that cloud (``valid_com_in_V``).
    """
    q = np.zeros((len(starts), 4))
    q[:, 0] = starts
    coms = robot.arm_com(q)
    outside = ~region.contains(coms)
    if outside.any() and hasattr(region, "valid_com_in_V"):
        inside = region.valid_com_in_V
        if len(inside):
            for k in np.flatnonzero(outside):
                coms[k] = inside[np.argmin(np.sum((inside - coms[k]) ** 2, axis=1))]
    return coms


def solve_pose(
    robot: Robot,
    ramp: Ramp,
    region: CoMRegion,
    pose: ArrayLike,
    previous_com: ArrayLike,
    settings: PlannerSettings,
    rng: np.random.Generator,
    mu_max: float | None = None,
    starts: FloatArray | None = None,
) -> PoseTarget:
    """Best arm CoM at one base pose: CMA-ES from each start, keep the better.

    Args:
        robot: the robot.
        ramp: the ramp.
        region: the workspace V (``contains``, ``diameter``).
        pose: base pose (x, y, heading) in S [m, m, rad].
        previous_com: arm CoM at the previous pose, body frame [m] (Eq. 6 penalty).
        settings: planner settings.
        rng: the planner's generator.
        mu_max: normaliser [N rad]; default: flat ground, arm stowed.
        starts: start means (S, 3) [m]; default :func:`start_coms`.
    """
    t0 = time.perf_counter()
    pose = np.asarray(pose, dtype=float)
    fitness = Fitness(
        robot=robot,
        polygon=base_polygon(robot).vertices,
        gravity_body=ramp.gravity_body([pose[2]])[0],
        previous_com=np.asarray(previous_com, dtype=float),
        mu_max=stowed_flat_mu(robot) if mu_max is None else mu_max,
        diameter=float(region.diameter),
        settings=settings,
    )
    if starts is None:
        starts = start_coms(robot, region, settings.starts)
    runs = tuple(solve_start(fitness, region, c, rng) for c in starts)
    best = int(np.argmax([r.best_fitness for r in runs]))
    target = runs[best].best_com
    return PoseTarget(
        pose=pose,
        target_com=target,
        fitness=runs[best].best_fitness,
        mu=float(fitness.mu(target)[0]),
        runs=runs,
        best_start=best,
        seconds=time.perf_counter() - t0,
    )


class Plan(NamedTuple):
    """A planned sequence of arm CoMs along the base path, with realising postures.

    Attributes:
        poses: base poses (K, 3) in S [m, m, rad].
        fractions: path fraction of each pose (K,) in [0, 1).
        target_com: chosen arm CoMs, body frame (K, 3) [m].
        postures: arm postures realising them (K, 4) [rad].
        realised_com_error: |g_a(posture) - target| (K,) [m].
        collision_free: whether each posture is collision-free (K,).
        targets: the per-pose planner results.
        settings: the settings used.
    """

    poses: FloatArray
    fractions: FloatArray
    target_com: FloatArray
    postures: FloatArray
    realised_com_error: FloatArray
    collision_free: NDArray[np.bool_]
    targets: tuple[PoseTarget, ...]
    settings: PlannerSettings


def solve_path(
    robot: Robot,
    ramp: Ramp,
    region: CoMRegion,
    poses: ArrayLike,
    settings: PlannerSettings,
    realise: Callable[[FloatArray, FloatArray], tuple[FloatArray, bool]] | None = None,
) -> Plan:
    """Plan poses in sequence, each penalised against the previous target (Eq. 6).

    Args:
        robot: the robot.
        ramp: the ramp.
        region: the workspace V.
        poses: base poses (K, 3) in S.
        settings: planner settings (its ``seed`` seeds the planner's generator).
        realise: ``(target_com, previous_posture) -> (posture, collision_free)``; default
            none: postures are NaN (CMA only, e.g. for benchmarks).
    """
    poses = np.asarray(poses, dtype=float)
    rng = np.random.default_rng(settings.seed)
    mu_max = stowed_flat_mu(robot)
    starts = start_coms(robot, region, settings.starts)
    previous_com, previous_q = robot.arm_com(robot.stowed), robot.stowed
    targets, postures, free = [], [], []
    for pose in poses:
        t = solve_pose(robot, ramp, region, pose, previous_com, settings, rng, mu_max, starts)
        targets.append(t)
        previous_com = t.target_com
        if realise is not None:
            q, ok = realise(t.target_com, previous_q)
            previous_q = q
        else:
            q, ok = np.full(4, np.nan), False
        postures.append(q)
        free.append(ok)
    target_com = np.array([t.target_com for t in targets])
    postures_arr = np.array(postures)
    realised = robot.arm_com(np.nan_to_num(postures_arr))
    error = np.where(
        np.isnan(postures_arr).any(axis=1), np.nan, np.linalg.norm(realised - target_com, axis=1)
    )
    return Plan(
        poses=poses,
        fractions=np.arange(len(poses)) / len(poses),
        target_com=target_com,
        postures=postures_arr,
        realised_com_error=error,
        collision_free=np.array(free, dtype=bool),
        targets=tuple(targets),
        settings=settings,
    )


def plan_path(problem: Problem, workspace: Any = None, progress: bool = False) -> Plan:
    """Plan the problem's circle: workspace (cached), CMA-ES per pose, IK per target.

    Args:
        problem: a loaded problem (sections ``planner``, ``workspace``, ``path``).
        workspace: a prebuilt :class:`mmstab.workspace.Workspace`; default: load or build.
        progress: show progress bars.
    """
    from mmstab.ik import PostureSolver
    from mmstab.workspace import load_or_build_workspace

    ws = workspace if workspace is not None else load_or_build_workspace(problem, progress=progress)
    if len(ws.valid_com_in_V) == 0:
        raise MmstabError(f"{problem.path}: the workspace V is empty; no arm CoM can be planned")
    settings = PlannerSettings.from_section(problem.section("planner"))
    solver = PostureSolver(problem.robot, ws)
    poses = problem.circle.poses(settings.poses)
    return solve_path(problem.robot, problem.ramp, ws, poses, settings, solver.realise)
