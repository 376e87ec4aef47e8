"""Where a dense sequence of postures collides: the anchors' proof against every sample."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ROBOT_YAML

from mmstab.model.collision import CollisionChecker
from mmstab.model.collision_sequence import (
    MAX_REACH_OUT,
    pair_counts,
    proven_free,
    sequence_collisions,
)
from mmstab.model.robot import load_robot


@pytest.fixture(scope="module")
def robot():
    return load_robot(ROBOT_YAML)


def sweep(robot, rng: np.random.Generator, knots: int, samples: int, step: float) -> np.ndarray:
    """A smooth random sweep: ``knots`` postures up to ``step`` [rad] apart, ``samples`` of it.

    Its columns stacked (Fortran order): the C kinematics once refused such an array
    (``a C-contiguous float64 array expected``)."""
    lo, hi = robot.joint_lower, robot.joint_upper
    q = [rng.uniform(lo, hi)]
    for _ in range(knots - 1):
        q.append(np.clip(q[-1] + rng.uniform(-step, step, len(lo)), lo, hi))
    u = np.linspace(0.0, knots - 1.0, samples)
    columns = [np.interp(u, np.arange(knots), np.array(q)[:, j]) for j in range(len(lo))]
    return np.array(columns).T  # Fortran order, as a user's stacked columns may come


def brute_force(checker: CollisionChecker, q: np.ndarray) -> tuple[np.ndarray, dict[str, int]]:
    """Every sample checked, and every colliding posture's pairs counted, one by one."""
    hit = np.asarray(checker.collides(q, cull=False), dtype=bool)
    counts: dict[str, int] = {}
    for q_k in np.unique(q[hit], axis=0):
        n = int(np.all(q[hit] == q_k, axis=1).sum())
        for name in checker.colliding_pairs(q_k):
            counts[name] = counts.get(name, 0) + n
    return hit, dict(sorted(counts.items(), key=lambda kv: -kv[1]))


@pytest.mark.parametrize("seed", [0, 3, 10])
def test_the_anchors_prove_only_free_samples_and_the_report_is_every_samples(robot, seed):
    rng = np.random.default_rng(seed)
    q = sweep(robot, rng, knots=6, samples=3000, step=1.0)  # under 2 mrad a sample
    checker = CollisionChecker(robot)
    hit, counts = brute_force(checker, q)
    assert 0 < hit.sum() < len(q)  # it passes through the robot and out
    free = proven_free(checker, q)
    assert not (free & hit).any() and free.mean() > 0.1
    report, got = sequence_collisions(checker, np.arange(len(q)) * 1e-3, q)
    np.testing.assert_array_equal(got, hit)
    assert report.colliding_samples == hit.sum() and report.pairs == counts
    assert list(report.pairs) == list(counts)  # ties in the same order


def test_a_sparse_sequence_is_checked_sample_by_sample(robot):
    """A run saved every 10 ms moves the arm centimetres between samples: anchors there would
    measure most pairs exactly and prove little; every sample is checked instead."""
    from mmstab.model.reach import joint_reach

    q = sweep(robot, np.random.default_rng(3), knots=40, samples=400, step=3.0)
    checker = CollisionChecker(robot)
    per_sample = np.abs(np.diff(q, axis=0)) @ joint_reach(robot, q)
    assert 2 * per_sample.max() > MAX_REACH_OUT  # one sample's motion already passes it
    assert not proven_free(checker, q).any()
    assert not proven_free(checker, q[:20]).any()  # too short for anchors
    hit, counts = brute_force(checker, q)
    report, got = sequence_collisions(checker, np.arange(len(q)), q)
    np.testing.assert_array_equal(got, hit)
    assert report.pairs == counts


def test_pair_counts_of_repeated_postures(robot):
    checker = CollisionChecker(robot)
    q = sweep(robot, np.random.default_rng(3), knots=6, samples=600, step=1.0)
    hit = np.asarray(checker.collides(q), dtype=bool)
    colliding = np.repeat(q[hit][::60][:5], [3, 1, 1, 2, 1], axis=0)  # postures held
    _, counts = brute_force(checker, colliding)
    assert pair_counts(checker, colliding) == counts and sum(counts.values()) >= 8
    assert pair_counts(checker, q[:0]) == {}
