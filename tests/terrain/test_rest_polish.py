"""The rests the Newton rounds leave unsettled, taken to the potential energy's minimum.

Ground we did not write: route 10 of ``make validate-routes`` (a seeded 19 deg side slope
with a 15 cm ditch and a 7.6 cm kerb across the route), rested at seeded random poses along
its path with seeded arm CoMs.
"""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from conftest import validation_route_file

from mmstab.core.problem import load_problem
from mmstab.terrain.rest import rest_poses
from mmstab.terrain.rest.polish import energy


@pytest.fixture(scope="module")
def kerb_and_ditch(tmp_path_factory):
    path = validation_route_file(10, tmp_path_factory.mktemp("route10"))
    data = yaml.safe_load(path.read_text())
    problem = load_problem(path)
    ground = problem.terrain.with_robot(problem.robot)
    rng = np.random.default_rng(0)
    n = 3000
    w = np.asarray(data["path"]["waypoints"], dtype=float)
    leg, u = rng.integers(0, len(w) - 1, n), rng.uniform(0.0, 1.0, n)
    xy = w[leg] + (w[leg + 1] - w[leg]) * u[:, None]
    heading = np.arctan2(*(w[leg + 1] - w[leg])[:, ::-1].T) + rng.normal(0.0, 0.05, n)
    arm = np.c_[rng.uniform(-0.1, 0.4, n), rng.uniform(-0.2, 0.2, n), rng.uniform(0.2, 0.5, n)]
    return ground, np.c_[xy, heading], problem.robot.overall_com(arm)


def rests(ground, poses, com, **changes):
    c = ground.candidates
    s = ground.settings._replace(**changes)
    return rest_poses(ground.heightmap, c.points, com, poses, c.part, s, False, c.compliant)


def test_unsettled_rests_end_at_the_energy_minimum(kerb_and_ditch) -> None:
    ground, poses, com = kerb_and_ditch
    before, after = rests(ground, poses, com, polish=False), rests(ground, poses, com)
    rows = np.flatnonzero(np.isfinite(before.z) & ~before.converged & ~before.tips_over)
    assert len(rows) >= 5  # the rounds do leave some on this ground
    settled = np.setdiff1d(np.arange(len(poses)), rows)
    for name in ("roll", "pitch", "z"):  # the rests the rounds settled are untouched
        np.testing.assert_array_equal(getattr(after, name)[settled], getattr(before, name)[settled])
    assert after.converged[rows].all()
    hm, c = ground.heightmap, ground.candidates.points
    th = np.linspace(0.0, 2 * np.pi, 72, endpoint=False)
    ring = np.c_[np.cos(th), np.sin(th)]
    for i in rows:
        a0 = np.array([before.roll[i], before.pitch[i]])
        a1 = np.array([after.roll[i], after.pitch[i]])
        v0, v1 = (float(energy(hm, c, com[i], poses[i], a[None])[0]) for a in (a0, a1))
        assert v1 <= v0 + 1e-12  # the CoM no higher than where the rounds stopped
        for eps in (1e-6, 1e-4, 1e-2):  # and no attitude near it lower: a minimum
            assert energy(hm, c, com[i], poses[i], a1 + eps * ring).min() >= v1 - 1e-12
        # the body rests on the ground: the highest lift is its height
        assert after.z[i] == pytest.approx(
            before.z[i] + (v1 - v0) - _com_z(a1, a0, com[i], poses[i]), abs=1e-9
        )


def _com_z(a1, a0, com, pose):
    """How much the CoM's height above B's origin changes from attitude a0 to a1 [m]."""
    from mmstab.terrain.rest.geometry import rotations

    A = np.array([a1, a0])
    R = rotations(np.full(2, pose[2]), A[:, 0], A[:, 1])[0]
    z = R[:, 2, :] @ com
    return float(z[0] - z[1])


def test_the_numpy_twin_polishes_to_the_same_rests(kerb_and_ditch) -> None:
    ground, poses, com = kerb_and_ditch
    before = rests(ground, poses, com, polish=False)
    rows = np.flatnonzero(np.isfinite(before.z) & ~before.converged & ~before.tips_over)
    c_rest = rests(ground, poses[rows], com[rows])
    np_rest = rests(ground, poses[rows], com[rows], backend="numpy")
    assert c_rest.converged.all() and np_rest.converged.all()
    for name in ("roll", "pitch", "z"):
        np.testing.assert_allclose(getattr(np_rest, name), getattr(c_rest, name), atol=1e-8)


def test_the_box_minimax_step_is_the_linear_programmes_optimum() -> None:
    """Random piecewise-linear models (ties included): the enumerated vertex is no worse
    than HiGHS's solution of the same programme, and no point of a fine grid is lower."""
    from scipy.optimize import linprog

    from mmstab.terrain.rest.polish import box_minimax

    rng = np.random.default_rng(3)
    for _ in range(300):
        m = int(rng.integers(1, 40))
        a, J = rng.normal(0.0, 0.01, m), rng.normal(0.0, 0.3, (m, 2))
        if rng.uniform() < 0.3:
            a[: min(3, m)] = a[0]  # pieces that meet at d = 0
        g, delta = rng.normal(0.0, 0.1, 2), float(10 ** rng.uniform(-3, -1))
        d, value = box_minimax(a, J, g, delta)
        assert (np.abs(d) <= delta).all()
        assert value == pytest.approx((a + J @ d).max() + g @ d, abs=1e-15)
        lp = linprog([g[0], g[1], 1.0], A_ub=np.c_[J, -np.ones(m)], b_ub=-a,
                     bounds=[(-delta, delta)] * 2 + [(None, None)], method="highs")  # fmt: skip
        x = lp.x[:2]
        assert value <= (a + J @ x).max() + g @ x + 1e-15
        u = np.linspace(-delta, delta, 41)
        grid = np.stack(np.meshgrid(u, u), axis=-1).reshape(-1, 2)
        assert value <= ((grid @ J.T + a).max(axis=1) + grid @ g).min() + 1e-15
