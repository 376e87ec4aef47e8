"""What one atlas cell computes, and the per-process cache that makes it cheap.

A cell is one base pose (heading [rad]) on a planar ramp (slope [rad]) for one robot
variant. It computes the planner's best arm CoM and its force-angle measure mu, the
measure with the arm stowed and with the arm removed (base mass only), and the planner's
wall time. Every cell draws from its own generator, seeded by the planner seed and the
cell's indices, so a cell's numbers do not depend on chunking, workers or resumption.

Workers receive a :class:`VariantPayload` (robot + workspace V, scattered once per
worker) and keep a :class:`CellContext` per variant and process (:func:`context_for`):
the CasADi kinematics, V's derived arrays and the planner's start points are built once
per process, not once per cell. :func:`worker_counts` reports what a process did.
"""

from __future__ import annotations

import threading
import time
from typing import Any, NamedTuple

import numpy as np

from mmstab.atlas.spec import Block
from mmstab.planner import PlannerSettings, solve_pose, start_coms
from mmstab.robot import FloatArray, Robot
from mmstab.stability import mu_max, robot_force_angle
from mmstab.terrain import Ramp


class VariantPayload(NamedTuple):
    """What a worker needs for one variant (pickled to each worker once).

    Attributes:
        key: cache key (robot hash, workspace grid, planner settings).
        position: (robot index, flipper index) of the variant.
        robot: the robot (without cached CasADi kinematics).
        workspace: the workspace V (``mmstab.workspace.Workspace``).
        settings: planner settings.
    """

    key: str
    position: tuple[int, int]
    robot: Robot
    workspace: Any
    settings: PlannerSettings


class CellContext(NamedTuple):
    """A variant ready to plan: built once per process by :func:`context_for`."""

    robot: Robot
    workspace: Any
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
    """One chunk to compute: its block and the slope and heading values it covers [rad]."""

    block: Block
    slopes: FloatArray
    headings: FloatArray


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
_COUNTS = {"cells": 0, "chunks": 0, "contexts": 0}


def build_context(payload: VariantPayload) -> CellContext:
    """Derive what every cell of a variant shares (kinematics, starts, normaliser)."""
    robot, ws, settings = payload.robot, payload.workspace, payload.settings
    return CellContext(
        robot=robot,
        workspace=ws,
        settings=settings,
        mu_max=mu_max(robot),
        starts=start_coms(robot, ws, settings.starts),
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


def cell_rng(seed: int, variant: tuple[int, int], slope: int, heading: int) -> np.random.Generator:
    """The generator of one cell: a function of the planner seed and the cell's indices."""
    return np.random.default_rng([seed, *variant, slope, heading])


def plan_best_pose(
    ctx: CellContext, ramp: Ramp, heading: float, rng: np.random.Generator
) -> BestPose:
    """The atlas's one call into the planner: best arm CoM at one pose, from the stowed arm.

    Args:
        ctx: the variant's context.
        ramp: the ramp of the cell.
        heading: base heading about the slope normal [rad] (position is irrelevant on a plane).
        rng: the cell's generator.
    """
    target = solve_pose(
        ctx.robot,
        ramp,
        ctx.workspace,
        np.array([0.0, 0.0, heading]),
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
    mu_p, secs = np.empty((ns, nh)), np.empty((ns, nh))
    com = np.empty((ns, nh, 3))
    mu_s, mu_r = np.empty((ns, nh)), np.empty((ns, nh))
    for i, slope in enumerate(task.slopes):
        ramp = Ramp(float(slope))
        headings = np.asarray(task.headings, dtype=float)
        gravity = ramp.gravity_body(np.c_[np.zeros((nh, 2)), headings])
        stowed = np.broadcast_to(ctx.stowed_com, (nh, 3))
        mu_s[i] = robot_force_angle(ctx.robot, gravity, stowed).mu
        mu_r[i] = robot_force_angle(ctx.robot, gravity, None).mu
        for j, heading in enumerate(task.headings):
            rng = cell_rng(ctx.settings.seed, b.variant, b.slope.start + i, b.heading.start + j)
            best = plan_best_pose(ctx, ramp, float(heading), rng)
            mu_p[i, j], com[i, j], secs[i, j] = best.mu, best.arm_com, best.seconds
            with _LOCK:
                _COUNTS["cells"] += 1
    with _LOCK:
        _COUNTS["chunks"] += 1
    return ChunkResult(b, mu_p, com, mu_s, mu_r, secs, time.perf_counter() - t0)
