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
from mmstab.stability import mu_max as stowed_flat_mu
from mmstab.stability import robot_force_angle
from mmstab.terrain import Ramp


class CoMRegion(Protocol):
    """Where the arm CoM may be: the workspace V (``mmstab.workspace.Workspace``)."""

    diameter: float

    def contains(self, points: ArrayLike) -> NDArray[np.bool_]:
        """Membership of body-frame points (N, 3) [m]."""
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
        max_resample: re-asks per generation before giving up on samples outside V.
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
    gravity_body: FloatArray  # (3,) [m/s^2]
    previous_com: FloatArray  # (3,) body frame [m]
    mu_max: float  # [N rad]
    diameter: float  # [m]
    settings: PlannerSettings

    def mu(self, com_body: ArrayLike) -> FloatArray:
        """Force-angle measure for arm CoMs (N, 3) [m] -> (N,) [N rad]."""
        coms = np.atleast_2d(com_body)
        g = np.broadcast_to(self.gravity_body, coms.shape)
        return robot_force_angle(self.robot, g, coms).mu

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
        evaluations: fitness evaluations (feasible samples).
        resamples: samples discarded for lying outside V.
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


def _ask_feasible(es: Any, region: CoMRegion, max_resample: int) -> tuple[FloatArray, int]:
    X = np.array(es.ask())
    inside = region.contains(X)
    discarded = 0
    for _ in range(max_resample):
        if inside.all():
            return X, discarded
        k = int((~inside).sum())
        discarded += k
        X[~inside] = np.array(es.ask(k))
        inside = region.contains(X)
    if inside.all():
        return X, discarded
    raise MmstabError(
        f"planner: CMA-ES samples kept falling outside the workspace V "
        f"({max_resample} re-asks); V may be empty or far from the starts"
    )


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
        X, discarded = _ask_feasible(es, region, s.max_resample)
        f = fitness(X)
        es.tell(list(X), list(-f))  # pycma minimises
        resamples += discarded
        evaluations += len(X)
        first = X.copy() if first is None else first
        k = int(np.argmax(f))
        if f[k] > best_f:
            best_f, best_com = float(f[k]), X[k].copy()
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


def start_coms(robot: Robot, starts: tuple[float, ...]) -> FloatArray:
    """FK arm CoMs of the start postures: link0 at each angle, other joints zero [m]."""
    q = np.zeros((len(starts), 4))
    q[:, 0] = starts
    return robot.arm_com(q)


def solve_pose(
    robot: Robot,
    ramp: Ramp,
    region: CoMRegion,
    pose: ArrayLike,
    previous_com: ArrayLike,
    settings: PlannerSettings,
    rng: np.random.Generator,
    mu_max: float | None = None,
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
    """
    t0 = time.perf_counter()
    pose = np.asarray(pose, dtype=float)
    fitness = Fitness(
        robot=robot,
        gravity_body=ramp.gravity_body([pose[2]])[0],
        previous_com=np.asarray(previous_com, dtype=float),
        mu_max=stowed_flat_mu(robot) if mu_max is None else mu_max,
        diameter=float(region.diameter),
        settings=settings,
    )
    runs = tuple(
        solve_start(fitness, region, c, rng) for c in start_coms(robot, settings.starts)
    )
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
    previous_com, previous_q = robot.arm_com(robot.stowed), robot.stowed
    targets, postures, free = [], [], []
    for pose in poses:
        t = solve_pose(robot, ramp, region, pose, previous_com, settings, rng, mu_max)
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
    error = np.where(np.isnan(postures_arr).any(axis=1), np.nan,
                     np.linalg.norm(realised - target_com, axis=1))
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

    ws = workspace if workspace is not None else load_or_build_workspace(problem,
                                                                         progress=progress)
    if len(ws.valid_com) == 0 or not ws.contains(ws.valid_com).any():
        raise MmstabError(f"{problem.path}: the workspace V is empty; no arm CoM can be planned")
    settings = PlannerSettings.from_section(problem.section("planner"))
    solver = PostureSolver(problem.robot, ws)
    poses = problem.circle.poses(settings.poses)
    return solve_path(problem.robot, problem.ramp, ws, poses, settings, solver.realise)
