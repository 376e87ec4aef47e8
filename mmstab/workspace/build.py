"""Labelling the grid: FK and FCL self-collision per posture, in chunks, in a process pool."""

from __future__ import annotations

import contextlib
import dataclasses
import os
import threading
import time
from collections.abc import Iterator, Sequence
from concurrent.futures import Executor, as_completed

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from mmstab.core.pool import ChunkPool
from mmstab.model.collision import CollisionChecker
from mmstab.model.robot import FloatArray, Robot
from mmstab.workspace.grid import JointGrid, grid_postures, joint_grid
from mmstab.workspace.region import Workspace, workspace_from_clouds

#: Postures per chunk handed to a worker.
DEFAULT_CHUNK = 16384
#: From this many postures on, ``build_workspace`` uses a process pool by default.
PARALLEL_MIN_POSTURES = 50_000
#: Processes of that pool (:class:`mmstab.core.pool.ChunkPool`).
PARALLEL_WORKERS = 2


# ---------------------------------------------------------------------------------- build
_CHECKERS: dict[tuple[str, int], CollisionChecker] = {}  # per robot, process and thread


def _checker(robot: Robot) -> CollisionChecker:
    key = (robot.source_hash, threading.get_ident())
    if key not in _CHECKERS or not robot.source_hash:
        _CHECKERS[key] = CollisionChecker(robot)
    return _CHECKERS[key]


def label_chunk(
    robot: Robot, grid: JointGrid, start: int, stop: int
) -> tuple[int, NDArray[np.bool_], FloatArray]:
    """Label grid postures ``start:stop`` (runs in a worker).

    Returns:
        ``start``, collision-free flags (n,), arm CoMs (n, 3) in the body frame [m].
    """
    checker = _checker(robot)
    q = grid_postures(grid, start, stop)
    frames = checker.kinematics.link_frames(q)
    free = ~np.asarray(checker.collides(q, frames=frames), dtype=bool)
    return start, free, arm_com_from_frames(robot, frames)


def arm_com_from_frames(robot: Robot, frames: FloatArray) -> FloatArray:
    """Arm CoM g_a (N, 3) in the body frame [m] from link frames B_T_R_i (N, n, 4, 4).

    The same quantity as ``robot.arm_com(q)`` (Eq. 1), without repeating the kinematics.
    """
    masses = np.array([link.mass for link in robot.links])
    com_link = np.array([link.com for link in robot.links])[:, :, None]  # (n, 3, 1) in R_i
    coms = (frames[..., :3, :3] @ com_link)[..., 0] + frames[..., :3, 3]  # (N, n, 3) in B
    return (coms * masses[:, None]).sum(axis=1) / masses.sum()


def build_workspace(
    robot: Robot,
    grid: Sequence[int],
    executor: Executor | None = None,
    chunk: int = DEFAULT_CHUNK,
    progress: bool = True,
    samples: int | None = None,
    seed: int = 0,
) -> Workspace:
    """Label every grid posture (or a draw of them) and build V (no cache).

    See ``load_or_build_workspace`` for the cached build. A grid over the size bound
    (:func:`mmstab.core.sizes.workspace_postures`) is sampled (:func:`joint_grid`).

    Args:
        robot: the robot.
        grid: samples per joint, one integer >= 2 per arm joint.
        executor: runs the chunks (any ``concurrent.futures.Executor``); default: a
            :class:`~mmstab.core.pool.ChunkPool` of ``PARALLEL_WORKERS`` processes from
            ``PARALLEL_MIN_POSTURES`` postures on (stopped at once by Ctrl-C), else this
            process.
        chunk: postures per chunk.
        progress: show a tqdm progress bar.
        samples: postures drawn from a grid over the bound (None: the whole grid).
        seed: seed of that draw (``workspace.seed``).
    """
    t0 = time.perf_counter()
    jg = joint_grid(robot, grid, samples, seed)
    n = jg.size
    bounds = [(s, min(s + chunk, n)) for s in range(0, n, chunk)]
    free = np.empty(n, dtype=bool)
    com = np.empty((n, 3))
    with contextlib.ExitStack() as stack:
        results: Iterator[tuple[int, NDArray[np.bool_], FloatArray]]
        light = dataclasses.replace(robot)  # without the cached CasADi kinematics
        if executor is not None:
            futures = [executor.submit(label_chunk, light, jg, a, b) for a, b in bounds]
            results = (f.result() for f in as_completed(futures))
        elif n >= PARALLEL_MIN_POSTURES and (os.cpu_count() or 1) > 1:
            # killable on Ctrl-C, workers included (mmstab.core.pool)
            pool = stack.enter_context(ChunkPool(label_chunk, (light, jg), PARALLEL_WORKERS))
            results = pool.run(bounds)
        else:
            results = (label_chunk(robot, jg, a, b) for a, b in bounds)
        with tqdm(total=n, unit="posture", desc="workspace", disable=not progress) as bar:
            for start, f, c in results:
                free[start : start + len(f)] = f
                com[start : start + len(f)] = c
                bar.update(len(f))
    q = grid_postures(jg)
    ws = workspace_from_clouds(
        grid, q[free], com[free], q[~free], com[~free], time.perf_counter() - t0
    )
    return ws if jg.picks is None else dataclasses.replace(ws, samples=n, seed=int(seed))
