"""What one atlas cell computes, and the per-process cache that makes it cheap.

A cell is one base pose (heading [rad]) on a planar ramp (slope [rad]), or at rest at the
centre of a generated heightmap (its seed and ``slope``), for one robot variant (robot,
flippers, payload). It computes the planner's best arm CoM and its force-angle measure mu,
the measure with the arm stowed and with the arm removed (base mass only), and the
planner's wall time. On a heightmap the planner ranks arm CoMs on the tracks' rectangle
under the stowed arm's rest, and the three measures it reports are mmstab's one μ: each
state rested under its own load, on the contacts that carry it
(:mod:`mmstab.stability.support`); a pose that tips over, does not settle or leaves the map
(with the arm stowed) is NaN. Every cell draws from its own
generator, seeded by the planner seed and the cell's indices, so a cell's numbers do not
depend on chunking, workers or resumption.

Workers receive a :class:`VariantPayload` (robot + workspace V, scattered once per
worker) and keep a :class:`CellContext` per variant and process (:func:`context_for`):
the CasADi kinematics, V's derived arrays and the planner's start points are built once
per process, not once per cell; a payload's V comes with its variant (built or loaded
once by the client, scattered once to each worker). Heightmaps are generated per process,
once per (seed, slope, robot). :func:`worker_counts` reports what a process did.
"""

from __future__ import annotations

import threading
import time
from typing import NamedTuple

import numpy as np

from experiments.atlas.spec import Block, TerrainCell
from mmstab.model.robot import FloatArray, Robot
from mmstab.planner import PlannerSettings, PlanningRegion, as_region, solve_pose, start_coms
from mmstab.stability.static import mu_max
from mmstab.stability.support import loaded_mu
from mmstab.terrain import Ramp, Terrain
from mmstab.terrain.generators import generate
from mmstab.terrain.heightmap_terrain import HeightmapTerrain
from mmstab.workspace import Workspace


class VariantPayload(NamedTuple):
    """What a worker needs for one variant (pickled to each worker once).

    Attributes:
        key: cache key (robot hash, workspace grid, planner settings).
        position: (robot index, flipper index, payload index) of the variant.
        robot: the robot (without cached CasADi kinematics).
        workspace: the workspace V (``mmstab.workspace.Workspace``).
        settings: planner settings.
    """

    key: str
    position: tuple[int, int, int]
    robot: Robot
    workspace: Workspace
    settings: PlannerSettings


class CellContext(NamedTuple):
    """A variant ready to plan: built once per process by :func:`context_for`."""

    robot: Robot
    region: PlanningRegion  # V with its views (built once per process)
    settings: PlannerSettings
    mu_max: float  # Eq. 6 normaliser [N rad]
    starts: FloatArray  # CMA-ES start means (S, 3) [m]
    stowed_com: FloatArray  # arm CoM with the arm stowed, body frame (3,) [m]


class BestPose(NamedTuple):
    """The planner's answer at one cell: mu [N rad], arm CoM (3,) body frame [m], time [s]."""

    mu: float
    arm_com: FloatArray
    seconds: float


class ChunkTask(NamedTuple):
    """One chunk: its block, the slope and heading values it covers [rad], its terrain."""

    block: Block
    slopes: FloatArray
    headings: FloatArray
    terrain: TerrainCell = TerrainCell("ramp", None)


class ChunkResult(NamedTuple):
    """A computed chunk; arrays are (slopes, headings[, 3]) of the block.

    Attributes:
        block: the block.
        mu_planned: mu at the planner's arm CoM [N rad].
        arm_com: the planner's arm CoM, body frame [m].
        mu_stowed: mu with the arm stowed [N rad].
        mu_arm_removed: mu of the base alone [N rad].
        planner_seconds: planner wall time per cell [s].
        seconds: wall time of the whole chunk [s].
    """

    block: Block
    mu_planned: FloatArray
    arm_com: FloatArray
    mu_stowed: FloatArray
    mu_arm_removed: FloatArray
    planner_seconds: FloatArray
    seconds: float


_LOCK = threading.Lock()
_CONTEXTS: dict[str, CellContext] = {}
_TERRAINS: dict[tuple[str, float, str], HeightmapTerrain] = {}
#: Heightmap terrains a process keeps (one per seed x slope x robot in use).
MAX_TERRAINS = 32
_COUNTS = {"cells": 0, "chunks": 0, "contexts": 0}


def build_context(payload: VariantPayload) -> CellContext:
    """Derive what every cell of a variant shares (kinematics, starts, normaliser)."""
    robot, settings = payload.robot, payload.settings
    region = as_region(payload.workspace)
    return CellContext(
        robot=robot,
        region=region,
        settings=settings,
        mu_max=mu_max(robot),
        starts=start_coms(robot, region, settings.starts),
        stowed_com=robot.arm_com(robot.stowed),
    )


def context_for(payload: VariantPayload) -> CellContext:
    """The process's context for a variant, built on first use (thread-safe)."""
    with _LOCK:
        ctx = _CONTEXTS.get(payload.key)
        if ctx is None:
            ctx = _CONTEXTS[payload.key] = build_context(payload)
            _COUNTS["contexts"] += 1
        return ctx


def worker_counts() -> dict[str, int]:
    """Cells, chunks computed and contexts built by this process so far."""
    with _LOCK:
        return dict(_COUNTS)


def cell_rng(seed: int, variant: tuple[int, ...], slope: int, heading: int) -> np.random.Generator:
    """The generator of one cell: a function of the planner seed and the cell's indices.

    ``variant`` is (robot, flipper[, payload, terrain]) indices; payload and terrain index
    0 leave the stream of an atlas without those axes unchanged.
    """
    ri, fi, *rest = variant
    extra = list(rest) if any(rest) else []
    return np.random.default_rng([seed, ri, fi, slope, heading, *extra])


def heightmap_terrain(cell: TerrainCell, slope: float, robot: Robot) -> HeightmapTerrain:
    """The cell's generated heightmap at ``slope`` [rad], bound to ``robot`` (per process)."""
    assert cell.generate is not None
    key = (cell.label, float(slope), robot.source_hash)
    with _LOCK:
        terrain = _TERRAINS.get(key)
    if terrain is None:
        hm = generate({**cell.generate, "slope": float(slope)})
        terrain = HeightmapTerrain(hm).with_robot(robot)
        with _LOCK:
            if len(_TERRAINS) >= MAX_TERRAINS:
                _TERRAINS.clear()
            _TERRAINS[key] = terrain
    return terrain


def heightmap_yaw(cell: TerrainCell, slope: float, headings: FloatArray) -> FloatArray:
    """Yaw in G [rad] of atlas headings on a generated map of slope parameter ``slope``.

    Headings mean what they mean on the ramp of that slope (about the slope normal; 0
    across, pi/2 facing uphill), turned to the generator's uphill ``azimuth`` (the ramp's
    uphill is +y_S): the yaw is the ramp pose's heading seen from above, plus
    ``azimuth - pi/2``. On a generated plane the cell is then exactly the ramp's.
    """
    assert cell.generate is not None
    h = np.asarray(headings, dtype=float)
    R = Ramp(float(slope)).G_T_B(np.c_[np.zeros((len(h), 2)), h])[:, :3, :3]
    return float(cell.generate["azimuth"]) - np.pi / 2 + np.arctan2(R[:, 1, 0], R[:, 0, 0])


def plan_best_pose(
    ctx: CellContext, terrain: Terrain, pose: FloatArray, rng: np.random.Generator
) -> BestPose:
    """The atlas's one call into the planner: best arm CoM at one pose, from the stowed arm.

    Args:
        ctx: the variant's context.
        terrain: the ground of the cell (a ramp, or a heightmap bound to the robot).
        pose: base pose (x, y, heading) in the terrain's pose frame [m, m, rad].
        rng: the cell's generator.
    """
    target = solve_pose(
        ctx.robot,
        terrain,
        ctx.region,
        np.asarray(pose, dtype=float),
        ctx.stowed_com,
        ctx.settings,
        rng,
        ctx.mu_max,
        ctx.starts,
    )
    return BestPose(mu=float(target.mu), arm_com=target.target_com, seconds=target.seconds)


def compute_chunk(payload: VariantPayload, task: ChunkTask) -> ChunkResult:
    """Compute every cell of a chunk (runs on a worker)."""
    t0 = time.perf_counter()
    ctx = context_for(payload)
    b = task.block
    ns, nh = len(task.slopes), len(task.headings)
    mu_p, secs = np.full((ns, nh), np.nan), np.full((ns, nh), np.nan)
    com = np.full((ns, nh, 3), np.nan)
    mu_s, mu_r = np.empty((ns, nh)), np.empty((ns, nh))
    headings = np.asarray(task.headings, dtype=float)
    stowed = np.broadcast_to(ctx.stowed_com, (nh, 3))
    for i, slope in enumerate(task.slopes):
        terrain: Terrain
        if task.terrain.generate is None:
            terrain = Ramp(float(slope))
            poses = np.c_[np.zeros((nh, 2)), headings]
            ok = np.ones(nh, dtype=bool)
        else:
            # at rest at the map's centre with the arm stowed (the planner's gravity too)
            terrain = heightmap_terrain(task.terrain, float(slope), ctx.robot)
            poses = np.c_[np.zeros((nh, 2)), heightmap_yaw(task.terrain, slope, headings)]
            rest = terrain.rest(poses, strict=False)
            ok = rest.converged & ~rest.tips_over
        # the one μ: each state on its own loaded support (on the ramp, the tracks' rectangle)
        mu_s[i] = np.where(ok, loaded_mu(ctx.robot, terrain, poses, stowed, strict=False), np.nan)
        mu_r[i] = np.where(ok, loaded_mu(ctx.robot, terrain, poses, None, strict=False), np.nan)
        for j in range(nh):
            if ok[j]:
                rng = cell_rng(ctx.settings.seed, b.variant, b.slope.start + i, b.heading.start + j)
                best = plan_best_pose(ctx, terrain, poses[j], rng)
                mu = best.mu
                if task.terrain.generate is not None:  # reported on the loaded support
                    at = loaded_mu(ctx.robot, terrain, poses[j], best.arm_com, strict=False)
                    mu = float(at[0])
                mu_p[i, j], com[i, j], secs[i, j] = mu, best.arm_com, best.seconds
            with _LOCK:
                _COUNTS["cells"] += 1
    with _LOCK:
        _COUNTS["chunks"] += 1
    return ChunkResult(b, mu_p, com, mu_s, mu_r, secs, time.perf_counter() - t0)
