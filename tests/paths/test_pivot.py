"""Pivot turns on routes: geometry by hand, time along a pivot, random routes, the CLI.

A corner whose arc does not fit between its neighbours, and every corner with
``turn_radius: 0``, is a turn on the spot; the route's parameter runs the distance the
tracks run there, ``b/2 · |turn|`` (docs/routes.md, "Pivot turns").
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import ROOT

from mmstab.core.files import ConfigError
from mmstab.core.problem import problem_from_dict
from mmstab.paths import Arc, Line, Pivot, SpeedLimits, route_from_waypoints, speed_profile
from mmstab.paths.route import RoutePath

#: Half the track separation of the limits below [m].
R_PIVOT = 0.21
LIMITS = SpeedLimits(
    speed=0.5,
    acceleration=0.5,
    lateral_acceleration=0.5,
    track_speed=1.13,
    track_separation=2 * R_PIVOT,
)
SQUARE = [[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0], [0.0, 0.5]]


def route_path(waypoints, turn_radius: float) -> RoutePath:
    route = route_from_waypoints(waypoints, turn_radius, pivot_radius=R_PIVOT)
    return RoutePath(route=route, profile=speed_profile(route, LIMITS))


# ------------------------------------------------------------------------- geometry by hand
def test_square_with_turn_radius_zero_by_hand():
    route = route_from_waypoints(SQUARE, 0.0, pivot_radius=R_PIVOT)
    assert [type(p) for p in route.pieces] == [Line, Pivot] * 3 + [Line]
    quarter = R_PIVOT * np.pi / 2  # each track runs b/2 · 90 deg
    assert route.length == pytest.approx(2 + 2 + 2 + 1.5 + 3 * quarter, rel=1e-12)
    np.testing.assert_allclose(route.pivot_spans[:, 0], [2, 4 + quarter, 6 + 2 * quarter])
    # half-way through the second pivot: at (2, 2), yaw between pi/2 and pi
    mid = route.sample(4 + 1.5 * quarter)
    np.testing.assert_allclose(mid.pose[0], [2.0, 2.0, 3 * np.pi / 4], atol=1e-12)
    np.testing.assert_allclose(mid.rate[0], [0.0, 0.0, 1 / R_PIVOT])
    assert mid.pivot[0] and not route.sample(1.0).pivot[0]
    # fixed position, yaw linear in s through the whole pivot
    s = np.linspace(2.0, 2.0 + quarter, 11)
    smp = route.sample(s)
    np.testing.assert_allclose(smp.pose[:, :2], np.tile([2.0, 0.0], (11, 1)), atol=1e-12)
    np.testing.assert_allclose(smp.pose[:, 2], np.linspace(0, np.pi / 2, 11), atol=1e-12)
    np.testing.assert_allclose(route.sample(route.length).pose[0], [0, 0.5, 3 * np.pi / 2])
    assert route.max_curvature == 0.0  # no arcs
    assert route.report() == [
        f"corner {k} at ({x:.2f}, {y:.2f}) m: pivot turn of 90 deg left (turn_radius 0)"
        for k, (x, y) in enumerate(SQUARE[1:4], start=1)
    ]


def test_a_corner_that_fits_keeps_its_arc_and_the_next_pivots():
    # corner 1: a 0.5 m arc (tangent 0.5 m) fits the 3 m legs; corner 2's does not fit the
    # last leg (0.3 m): a pivot, and the route check says the radius that would fit (0.3 m)
    w = [[0.0, 0.0], [3.0, 0.0], [3.0, 3.0], [3.3, 3.0]]
    route = route_from_waypoints(w, 0.5, pivot_radius=R_PIVOT)
    assert [type(p) for p in route.pieces] == [Line, Arc, Line, Pivot, Line]
    arc, pivot = route.pieces[1], route.pieces[3]
    np.testing.assert_allclose(arc.center, [2.5, 0.5], atol=1e-12)
    assert arc.radius == 0.5 and arc.turn == pytest.approx(np.pi / 2)
    np.testing.assert_allclose(pivot.point, [3.0, 3.0])
    assert pivot.turn == pytest.approx(-np.pi / 2)
    length = 2.5 + 0.5 * np.pi / 2 + 2.5 + R_PIVOT * np.pi / 2 + 0.3
    assert route.length == pytest.approx(length, rel=1e-12)
    assert [c.pivot for c in route.corners] == [False, True]
    assert route.report() == [
        "corner 2 at (3.00, 3.00) m: pivot turn of 90 deg right (its 0.5 m arc does not fit "
        "between its neighbours; a radius <= 0.300 m would)"
    ]
    # without a pivot radius the same corner is refused, as before pivots
    with pytest.raises(ValueError, match="needs a radius <= 0.300 m"):
        route_from_waypoints(w, 0.5)


def test_routes_whose_corners_fit_are_unchanged(rng):
    xy = np.cumsum(rng.uniform([2.0, -2.0], [3.0, 2.0], (6, 2)), axis=0)
    old = route_from_waypoints(xy, turn_radius=0.4)
    new = route_from_waypoints(xy, turn_radius=0.4, pivot_radius=R_PIVOT)
    assert not any(c.pivot for c in new.corners) and new.report() == []
    assert len(old.pieces) == len(new.pieces)
    for a, b in zip(old.pieces, new.pieces, strict=True):
        assert type(a) is type(b)
        assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    s = np.linspace(0, old.length, 300)
    assert np.array_equal(old.sample(s).pose, new.sample(s).pose)
    p, q = speed_profile(old, LIMITS), speed_profile(new, LIMITS)
    assert all(np.array_equal(x, y) for x, y in zip(p, q, strict=True))


# ------------------------------------------------------------------------- time along it
def test_a_pivot_from_rest_to_rest_by_hand():
    """One 90 deg pivot: the tracks run R·pi/2 = 0.33 m, from rest to rest at acceleration a.

    0.33 m < v^2 / a = 0.5 m: the tracks never reach ``speed``; they accelerate half-way
    and brake: t = 2 sqrt(L / a), the peak track speed sqrt(a L), yaw rate that / R.
    """
    path = route_path(SQUARE[:3], 0.0)
    prof = path.profile
    (s0, s1), *_ = path.route.pivot_spans
    length, a = s1 - s0, LIMITS.acceleration
    t0, t1 = np.interp([s0, s1], prof.s, prof.t)
    assert t1 - t0 == pytest.approx(2 * np.sqrt(length / a), rel=1e-3)
    assert np.interp([s0, s1], prof.s, prof.v) == pytest.approx([0.0, 0.0], abs=1e-12)
    inside = (prof.s > s0) & (prof.s < s1)
    assert prof.v[inside].max() == pytest.approx(np.sqrt(a * length), rel=1e-3)
    # d pose / du: no translation, yaw rate = track speed / R, never above speed / R
    u = np.linspace(t0, t1, 50)[1:-1] / path.lap_time
    rate = path.pose_rate(u).rate / path.lap_time  # d pose / dt
    np.testing.assert_allclose(rate[:, :2], 0.0, atol=1e-15)
    np.testing.assert_allclose(rate[:, 2], path.speed_at_t(u * path.lap_time) / R_PIVOT)
    assert rate[:, 2].max() <= LIMITS.speed / R_PIVOT


def test_a_long_pivot_turns_at_speed_over_r():
    """A 150 deg pivot (0.55 m of track > v^2 / a): it cruises at yaw rate speed / R."""
    turn = np.radians(150)
    path = route_path([[0, 0], [2, 0], [2 + 2 * np.cos(turn), 2 * np.sin(turn)]], 0.0)
    (s0, s1), *_ = path.route.pivot_spans
    v, a, length = LIMITS.speed, LIMITS.acceleration, R_PIVOT * turn
    t0, t1 = np.interp([s0, s1], path.profile.s, path.profile.t)
    assert t1 - t0 == pytest.approx(2 * v / a + (length - v**2 / a) / v, rel=1e-3)
    u = np.linspace(t0, t1, 400) / path.lap_time
    yaw_rate = path.pose_rate(u).rate[:, 2] / path.lap_time
    assert yaw_rate.max() == pytest.approx(v / R_PIVOT, rel=1e-9)


def test_pose_rate_is_the_derivative_of_pose_at(rng):
    path = route_path(SQUARE, 0.0)
    u = rng.uniform(0.01, 0.79, 300)  # the run; the hold after it is at rest
    h = 1e-7
    fd = (path.pose_at(u + h) - path.pose_at(u - h)) / (2 * h)
    np.testing.assert_allclose(path.pose_rate(u).rate, fd, atol=2e-4 * path.lap_time)


# ------------------------------------------------------------------------- random routes
def random_route(rng: np.random.Generator, n: int = 7) -> np.ndarray:
    """Waypoints with turns up to 120 deg either way and legs 0.3 to 3 m."""
    yaw = np.cumsum(np.r_[rng.uniform(-np.pi, np.pi), rng.uniform(-1, 1, n - 2) * 2 * np.pi / 3])
    legs = rng.uniform(0.3, 3.0, n - 1)
    steps = legs[:, None] * np.column_stack([np.cos(yaw), np.sin(yaw)])
    return np.vstack([[0.0, 0.0], np.cumsum(steps, axis=0)])


@pytest.mark.parametrize("seed", range(6))
def test_random_routes_are_continuous_and_turn_at_bounded_rates(seed):
    rng = np.random.default_rng(seed)
    w, turn_radius = random_route(rng), 0.8  # too wide for some corners
    path = route_path(w, turn_radius)
    route = path.route
    # position and yaw continuous across every piece boundary
    b = route.starts[1:-1]
    np.testing.assert_allclose(
        route.sample(b - 1e-10).pose, route.sample(b + 1e-10).pose, atol=1e-8
    )
    # a pivot stands on its waypoint and ends on the next leg's direction; the rest of the
    # route runs along its yaw
    for c in route.corners:
        if c.pivot:
            k = c.waypoint
            assert any(isinstance(p, Pivot) and np.array_equal(p.point, w[k]) for p in route.pieces)
            assert 0 < c.radius_fit < turn_radius
    s = np.linspace(0, route.length, 4000)
    smp = route.sample(s)
    drive = ~smp.pivot
    np.testing.assert_allclose(np.hypot(*smp.rate[drive, :2].T), 1.0)
    np.testing.assert_allclose(
        np.angle(
            np.exp(1j * (np.arctan2(smp.rate[drive, 1], smp.rate[drive, 0]) - smp.pose[drive, 2]))
        ),
        0.0,
        atol=1e-9,
    )
    np.testing.assert_allclose(smp.rate[smp.pivot, :2], 0.0)
    end_yaw = np.arctan2(*(w[-1] - w[-2])[::-1])
    assert np.angle(np.exp(1j * (route.sample(route.length).pose[0, 2] - end_yaw))) == (
        pytest.approx(0.0, abs=1e-9)
    )
    # the heading rate: at most speed / R in a pivot, v / turn_radius on an arc
    u = np.linspace(0, 1, 5000)
    yaw_rate = np.abs(path.pose_rate(u).rate[:, 2]) / path.lap_time
    assert yaw_rate.max() <= LIMITS.speed / R_PIVOT + 1e-9
    # the tracks within the headroom everywhere: v (1 + |kappa| b / 2) on lines and arcs,
    # v (each track, opposite ways) in a pivot
    prof = path.profile
    at = route.sample(prof.s)
    kappa = np.where(at.pivot, 0.0, np.abs(at.curvature))
    assert np.max(prof.v * (1 + kappa * R_PIVOT)) <= LIMITS.headroom * LIMITS.track_speed + 1e-12
    assert np.all(np.abs(np.diff(prof.v**2) / (2 * np.diff(prof.s))) <= LIMITS.acceleration + 1e-9)
    # at rest on both ends of each pivot
    for s0, s1 in route.pivot_spans:
        np.testing.assert_allclose(np.interp([s0, s1], prof.s, prof.v), 0.0, atol=1e-12)


def test_random_routes_mix_arcs_and_pivots():
    kinds = set()
    for seed in range(6):
        route = route_path(random_route(np.random.default_rng(seed)), 0.8).route
        kinds |= {type(p) for p in route.pieces}
    assert kinds == {Line, Arc, Pivot}


# ------------------------------------------------------------------------- problems, CLI
def small_problem(**path: object) -> dict:
    """A short route on gently rough, level ground; coarse V; the given path keys."""
    data = yaml.safe_load((ROOT / "problems" / "rough.yaml").read_text())
    data["robot"] = str(ROOT / "problems" / "robots" / "cameleon.yaml")
    data["workspace"]["grid"] = [10, 8, 8, 8]
    data["terrain"]["generate"].update(size=[6.0, 4.0], slope=0.0, amplitude=0.01, features={})
    data["path"].update(
        waypoints=[[-1.2, -0.3], [-0.2, -0.3], [-0.2, 0.5]], turn_radius=0.0, speed=0.25
    )
    data["path"].update(path)
    data["planner"]["spacing"] = 0.3
    data["controller"]["dt"] = 0.005
    return data


def test_turn_radius_zero_loads_and_too_small_a_radius_is_still_refused(tmp_path):
    problem = problem_from_dict(small_problem(), tmp_path / "p.yaml")
    assert problem.route is not None
    b = problem.robot.base.tracks.separation
    (pivot,) = [p for p in problem.route.route.pieces if isinstance(p, Pivot)]
    assert pivot.radius == pytest.approx(b / 2) and pivot.turn == pytest.approx(np.pi / 2)
    assert problem.route.length == pytest.approx(1.0 + 0.8 + b / 2 * np.pi / 2)
    with pytest.raises(ConfigError, match="path.turn_radius: .*inner track.*turn_radius 0"):
        problem_from_dict(small_problem(turn_radius=b / 4), tmp_path / "p.yaml")
    with pytest.raises(ConfigError, match="path.turn_radius"):
        problem_from_dict(small_problem(turn_radius=-1.0), tmp_path / "p.yaml")


def test_the_footprint_check_sweeps_the_pivot(tmp_path):
    """Near the map's edge (x = 3 m) the turning base leaves the map where driving does not.

    The footprint (``footprint_body`` of cameleon.yaml) reaches 0.587 m ahead of the body
    origin and 0.671 m at its corners: driving to x = 2.35 m the front stays at 2.94 m,
    pivoting there a corner sweeps past 3 m; the error names the pivot's waypoint.
    """
    straight = small_problem(waypoints=[[-1.5, 0.0], [2.35, 0.0]])
    assert problem_from_dict(straight, tmp_path / "p.yaml").route is not None
    turning = small_problem(waypoints=[[-1.5, 0.0], [2.35, 0.0], [2.35, 1.2]])
    with pytest.raises(ConfigError, match=r"path.waypoints\[1\]: the route pivoting here leaves"):
        problem_from_dict(turning, tmp_path / "p.yaml")
    inward = small_problem(waypoints=[[-1.5, 0.0], [2.2, 0.0], [2.2, 1.2]])  # 2.2 + 0.671 < 3
    assert problem_from_dict(inward, tmp_path / "p.yaml").route is not None


def _cli(args: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.run(
        [sys.executable, "-m", "mmstab", *args], cwd=cwd, env=env, capture_output=True, text=True
    )


@pytest.mark.slow
def test_plan_and_track_a_route_with_a_pivot_from_the_cli(tmp_path):
    problem = tmp_path / "pivot.yaml"
    problem.write_text(yaml.safe_dump(small_problem()))
    said = "route: corner 1 at (-0.20, -0.30) m: pivot turn of 90 deg left (turn_radius 0)"
    # the pivot on this level, rough ground: no slide (the CoM barely moves in a pivot)
    out = _cli(["plan", str(problem), "-o", "plan"], tmp_path)
    assert out.returncode == 0, out.stderr[-2000:]
    assert said in out.stdout.splitlines()
    s = json.loads((tmp_path / "plan" / "summary.json").read_text())
    assert [c["kind"] for c in s["route"]["corners"]] == ["pivot"]
    assert s["route"]["pivots"] == [said.removeprefix("route: ")]
    assert s["slip"]["turns"]["sliding_turns"] == []
    assert 0.01 < s["slip"]["turns"]["slide_rate_max_m_s"] < 0.05  # 3.0 cm/s: the 1 cm bumps
    out = _cli(["track", str(problem), "-o", "track"], tmp_path)
    assert out.returncode == 0, out.stderr[-2000:]
    assert said in out.stdout.splitlines()
    t = json.loads((tmp_path / "track" / "summary.json").read_text())
    assert t["qp_failures"] == 0 and t["pivots"] == s["route"]["pivots"]
    assert t["after_transient"]["base_error_max_m"] < 2e-3
    # in the pivot the base stands on the corner and the tracks run opposite ways, on the
    # plan's time law (its pivot slowed where it would slide: mmstab.runs.time_law)
    route = problem_from_dict(small_problem(), problem).route
    run = np.load(tmp_path / "track" / "run.npz")
    (s0, s1), *_ = route.route.pivot_spans
    t0, t1 = np.interp([s0, s1], route.profile.s, route.profile.t)
    slowed = [c for c in s["route"]["time_law"]["corners"] if c["slowed"]]
    if slowed:
        assert slowed[0]["start_s"] == pytest.approx(s0) and slowed[0]["end_t_s"] > t1
        t0, t1 = slowed[0]["start_t_s"], slowed[0]["end_t_s"]
    t0, t1 = np.array([t0, t1]) + t["approach"]["base_wait_s"]  # the wait at the start
    inside = (run["t"] > t0 + 0.2) & (run["t"] < t1 - 0.2)
    assert np.abs(run["state"][inside, :2] - [-0.2, -0.3]).max() < 1e-3
    left, right = run["qdot"][inside, 0], run["qdot"][inside, 1]
    assert np.all(left < 0) and np.all(right > 0)
    assert run["state"][-1, 2] == pytest.approx(np.pi / 2, abs=1e-2)


# ------------------------------------------------------------------------- the pivot centre
def test_a_pivot_about_a_point_ahead_by_hand():
    """90 deg left at (2, 0) about a point c = 0.1 m ahead of B's origin.

    The origin stops c short of the corner (1.9, 0), swings about the corner at radius c
    (at 45 deg: (2 − c cos 45°, −c sin 45°)) and leaves from c behind it on the next leg's
    line, (2, −0.1); the route's length and the pivot's own length are unchanged.
    """
    from mmstab.paths.geometry import shift_pivot_centres

    c, quarter = 0.1, R_PIVOT * np.pi / 2
    old = route_from_waypoints(SQUARE[:3], 0.0, pivot_radius=R_PIVOT)
    route = shift_pivot_centres(old, [c])
    assert route.length == pytest.approx(old.length, abs=1e-12)
    assert [p.length for p in route.pieces] == pytest.approx([1.9, quarter, 2.1], abs=1e-12)
    np.testing.assert_allclose(route.pivot_spans, [[1.9, 1.9 + quarter]], atol=1e-12)
    smp = route.sample([1.9, 1.9 + quarter / 2, 1.9 + quarter, 1.9 + quarter + 2.1])
    h = np.sqrt(0.5) * c
    want = [[1.9, 0, 0], [2 - h, -h, np.pi / 4], [2, -c, np.pi / 2], [2, 2, np.pi / 2]]
    np.testing.assert_allclose(smp.pose, want, atol=1e-12)
    # every pose c behind the corner along its heading: the point c ahead stands on it
    s = np.linspace(1.9, 1.9 + quarter, 21)
    pose = route.sample(s).pose
    ahead = pose[:, :2] + c * np.column_stack([np.cos(pose[:, 2]), np.sin(pose[:, 2])])
    np.testing.assert_allclose(ahead, np.tile([2.0, 0.0], (21, 1)), atol=1e-12)
    # d pose / ds against central differences, through the pivot and across its ends
    s = np.linspace(0.5, route.length - 0.5, 401)
    e = 1e-6
    fd = (route.sample(s + e).pose - route.sample(s - e).pose) / (2 * e)
    np.testing.assert_allclose(route.sample(s).rate, fd, atol=1e-6)
    # continuous: no step in the pose anywhere (the largest step of a fine sampling)
    fine = route.sample(np.linspace(0, route.length, 20001)).pose
    assert np.abs(np.diff(fine, axis=0)).max() < 2 * route.length / 20000 / R_PIVOT


def test_a_centre_behind_the_origin_overshoots_the_corner_and_arcs_are_left_alone():
    from mmstab.paths.geometry import shift_pivot_centres

    route = shift_pivot_centres(
        route_from_waypoints(SQUARE[:3], 0.0, pivot_radius=R_PIVOT), [-0.08]
    )
    start = route.sample(route.pivot_spans[0, 0]).pose[0]
    np.testing.assert_allclose(start, [2.08, 0.0, 0.0], atol=1e-12)
    with pytest.raises(ValueError, match="2 pivot centres for the route's 1 pivots"):
        shift_pivot_centres(route, [0.1, 0.1])
    # a route of arcs only: nothing to move
    arcs = route_from_waypoints(SQUARE, 0.5, pivot_radius=R_PIVOT)
    assert shift_pivot_centres(arcs, []).pieces == arcs.pieces


def test_a_route_path_with_pivot_centres_keeps_its_time_and_moves_its_turn_caps():
    from mmstab.paths.speed import TurnLimit

    plain = route_path(SQUARE, 0.0)
    path = RoutePath(plain.route, plain.profile, LIMITS)
    (s0, s1), *_ = path.route.pivot_spans
    capped = path.with_turn_limits((TurnLimit(s0, s1, 0.5),))
    moved = capped.with_pivot_centres([0.1, 0.05, -0.05])
    assert moved.length == pytest.approx(path.length, abs=1e-12)
    # the legs are long enough to cruise: a leg c shorter and the next c longer take as long
    assert moved.duration == pytest.approx(capped.duration, abs=1e-6)  # the profile's grid
    (m0, m1), *_ = moved.route.pivot_spans
    assert moved.turn_limits == (TurnLimit(m0, m1, 0.5),)
    assert (m0, m1) == pytest.approx((s0 - 0.1, s1 - 0.1), abs=1e-12)
    # the pivot's timing is the capped one's, 0.1 m earlier along the leg
    assert moved.yaw_rate_max(m0, m1) == pytest.approx(capped.yaw_rate_max(s0, s1), rel=1e-9)
    u = np.linspace(0.01, 0.79, 300)
    h = 1e-7
    fd = (moved.pose_at(u + h) - moved.pose_at(u - h)) / (2 * h)
    np.testing.assert_allclose(moved.pose_rate(u).rate, fd, atol=2e-4 * moved.lap_time)
