"""The ground under the arm's C kernel against its NumPy twin, on seeded random maps.

The kernel (mmstab/planner/ground/kernel.c) follows
:mod:`mmstab.planner.ground.under_arm`'s NumPy functions operation for operation: the
pieces' lowest points (over the attitude margin's tilts) come out bit for bit, their
centres to 1 ulp (NumPy's matrix product may fuse multiply-adds), the heights above the
ground bit for bit from the same pieces, and a route's plan is the same posture for
posture and move for move.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
from test_random_routes import COARSE, pair_problem

MARGINS = (0.0, 0.0524)


@pytest.fixture(scope="module")
def pairs(tmp_path_factory):
    from mmstab.core.problem import load_problem

    folder = tmp_path_factory.mktemp("pairs")
    return [load_problem(pair_problem(k, folder, COARSE)) for k in (0, 1, 2)]


def _route_poses(problem, spacing=0.5):
    route = problem.route
    return route.route.sample(np.arange(0.0, route.length, spacing)).pose


@pytest.mark.parametrize("margin", MARGINS)
def test_pieces_in_body_c_equals_numpy(robot, margin):
    from mmstab.planner.ground.under_arm import arm_pieces, pieces_in_body

    pieces = arm_pieces(robot)
    q = np.random.default_rng(7).uniform(robot.joint_lower, robot.joint_upper, (3000, 4))
    twin = pieces_in_body(robot, pieces, q, margin, "numpy")
    kernel = pieces_in_body(robot, pieces, q, margin, "c")
    assert np.array_equal(kernel.low, twin.low)  # bit for bit
    assert np.allclose(kernel.centre, twin.centre, rtol=0.0, atol=1e-15)
    assert np.ptp(twin.low) > 0.5  # the postures spread the arm: a real comparison


@pytest.mark.parametrize("margin", MARGINS)
def test_heights_c_equal_numpy_on_random_maps(robot, pairs, margin):
    from mmstab.planner.ground.under_arm import GroundUnderArm

    rng = np.random.default_rng(11)
    q = rng.uniform(robot.joint_lower, robot.joint_upper, (1500, 4))
    low_seen = 0
    for problem in pairs:
        poses = _route_poses(problem)
        twin = GroundUnderArm(robot, problem.terrain, poses, margin=margin, backend="numpy")
        kernel = GroundUnderArm(robot, problem.terrain, poses, margin=margin, backend="c")
        body = twin.body(q)
        for k in range(len(poses)):
            for above, plane in ((np.inf, False), (0.05, False), (0.05, True)):
                h_twin = twin.poses[k].heights(body, above, plane)
                h_kernel = kernel.poses[k].heights(body, above, plane)
                assert np.array_equal(h_kernel, h_twin), (k, above, plane)
            # and the kernel's own pieces decide the same clearances
            assert np.array_equal(kernel.clear(k, q, 0.05), twin.clear(k, q, 0.05, body))
            low_seen += int((~twin.clear(k, q, 0.05, body)).sum())
        ks = (0, 1)
        path = q[:6]
        a, b = twin.sweep_clear(ks, path, np.full(4, 0.8), 0.05)
        c, d = kernel.sweep_clear(ks, path, np.full(4, 0.8), 0.05)
        assert np.array_equal(a, c) and np.array_equal(b, d)
    assert low_seen > 100  # the ground rules some postures out: both paths say which


def test_a_route_plans_the_same_with_the_kernel_and_its_twin(pairs, monkeypatch):
    """The plan's postures and moves identical, the kernel's against the NumPy twin's."""
    import mmstab.planner.searches.roadmap as search
    from mmstab import app
    from mmstab.planner.ground.under_arm import GroundUnderArm

    for problem in pairs[:2]:
        assert problem.section("planner")["attitude_margin"]  # every default check on
        ws = app.workspace(problem, progress=False)
        plans = {}
        for backend in ("numpy", "c"):
            monkeypatch.setattr(
                search, "GroundUnderArm", functools.partial(GroundUnderArm, backend=backend)
            )
            plans[backend] = app.plan(problem, ws=ws)
        twin, kernel = plans["numpy"], plans["c"]
        assert np.array_equal(kernel.postures, twin.postures)
        assert len(kernel.moves) == len(twin.moves) == len(twin.s)
        assert all(np.array_equal(a, b) for a, b in zip(kernel.moves, twin.moves, strict=True))
