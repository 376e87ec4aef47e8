"""Collision checks' skips against FCL on every pair: turn floors, the pairs' gaps, clearance."""

from __future__ import annotations

import fcl
import numpy as np
from conftest import random_postures

from mmstab.model.collision import CollisionChecker, Pair
from mmstab.model.reach import joint_reach


def fcl_distance(checker: CollisionChecker, pair: Pair, q: np.ndarray) -> np.ndarray:
    """FCL's distance of one link-vs-base pair at postures q (N, 4) [rad] (N,) [m]."""
    R, p = checker.shape_poses(q)
    a, b = checker._link_objs[pair.link], checker._base_objs[str(pair.other)]
    out = []
    for n in range(len(q)):
        a.setTransform(fcl.Transform(R[n, pair.link], p[n, pair.link]))
        out.append(fcl.distance(a, b, fcl.DistanceRequest(), fcl.DistanceResult()))
    return np.array(out)


def test_turn_floors_lie_below_fcl_at_every_angle_and_the_turret_keeps_a_centimetre(robot, rng):
    checker = CollisionChecker(robot)
    floors = checker.turn_floors()
    assert set(floors) == {p.name for p in checker.pairs if p.columns == (0,)}
    q = random_postures(robot, rng, 400)
    q[:, 0] = rng.uniform(-np.pi, np.pi, len(q))  # any angle, off the floors' grid
    for pair in checker.pairs:
        if pair.name in floors:
            d = fcl_distance(checker, pair, q)
            assert floors[pair.name] <= d.min(), pair.name
            assert d.min() - floors[pair.name] < 1e-3, pair.name  # a bound close to the truth
    # the turret box sits 1 cm over the body at every angle (the robot file's geometry)
    assert 0.009 < floors["turret-body"] <= 0.01


def test_all_gaps_at_once_equal_each_pairs_gap(robot, rng):
    checker = CollisionChecker(robot)
    _, p = checker.shape_poses(random_postures(robot, rng, 300))
    gaps = checker._gaps(p)
    for pair in checker.pairs:
        np.testing.assert_allclose(
            gaps[:, checker._gap_column[pair.name]], checker._gap(pair, p), rtol=0, atol=1e-12
        )


def test_keeps_clearance_equals_fcl_on_every_posture_and_pair(robot, rng):
    """Straight moves near the body: the answer is FCL's clearance at every posture >= need."""
    checker = CollisionChecker(robot)
    stowed = np.asarray(robot.stowed, dtype=float)
    reach = joint_reach(robot, random_postures(robot, rng, 2000))
    agree, seen = 0, set()
    for _ in range(60):
        a = stowed + rng.normal(0.0, 0.3, 4)
        b = stowed + rng.normal(0.0, 0.3, 4)
        q = a + np.linspace(0.0, 1.0, 40)[:, None] * (b - a)
        need = float(rng.uniform(0.002, 0.02))
        truth = bool((checker.clearance(q) >= need).all())
        step = float(reach @ np.abs(q[1] - q[0]))  # no point moves more between postures
        got = checker.keeps_clearance(q, need, step)
        seen.add(truth)
        agree += got == truth
    assert seen == {True, False}  # both answers occur (else the test proves little)
    assert agree == 60
