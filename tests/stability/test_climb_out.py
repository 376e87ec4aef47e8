"""Climbing a step with the rear down (``mmstab.stability.climb_out``) against hand geometry."""

from __future__ import annotations

import numpy as np
import pytest

from mmstab.stability.climb_out import climb_out, pivot_rest
from mmstab.terrain.generators import Grid, ditch, plane
from mmstab.terrain.heightmap_terrain import HeightmapTerrain

WIDTH = 0.8  # the ditch, across x = 0 [m]


def _crosses_by_hand(xc: float, zc: float, h: float, r: float, L: float) -> bool:
    """Whether a CoM (xc, zc) in B passes a sharp step's edge, h high, before the robot
    overturns: the rear axle at (0, r) over the floor, the belt tangent to the edge
    (X_e, h): X_e sin p = (h - r) cos p + r; the CoM (xc + L/2) cos p - (zc - r) sin p
    ahead of the axle. Overturned where that falls behind 0 or the rear wheel reaches
    the face (X_e <= r)."""
    for p in np.radians(np.arange(0.05, 89.9, 0.01)):
        xe = ((h - r) * np.cos(p) + r) / np.sin(p)
        if np.sqrt(xe**2 + (h - r) ** 2 - r**2) > L:
            continue  # the edge is ahead of the front axle: the front wheel not up yet
        if xe <= r:
            return False
        xcom = (xc + L / 2) * np.cos(p) - (zc - r) * np.sin(p)
        if xcom < 0:
            return False
        if xcom >= xe:
            return True
    return False


@pytest.fixture(scope="module")
def crossing(robot):
    """The samples across a 5 mm map with a sharp ditch: x from -1.1 to 1.1 m, heading 0."""

    def make(depth: float):
        grid = Grid.of_size((3.0, 1.6), 0.005)
        terrain = HeightmapTerrain(ditch(grid, depth, WIDTH, 0.0, 0.0)).with_robot(robot)
        x = np.arange(-1.1, 1.1, 0.01)
        poses = np.c_[x, np.zeros_like(x), np.zeros_like(x)]
        return pivot_rest(robot, terrain, poses)

    return make


def _boundary(robot, zc: float, h: float) -> float:
    """The CoM's x in B [m] from which it crosses, by bisection on the hand geometry."""
    t = robot.base.tracks
    lo, hi = -0.3, 0.3
    for _ in range(40):
        mid = (lo + hi) / 2
        lo, hi = (lo, mid) if _crosses_by_hand(mid, zc, h, t.height / 2, t.length) else (mid, hi)
    return hi


def test_a_deep_ditch_overturns_a_com_behind_the_hand_boundary_and_not_one_ahead(robot, crossing):
    h, zc = 0.18, 0.16
    x_star = _boundary(robot, zc, h)
    assert -0.1 < x_star < 0.2  # an 18 cm wall: the Cameleon's CoM decides
    rest = crossing(h)
    behind = climb_out(robot, rest, [x_star - 0.015, 0.0, zc])
    ahead = climb_out(robot, rest, [x_star + 0.015, 0.0, zc])
    assert behind.overturns.sum() == 1 and not ahead.overturns.any()
    # both climb the far wall with the rear in the ditch first, nose up past 20 deg
    for co in (behind, ahead):
        assert co.climbing.any() and np.nanmax(co.pitch[co.climbing]) > np.radians(20)
    # the climbing attitude against the hand geometry: where the belt rests on the edge at
    # x_e ahead of the rear axle, X_e sin p = (h - r) cos p + r
    r, L = robot.base.tracks.height / 2, robot.base.tracks.length
    k = np.flatnonzero(behind.climbing & (rest.pitch > np.radians(5)))
    assert len(k) >= 20
    p = rest.pitch[k]
    x_edge = WIDTH / 2 - (np.arange(-1.1, 1.1, 0.01)[k] - L / 2)  # edge ahead of the axle
    np.testing.assert_allclose(x_edge * np.sin(p), (h - r) * np.cos(p) + r, atol=0.006)


def test_a_shallow_ditch_and_a_plane_never_overturn(robot, crossing):
    back = [-0.06, 0.0, 0.18]  # the arm swung over the rear
    shallow = climb_out(robot, crossing(0.08), back)
    assert not shallow.overturns.any() and _crosses_by_hand(-0.06, 0.18, 0.08, 0.11, 0.70)
    terrain = HeightmapTerrain(plane(Grid.of_size((3.0, 1.6), 0.05), 0.2, 0.0)).with_robot(robot)
    x = np.arange(-1.0, 1.0, 0.05)
    rest = pivot_rest(robot, terrain, np.c_[x, np.zeros_like(x), np.zeros_like(x)])
    np.testing.assert_allclose(rest.pitch, 0.2, atol=1e-3)  # nose up the 0.2 rad plane
    assert not rest.belly.any()  # on its end wheels
    assert not climb_out(robot, rest, back).overturns.any()


def test_the_most_backward_com_of_a_move_counts(robot, crossing):
    """Per sample, the CoMs the arm may pass through: the most backward one decides."""
    h, zc = 0.18, 0.16
    x_star = _boundary(robot, zc, h)
    rest = crossing(h)
    n = len(rest.pitch)
    coms = np.full((n, 3, 3), np.nan)
    coms[:, 0] = [x_star + 0.05, 0.0, zc]
    coms[:, 1] = [x_star - 0.015, 0.0, zc]  # mid-move, behind the boundary
    assert climb_out(robot, rest, coms).overturns.any()
    coms[:, 1] = np.nan
    assert not climb_out(robot, rest, coms).overturns.any()
