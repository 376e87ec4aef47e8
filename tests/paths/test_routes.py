"""Routes: geometry by hand, derivatives, invariances, speed profile, files and errors."""

from __future__ import annotations

import numpy as np
import pytest

from mmstab.core.files import ConfigError
from mmstab.paths import Arc, Line, SpeedLimits, route_from_waypoints, speed_profile
from mmstab.paths.geometry import RouteError
from mmstab.paths.io import read_waypoints_csv, route_from_section

LIMITS = SpeedLimits(
    speed=0.5, acceleration=0.5, lateral_acceleration=0.5, track_speed=1.13, track_separation=0.42
)


def test_right_angle_corner_by_hand():
    route = route_from_waypoints([[0, 0], [2, 0], [2, 2]], turn_radius=0.5)
    kinds = [type(p) for p in route.pieces]
    assert kinds == [Line, Arc, Line]
    # the arc's tangent points are R tan(45 deg) = 0.5 m from the corner
    np.testing.assert_allclose(route.length, 1.5 + np.pi * 0.5 / 2 + 1.5, rtol=1e-12)
    mid = route.sample(1.5 + np.pi * 0.5 / 4)
    c = np.array([1.5, 0.5])  # the arc's centre
    np.testing.assert_allclose(
        mid.pose[0, :2], c + 0.5 * np.array([np.sin(np.pi / 4), -np.cos(np.pi / 4)])
    )
    np.testing.assert_allclose(mid.pose[0, 2], np.pi / 4)
    np.testing.assert_allclose(mid.curvature, [2.0])
    end = route.sample(route.length)
    np.testing.assert_allclose(end.pose[0], [2.0, 2.0, np.pi / 2], atol=1e-12)


def test_two_points_is_a_line():
    route = route_from_waypoints([[1, 1], [4, 5]], turn_radius=0.3)
    assert route.length == pytest.approx(5.0)
    np.testing.assert_allclose(route.sample(2.5).pose[0], [2.5, 3.0, np.arctan2(4, 3)])


def _random_route(rng, n=6):
    # waypoints on a rough zig-zag far enough apart for 0.4 m arcs
    xy = np.cumsum(rng.uniform([2.0, -2.0], [3.0, 2.0], (n, 2)), axis=0)
    return route_from_waypoints(xy, turn_radius=0.4), xy


def test_rate_is_the_derivative_and_yaw_the_tangent(rng):
    route, _ = _random_route(rng)
    s = rng.uniform(0, route.length, 200)
    h = 1e-6
    smp = route.sample(s)
    fd = (route.sample(s + h).pose - route.sample(s - h).pose) / (2 * h)
    np.testing.assert_allclose(smp.rate, fd, atol=1e-6)
    np.testing.assert_allclose(
        np.arctan2(smp.rate[:, 1], smp.rate[:, 0]), np.angle(np.exp(1j * smp.pose[:, 2])), atol=1e-9
    )
    np.testing.assert_allclose(np.hypot(smp.rate[:, 0], smp.rate[:, 1]), 1.0)  # unit speed in s
    # continuous across piece boundaries, curvature bounded by 1 / turn_radius
    b = route.starts[1:-1]
    np.testing.assert_allclose(route.sample(b - 1e-9).pose, route.sample(b + 1e-9).pose, atol=1e-8)
    dense = route.sample(np.linspace(0, route.length, 5000))
    assert np.abs(dense.curvature).max() == pytest.approx(1 / 0.4)


def test_rigid_motion_of_the_waypoints(rng):
    route, xy = _random_route(rng)
    a, t = 0.7, np.array([3.0, -2.0])
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    moved = route_from_waypoints(xy @ R.T + t, turn_radius=0.4)
    s = np.linspace(0, route.length, 50)
    p, q = route.sample(s).pose, moved.sample(s).pose
    np.testing.assert_allclose(q[:, :2], p[:, :2] @ R.T + t, atol=1e-9)
    np.testing.assert_allclose(np.angle(np.exp(1j * (q[:, 2] - p[:, 2] - a))), 0.0, atol=1e-9)


@pytest.mark.parametrize(
    ("waypoints", "field"),
    [
        ([[0, 0]], "waypoints"),
        ([[0, 0], [1, 0], [1, 0], [2, 0]], "waypoints[2]"),
        ([[0, 0], [2, 0], [0, 0]], "waypoints[1]"),
        ([[0, 0], [2, 0], [2, 0.3], [4, 0.3]], "waypoints[1]"),
    ],
)
def test_bad_waypoints_name_the_point(waypoints, field):
    with pytest.raises(RouteError) as info:
        route_from_waypoints(waypoints, turn_radius=0.5)
    assert info.value.field == field


def test_speed_profile_on_a_line_by_hand():
    route = route_from_waypoints([[0, 0], [4, 0]], turn_radius=0.5)
    prof = speed_profile(route, LIMITS, ds=0.001)
    v, a, length = LIMITS.speed, LIMITS.acceleration, 4.0
    # accelerate to v over v^2 / 2a, cruise, brake: t = 2 v / a + (L - v^2 / a) / v
    assert prof.duration == pytest.approx(2 * v / a + (length - v**2 / a) / v, rel=1e-6)
    assert prof.v[0] == 0 and prof.v[-1] == 0 and prof.v.max() == pytest.approx(v)
    np.testing.assert_allclose(prof.s_at(prof.t), prof.s, atol=1e-9)


def test_speed_profile_respects_the_tracks_in_turns(rng):
    route, _ = _random_route(rng)
    fast = LIMITS._replace(speed=0.9, lateral_acceleration=10.0)  # the tracks decide
    prof = speed_profile(route, fast)
    kappa = np.abs(route.sample(prof.s).curvature)
    outer = prof.v * (1 + kappa * fast.track_separation / 2)
    assert outer.max() <= fast.headroom * fast.track_speed + 1e-12
    assert prof.v[kappa > 0].max() < fast.speed  # it slows down in the arcs
    assert np.all(np.abs(np.diff(prof.v**2) / (2 * np.diff(prof.s))) <= fast.acceleration + 1e-9)
    with pytest.raises(ValueError, match="above the tracks"):
        speed_profile(route, LIMITS._replace(speed=1.0))


def test_csv_routes_and_section_errors(tmp_path):
    f = tmp_path / "route.csv"
    f.write_text("x,y,yaw\n0,0,0\n3,0,0\n3,3,1.57\n")
    wp = read_waypoints_csv(f)
    np.testing.assert_allclose(wp.xy, [[0, 0], [3, 0], [3, 3]])
    prob = tmp_path / "p.yaml"
    planned = route_from_section(prob, {"file": "route.csv", "turn_radius": 0.5}, LIMITS)
    assert planned.route.length == pytest.approx(2.5 + np.pi / 4 + 2.5)
    f.write_text("x,y,yaw\n0,0,3.14\n3,0,3.14\n")  # listed backwards
    with pytest.raises(ConfigError, match="waypoint 0: its yaw points against"):
        route_from_section(prob, {"file": "route.csv", "turn_radius": 0.5}, LIMITS)
    f.write_text("0,0\n1,zero\n")
    with pytest.raises(ConfigError, match=r"route.csv: line 2: expected numbers"):
        read_waypoints_csv(f)
    # a corner whose arc does not fit is a pivot turn now (tests/paths/test_pivot.py), both here:
    # the 0.3 m leg holds neither 0.5 m tangent (R tan 45 deg)
    jog = route_from_section(
        prob, {"waypoints": [[0, 0], [2, 0], [2, 0.3], [4, 0.3]], "turn_radius": 0.5}, LIMITS
    )
    assert jog.route.length == pytest.approx(4.3 + 2 * 0.21 * np.pi / 2)
    assert [c.pivot for c in jog.route.corners] == [True, True]
    with pytest.raises(ConfigError, match=r"p.yaml: path.speed"):
        route_from_section(
            prob, {"waypoints": [[0, 0], [2, 0]], "turn_radius": 0.5}, LIMITS._replace(speed=2.0)
        )
    with pytest.raises(ConfigError, match="no route file"):
        route_from_section(prob, {"file": "missing.csv", "turn_radius": 0.5}, LIMITS)
