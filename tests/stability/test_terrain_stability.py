"""Force-angle on 3-D contacts that are not coplanar (support_polygon_3d + axis_angles)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import Delaunay

from mmstab.stability.static import (
    axis_angles,
    contact_force_angle,
    force_angle,
    support_polygon_3d,
)


def test_non_coplanar_polygon_by_hand():
    """Four contacts, one raised 0.4 m: two axes lie flat, two climb; CoM 1 m above the middle.

    Flat axes (x = 1 and y = -1, z = 0): the CoM sits 1 m in and 1 m up: 45 deg.
    Climbing axes (from (1, 1, 0) to (-1, 1, 0.4), and from (-1, 1, 0.4) to (-1, -1, 0)):
    seen along the axis, the CoM is 1 m aside and 1.6/sqrt(4.16) m below, the force
    2/sqrt(4.16) of its length across: theta = atan2(sqrt(4.16), 1.6).
    """
    pts = np.array([[1.0, -1, 0], [1, 1, 0], [-1, 1, 0.4], [-1, -1, 0]])
    com, force = np.array([0.0, 0, 1]), np.array([0.0, 0, -100])
    assert np.linalg.svd(pts - pts.mean(axis=0))[1][2] > 0.05  # not coplanar
    poly = support_polygon_3d(pts[[2, 0, 3, 1]], force)  # any input order
    theta = axis_angles(poly.vertices, com, force)
    climb = np.arctan2(np.sqrt(4.16), 1.6)
    expected = {(0, 1): np.pi / 4, (1, 2): climb, (2, 3): climb, (3, 0): np.pi / 4}
    index = [int(np.flatnonzero((pts == v).all(axis=1))[0]) for v in poly.vertices]
    for j in range(4):
        axis = (index[j], index[(j + 1) % 4])
        assert theta[j] == pytest.approx(expected[axis], abs=1e-12)
    mu = float(theta.min() * 100)
    assert mu == pytest.approx(100 * np.pi / 4)
    _, mu2, line = contact_force_angle(pts, com, force)
    assert mu2 == pytest.approx(mu) and not line


def test_sign_is_the_gravity_line_inside_the_footprint(rng):
    """Vertical gravity: mu > 0 exactly when the CoM is above the contacts' footprint."""
    down = np.array([0.0, 0.0, -50.0])
    agree = 0
    for _ in range(200):
        pts = np.c_[rng.uniform(-1, 1, (6, 2)), rng.uniform(-0.3, 0.3, 6)]
        com = np.r_[rng.uniform(-1.2, 1.2, 2), rng.uniform(0.5, 1.5)]
        poly = support_polygon_3d(pts, down)
        mu = axis_angles(poly.vertices, com, down).min()
        inside = Delaunay(pts[:, :2]).find_simplex(com[:2]) >= 0
        assert (mu > 0) == inside
        agree += 1
    assert agree == 200


def test_coplanar_contacts_match_the_planar_polygon(rng):
    """On a tilted plane with a slanted force the 3-D ordering gives the planar measure."""
    for _ in range(20):
        a, b = rng.uniform(-0.5, 0.5, 2)
        xy = rng.uniform(-1, 1, (7, 2))
        pts = np.c_[xy, a * xy[:, 0] + b * xy[:, 1]]
        com = np.r_[rng.uniform(-0.3, 0.3, 2), 0.8]
        force = np.r_[rng.normal(0, 15, 2), -100.0]
        poly = support_polygon_3d(pts, force)
        mu3 = axis_angles(poly.vertices, com, force).min() * np.linalg.norm(force)
        assert mu3 == pytest.approx(force_angle(pts, com, force), abs=1e-9)


def test_collinear_contacts_are_a_line_with_mu_at_most_zero():
    pts = np.array([[0.0, -1, 0], [0, 0, 0], [0, 1, 0]])
    with pytest.raises(ValueError, match="collinear"):
        support_polygon_3d(pts, [0, 0, -1.0])
    poly, mu, line = contact_force_angle(pts, np.array([0.1, 0, 1]), [0, 0, -98.1])
    assert line and len(poly) == 2 and mu < 0
    _, mu, line = contact_force_angle(pts, np.array([0.0, 0.3, 1]), [0, 0, -98.1])
    assert line and mu == pytest.approx(0.0, abs=1e-12)  # balanced on the line


def test_contacts_a_fraction_of_a_millimetre_apart_are_one():
    """Two contacts 0.07 mm apart (a simulated wheel's contact and its nearest point) are one
    vertex: the hull edge between them has no meaningful tip axis.

    A 0.70 x 0.52 m rectangle of wheel contacts on the ground, the CoM 0.146 m above its
    centre, gravity tilted 18 deg forward (a robot driving down an 18 deg slope): by hand the
    front edge limits, theta = atan(0.35 / 0.146) - 18 deg. The same rectangle with each
    front corner doubled by a point 0.07 mm off it (slightly higher, as a heightfield's
    second contact under one wheel) gives the same μ; without the merge the 0.07 mm edge
    gave 8 % less (446 N rad against 486).
    """
    x, y = 0.35, 0.26
    corners = np.array([[x, -y, 0.0], [x, y, 0.0], [-x, y, 0.0], [-x, -y, 0.0]])
    twin = corners[:1] + np.array([2e-5, 1e-5, 6.7e-5])  # 0.07 mm off the front right one
    along = np.linspace(-x, x, 15)
    rows = [np.c_[along, np.full(15, s * y), np.zeros(15)] for s in (1, -1)]
    com = np.array([0.0, 0.0, 0.146])
    tilt = np.radians(18.0)
    force = 57.5 * 9.81 * np.array([np.sin(tilt), 0.0, -np.cos(tilt)])
    by_hand = (np.arctan2(x, 0.146) - tilt) * np.linalg.norm(force)
    clean = contact_force_angle(np.concatenate(rows), com, force)
    doubled = contact_force_angle(np.concatenate([*rows, twin]), com, force)
    assert clean.mu == pytest.approx(by_hand, rel=1e-9)
    assert doubled.mu == pytest.approx(by_hand, rel=1e-3)  # the kept vertex may be the twin
    assert len(doubled.polygon) == 4
