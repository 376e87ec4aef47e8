"""Collision checks' skips against FCL on every pair: turn floors, the pairs' gaps, clearance."""

from __future__ import annotations

import fcl
import numpy as np
from conftest import random_postures

from mmstab.model import collision_distance
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


def _rotation(rng: np.random.Generator) -> np.ndarray:
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))


def test_segment_bounds_equal_fcl_distances_to_boxes_and_capsules(rng):
    """The C kernel's bounds: below FCL's distance, and within 1e-4 m of it (to round-off)."""
    half = np.array([0.2, 0.1, 0.05])
    box = fcl.CollisionObject(fcl.Box(*(2 * half)), fcl.Transform())
    n = 300
    a0, a1 = rng.uniform(-0.6, 0.6, (n, 3)), rng.uniform(-0.6, 0.6, (n, 3))
    b0, b1 = rng.uniform(-0.6, 0.6, (n, 3)), rng.uniform(-0.6, 0.6, (n, 3))
    centre, R = rng.uniform(-0.1, 0.1, (n, 3)), np.stack([_rotation(rng) for _ in range(n)])
    to_box = collision_distance.segment_box(a0, a1, centre, R, half)
    between = collision_distance.segment_segment(a0, a1, b0, b1)
    r = 0.01
    for k in range(n):
        cap_a = _capsule(a0[k], a1[k], r)
        box.setTransform(fcl.Transform(R[k], centre[k]))
        d = fcl.distance(cap_a, box, fcl.DistanceRequest(), fcl.DistanceResult())
        if d > 0:  # FCL answers -1 when they overlap
            assert to_box[k] - r <= d + 1e-9
            assert d - (to_box[k] - r) < 1e-4
        cap_b = _capsule(b0[k], b1[k], r)
        d = fcl.distance(cap_a, cap_b, fcl.DistanceRequest(), fcl.DistanceResult())
        if d > 0:
            assert between[k] - 2 * r <= d + 1e-9
            assert d - (between[k] - 2 * r) < 1e-4
    # the stop: a bound decided against it is on the right side of it
    stop = 0.05
    decided = collision_distance.segment_box(a0, a1, centre, R, half, stop)
    np.testing.assert_array_equal(decided >= stop, to_box >= stop)


def _capsule(a: np.ndarray, b: np.ndarray, r: float) -> fcl.CollisionObject:
    """An FCL capsule of radius r [m] around segment a-b (its axis along its local z)."""
    axis = b - a
    z = axis / np.linalg.norm(axis)
    x = np.cross([1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    R = np.column_stack([x, np.cross(z, x), z])
    return fcl.CollisionObject(
        fcl.Capsule(r, float(np.linalg.norm(axis))), fcl.Transform(R, (a + b) / 2)
    )
