"""The exhaustive optimum, pruned axis by axis, against scoring every sample on every axis."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ROOT
from scipy.spatial import ConvexHull

from mmstab.model.robot import load_robot
from mmstab.planner.fitness import linear_fitness
from mmstab.planner.searches.exhaustive import SUBSET_ROWS, best_mu, max_min_mu
from mmstab.stability.static import base_polygon


def _polygon(rng: np.random.Generator, robot) -> np.ndarray:
    """A random convex support polygon in B, counter-clockwise, around the tracks' one."""
    rect = base_polygon(robot).vertices[:, :2]
    pts = np.vstack([rect * rng.uniform(0.4, 1.1, size=rect.shape), rng.normal(0, 0.15, (5, 2))])
    hull = pts[ConvexHull(pts).vertices]
    return np.c_[hull, rng.uniform(-0.01, 0.01, len(hull))]


def _gravity(rng: np.random.Generator) -> np.ndarray:
    tilt, azimuth = rng.uniform(0, 0.7), rng.uniform(-np.pi, np.pi)
    return 9.81 * np.array([np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth),
                            -np.cos(tilt)])  # fmt: skip


@pytest.mark.parametrize("seed", range(8))
def test_the_pruned_optimum_is_every_samples_optimum(seed: int) -> None:
    rng = np.random.default_rng(seed)
    robot = load_robot(ROOT / "problems" / "robots" / "cameleon.yaml")
    coms = rng.uniform([-0.6, -0.5, 0.0], [0.6, 0.5, 0.8], size=(60_000, 3))
    polygon = None if seed % 3 == 0 else _polygon(rng, robot)
    g = _gravity(rng)
    poly = base_polygon(robot).vertices if polygon is None else polygon
    fit = linear_fitness(robot, poly, g, np.zeros(3), 1.0, 0.0)
    mu = fit.mu(coms)
    k = int(np.argmax(mu))
    assert len(coms) > 4 * SUBSET_ROWS  # the pruned path, not the small-N one
    assert best_mu(robot, g, coms, polygon) == (float(mu[k]), k)
    # a tie: the best row again, earlier and later; the first row reaching it is named
    tied = np.insert(coms, [10, len(coms)], coms[k], axis=0)
    value, row = max_min_mu(fit, tied)
    assert value == float(mu[k]) and row == 10
