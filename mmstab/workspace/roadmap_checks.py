"""The posture roadmap's checks in batches: the edges' moves and the nodes' own arrays.

Helpers of :mod:`mmstab.workspace.roadmap`: a move's checked postures coarse first, the
grid indices of grid postures, the collision checks of every edge along one joint, and the
per-node arrays the roadmap's cache file keeps.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from mmstab.model.collision import CollisionChecker, row_keys, value_codes
from mmstab.model.plane_clearance import arm_ground_clearance
from mmstab.model.robot import FloatArray, Robot
from mmstab.workspace.grid import JointGrid

#: Smallest clearance [m] between an arm link and the robot that a shortcut's straight
#: move keeps (:meth:`mmstab.workspace.roadmap.Roadmap.shortcut`): the tracked arm follows
#: the moves within a few millimetres, and a tracking run must keep 1 mm
#: (``mmstab.runs.verdict.MIN_CLEARANCE``).
MOVE_CLEARANCE = 0.003
#: A move's checked postures go to the checker every this many first (:func:`coarse_first`).
COARSE_STRIDE = 8
#: Postures per batch handed to the collision checker.
CHECK_CHUNK = 16384


def coarse_first(n: int, stride: int = COARSE_STRIDE) -> tuple[FloatArray, FloatArray]:
    """The fractions i / n, i = 0..n, in two batches: every ``stride``-th, then the rest.

    A move that fails usually fails over a stretch, which the first batch finds at a
    ``stride``-th of the cost; a move that passes is checked at every fraction all the same.
    """
    i = np.arange(n + 1)
    first = (i % stride == 0) | (i == n)
    return i[first] / n, i[~first] / n


def grid_index(jg: JointGrid, q: FloatArray) -> NDArray[np.int64]:
    """Grid indices (N, 4) of grid postures q [rad]."""
    lo = np.array([a[0] for a in jg.axes])
    idx = np.rint((q - lo) / jg.step).astype(np.int64)
    return np.minimum(idx, np.array(jg.shape) - 1)


def free_moves(
    checker: CollisionChecker,
    q: FloatArray,
    j: int,
    step: float,
    steps: int,
    bar: tqdm | None = None,
) -> NDArray[np.bool_]:
    """Whether the moves q -> q + step e_j (N rows) are free at ``steps`` interior postures.

    The rows are collision-free postures (V's nodes): only the pairs that joint j moves
    relative to each other are checked.

    ``bar``: advanced by one per interior posture checked.
    """
    ok = np.ones(len(q), dtype=bool)
    # a move shifts every row's joint j alike, so the rows that agree on a pair's joints
    # agree at every step: grouped once here, not once per step
    groups = move_groups(checker, q, j)
    for s in range(1, steps + 1):
        if bar is not None:
            bar.update(1)
        rows = np.flatnonzero(ok)
        if not len(rows):
            break
        shifted = q[rows].copy()
        shifted[:, j] += step * s / (steps + 1)
        for c in range(0, len(rows), CHECK_CHUNK):
            part = rows[c : c + CHECK_CHUNK]
            batch = shifted[c : c + CHECK_CHUNK]
            hit = checker.collides(batch, moving=j, groups=groups_of(groups, part))
            hit = np.asarray(hit, dtype=bool)
            ok[part[hit]] = False
    return ok


def move_groups(
    checker: CollisionChecker, q: FloatArray, j: int
) -> dict[tuple[int, ...], tuple[NDArray[np.intp], int]]:
    """Per joint set of the pairs joint j moves: each row's group of equal values there."""
    out: dict[tuple[int, ...], tuple[NDArray[np.intp], int]] = {}
    codes = value_codes(q)
    for columns in {pr.columns for pr in checker.pairs if j in pr.columns}:
        _, inverse = np.unique(row_keys(codes, columns), return_inverse=True)
        out[columns] = inverse.reshape(-1), int(inverse.max(initial=-1)) + 1
    return out


def groups_of(
    groups: dict[tuple[int, ...], tuple[NDArray[np.intp], int]], part: NDArray[np.intp]
) -> dict[tuple[int, ...], tuple[NDArray[np.intp], NDArray[np.intp]]]:
    """:func:`move_groups` for the rows ``part``, as :meth:`CollisionChecker.collides` takes them.

    ``(first row of each group, each row's group)``; a group absent from ``part`` keeps
    ``len(part)`` as its first row (it is never asked for).
    """
    out = {}
    for columns, (inverse, n) in groups.items():
        inv = inverse[part]
        first = np.full(n, len(part), dtype=np.intp)
        np.minimum.at(first, inv, np.arange(len(part), dtype=np.intp))
        out[columns] = first, inv
    return out


def node_arrays(robot: Robot, nodes_q: FloatArray) -> dict[str, FloatArray]:
    """The nodes' ``node_com``, ``_ground``, ``_clearance`` [m], kept in the cache file."""
    checker, step = CollisionChecker(robot), range(0, len(nodes_q), CHECK_CHUNK)
    clear = [checker.clearance(nodes_q[c : c + CHECK_CHUNK], MOVE_CLEARANCE) for c in step]
    return {
        "node_com": np.asarray(robot.arm_com(nodes_q), dtype=float).reshape(-1, 3),
        "node_ground": arm_ground_clearance(robot, nodes_q),
        "node_clearance": np.concatenate(clear) if clear else np.zeros(0),
    }
