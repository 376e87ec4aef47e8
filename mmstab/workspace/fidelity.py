"""How faithful the workspace V is to the labelled clouds (paper Fig. 3 numbers).

Moved whole out of :mod:`mmstab.workspace` (modules by concept).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from mmstab.core.files import MmstabError
from mmstab.model.robot import FloatArray, Robot
from mmstab.workspace import Workspace, joint_grid


class Fidelity(NamedTuple):
    """How faithful V is to the labelled clouds.

    Attributes:
        recall: share of valid CoMs inside V.
        precision: share of points uniform in V within ``cell_size`` of a valid CoM.
        precision_half_cell: the same within ``cell_size / 2`` (stricter).
        cell_size: typical CoM spacing of one grid cell [m] (see :func:`grid_cell_size`).
        samples: points drawn in V for the precision.
    """

    recall: float
    precision: float
    precision_half_cell: float
    cell_size: float
    samples: int


def grid_cell_size(robot: Robot, ws: Workspace, rng: np.random.Generator, n: int = 2000) -> float:
    """Typical CoM-space size of one grid cell [m].

    For a posture q the cell is the joint-space box q + [0, step]^n; its CoM-space size is
    the largest distance from g_a(q) to the arm CoM at the cell's 2^n − 1 other corners. This
    returns the median over up to ``n`` valid postures drawn with ``rng``.
    """
    step = joint_grid(robot, ws.grid).step
    q = ws.valid_q[rng.choice(len(ws.valid_q), size=min(n, len(ws.valid_q)), replace=False)]
    n = len(step)
    corners = np.array([[(k >> j) & 1 for j in range(n)] for k in range(1, 2**n)]) * step
    com0 = robot.arm_com(q)
    shifted = (q[:, None, :] + corners[None]).reshape(-1, n)
    com = robot.arm_com(shifted).reshape(len(q), len(corners), 3)
    return float(np.median(np.linalg.norm(com - com0[:, None], axis=2).max(axis=1)))


def sample_in_workspace(
    ws: Workspace, n: int, rng: np.random.Generator, max_rounds: int = 200
) -> FloatArray:
    """Points uniform in V by rejection sampling in the bounding box of hull(all) (n, 3) [m].

    Raises:
        MmstabError: V is too thin to hit ``n`` times in ``max_rounds`` batches.
    """
    all_com = np.vstack([ws.valid_com, ws.invalid_com])
    lo, hi = all_com.min(axis=0), all_com.max(axis=0)
    kept: list[FloatArray] = []
    count = 0
    for _ in range(max_rounds):
        p = rng.uniform(lo, hi, size=(max(4 * (n - count), 1024), 3))
        p = p[ws.contains(p)]
        kept.append(p)
        count += len(p)
        if count >= n:
            return np.vstack(kept)[:n]
    raise MmstabError(f"V is too thin: {count} of {n} samples found in its bounding box")


def measure_fidelity(robot: Robot, ws: Workspace, samples: int, seed: int) -> Fidelity:
    """Recall and precision of V against the valid CoMs (see :class:`Fidelity`).

    Args:
        robot: the robot the workspace was built for.
        ws: the workspace.
        samples: points drawn uniformly in V for the precision.
        seed: seed of the numpy Generator used for sampling.
    """
    rng = np.random.default_rng(seed)
    cell = grid_cell_size(robot, ws, rng)
    recall = float(ws.contains(ws.valid_com).mean())
    pts = sample_in_workspace(ws, samples, rng)
    dist, _ = ws._valid_tree.query(pts)
    return Fidelity(
        recall=recall,
        precision=float(np.mean(dist <= cell)),
        precision_half_cell=float(np.mean(dist <= cell / 2)),
        cell_size=cell,
        samples=len(pts),
    )
