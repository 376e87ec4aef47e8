"""Routes as problems: the ``path:`` section, bad routes, the planner and tracking along them.

Small settings throughout: a coarse workspace grid, a short route, a few planned poses.
"""

from __future__ import annotations

import copy
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import ROOT, assert_committed_has_the_keys

from mmstab.core.files import ConfigError
from mmstab.core.problem import load_problem, problem_from_dict
from mmstab.planner import (
    PlannerSettings,
    plan_route,
    planning_region,
    region_samples,
    route_risk,
    solve_exhaustive,
    stretches,
)
from mmstab.planner.fitness import pose_fitness
from mmstab.runs.arm_ground import arm_heights_at_rest
from mmstab.stability.static import mu_max

ROUGH = ROOT / "problems" / "rough.yaml"
COARSE = [10, 8, 8, 8]


def rough_data(**path: object) -> dict:
    """rough.yaml with a coarse workspace and the given ``path:`` keys replaced."""
    data = yaml.safe_load(ROUGH.read_text())
    data["robot"] = str(ROOT / "problems" / "robots" / "cameleon.yaml")
    data["workspace"]["grid"] = COARSE
    data["path"].update(path)
    return data


def write(tmp_path: Path, data: dict, name: str = "p.yaml") -> Path:
    p = tmp_path / name
    p.write_text(yaml.safe_dump(data))
    return p


@pytest.fixture(scope="module")
def rough_small(tmp_path_factory):
    """rough.yaml, coarse V, poses 2 m apart; with its workspace."""
    from mmstab.workspace import load_or_build_workspace

    tmp = tmp_path_factory.mktemp("routes")
    data = rough_data()
    data["planner"]["spacing"] = 2.0
    data["planner"]["method"] = "cmaes"  # the warm-started per-pose search (sequence: below)
    problem = problem_from_dict(data, tmp / "rough.yaml")
    ws = load_or_build_workspace(problem, progress=False, cache_dir=tmp / "cache")
    return problem, ws


# ------------------------------------------------------------------------- path section
def test_route_and_circle_paths_load(tmp_path):
    problem = problem_from_dict(rough_data(), tmp_path / "p.yaml")
    assert problem.route is not None and problem.route.length > 15.0
    with pytest.raises(Exception, match="this command works on a circle"):
        _ = problem.circle
    ramp = load_problem(ROOT / "problems" / "ramp.yaml")
    assert ramp.route is None and ramp.circle.radius == 1.5
    bad = copy.deepcopy(ramp.data)
    bad["robot"] = str(ROOT / "problems" / "robots" / "cameleon.yaml")
    bad["path"]["radius"] = -1.0  # a circle is still checked as before
    with pytest.raises(ConfigError, match=r"p.yaml: path.radius"):
        problem_from_dict(bad, tmp_path / "p.yaml")
    # the time parametrisation: from rest to rest, d pose/du is the finite difference
    r = problem.route
    u = np.linspace(0.05, 0.75, 50)
    h = 1e-6
    fd = (r.pose_at(u + h) - r.pose_at(u - h)) / (2 * h)
    np.testing.assert_allclose(r.pose_rate(u).rate, fd, atol=2e-4 * r.lap_time)
    assert r.pose_rate(np.array([0.0, 0.99])).rate == pytest.approx(np.zeros((2, 3)))


def test_track_announces_the_time_the_route_run_simulates(tmp_path, capsys, monkeypatch):
    """A route's run lasts its driving time (tracking.simulate); the estimate shown is for it."""
    import mmstab.outputs.tracking as tracking
    from mmstab.cli import main
    from mmstab.core import sizes
    from mmstab.core.files import MmstabError

    problem = load_problem(ROUGH)
    route, ctrl = problem.route, problem.section("controller")
    dt = ctrl["dt"]
    assert abs(route.duration - ctrl["duration"]) > 10.0  # the YAML's duration is not it
    steps = f"{route.duration / dt:.6g} control periods ({route.duration:g} s at dt = {dt:g} s)"

    def stop(*args: object, **kwargs: object) -> None:
        raise MmstabError("stopped before tracking")

    monkeypatch.setattr(sizes, "ANNOUNCE_SECONDS", 0.0)  # show every estimate
    monkeypatch.setattr(tracking, "run_tracking", stop)
    assert main(["track", str(ROUGH), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert f"mmstab: path: {steps}, about" in err and "controller.duration" not in err
    assert main(["track", str(ROUGH), "--duration", "2", "-o", str(tmp_path / "out")]) == 2
    assert f"mmstab: --duration: {2.0 / dt:.6g} control periods" in capsys.readouterr().err
    found = problem.size_estimates()  # what the command announced, and the animation's
    assert found["controller"] == sizes.steps_estimate("path", route.duration, dt)
    assert found["animation"] == sizes.animation_estimate(
        problem.section("animation"), route.duration / dt + 1
    )
    # the planner's is for the poses the route plans (every planner.spacing)
    spacing = problem.section("planner")["spacing"]
    planned = int(np.ceil(route.length / spacing - 1e-9)) + 1
    assert problem.route.planned_poses(spacing) == planned != problem.section("planner")["poses"]
    assert found["planner"] == sizes.planner_estimate(problem.section("planner"), planned)
    assert f"poses {planned} x" in found["planner"].work


def test_a_route_too_long_to_track_is_refused_naming_the_path(tmp_path, monkeypatch):
    """The size bound holds for the route's driving time, not the YAML's duration."""
    from mmstab.core import sizes

    monkeypatch.setattr(sizes, "available_memory", lambda: 16e9)
    with pytest.raises(ConfigError, match=r"p.yaml: path: .* control periods .* memory"):
        problem_from_dict(rough_data(speed=1e-5), tmp_path / "p.yaml")  # ~20 days of driving


@pytest.mark.parametrize(
    ("path", "field", "message"),
    [
        ({"waypoints": [[0.0, 0.0]]}, "path.waypoints", "at least two"),
        ({"waypoints": [[-2, 0], [0, 0], [0, 0], [2, 0]]}, r"path.waypoints\[2\]", "repeats"),
        ({"waypoints": [[-2, 0], [12, 0]]}, r"path.waypoints\[0\]", "off the map"),
        ({"turn_radius": 0.1}, "path.turn_radius", "inner track"),
        ({"speed": 5.0}, "path.speed", "above the tracks"),
        ({"speed": -1.0}, "path.speed", ""),
        ({"file": "none.csv"}, "path", ""),
    ],
)
def test_bad_routes_name_the_file_and_field(tmp_path, path, field, message):
    data = rough_data(**path)  # with "file": both a file and waypoints, which is refused
    with pytest.raises(ConfigError, match=rf"p.yaml: {field}.*{message}"):
        problem_from_dict(data, tmp_path / "p.yaml")


def test_unknown_cells_and_csv_routes(tmp_path):
    """A route over NaN cells of a heightmap file names the CSV line's waypoint."""
    from mmstab.terrain.generators import Grid, plane

    hm = plane(Grid.of_size((6.0, 4.0), 0.1), 0.2, 0.0)
    e = hm.elevation.copy()
    e[15:25, 38:42] = np.nan  # a hole around x = 0.8 m, y = 0 m
    np.savez(tmp_path / "map.npz", elevation=e, resolution=0.1, origin=hm.origin)
    data = rough_data()
    data["terrain"] = {"file": "map.npz"}
    del data["path"]["waypoints"]
    data["path"]["file"] = "route.csv"
    (tmp_path / "route.csv").write_text("x,y\n-2,0\n0,0.1\n2,0\n")
    with pytest.raises(ConfigError, match=r"route.csv: waypoint 1: .*unknown \(NaN\) cell"):
        problem_from_dict(data, tmp_path / "p.yaml")
    (tmp_path / "route.csv").write_text("x,y\n-2,-1.2\n2,-1.2\n")  # beside the hole
    assert problem_from_dict(data, tmp_path / "p.yaml").route.length == pytest.approx(4.0)


def test_stretches_by_hand():
    s = np.arange(6) * 0.5
    mu = np.array([5.0, 1.0, 2.0, 9.0, 0.5, 7.0])
    got = stretches(mu < 3, s, mu)
    assert [tuple(x) for x in got] == [(0.5, 1.0, 1.0), (2.0, 2.0, 0.5)]
    assert stretches(np.zeros(3, bool), s[:3], mu[:3]) == []


# ------------------------------------------------------------------------------ planner
def test_plan_along_the_rough_route(rough_small):
    problem, ws = rough_small
    plan = plan_route(problem, ws)
    assert len(plan.s) >= 9 and plan.s[-1] == pytest.approx(problem.route.length)
    # the claim: the planned posture is never less stable than the stowed arm
    assert np.all(plan.mu_planned >= plan.mu_stowed)
    assert plan.collision_free.all() and np.nanmax(plan.realised_com_error) < 1e-3
    # within 0.5 % of the exhaustive reference's Eq. 6 at every pose (same previous CoM)
    region = planning_region(ws, problem.section("workspace")["method"])
    samples = region_samples(region)
    gravity = problem.terrain.gravity_body(plan.poses)
    previous = problem.robot.arm_com(problem.robot.stowed)
    for k, t in enumerate(plan.targets):
        fit = pose_fitness(
            problem.robot, gravity[k], previous, plan.settings, mu_max(problem.robot), ws.diameter
        )
        best = solve_exhaustive(fit, samples).best_fitness
        assert fit(t.target_com)[0] >= best - 0.005 * abs(best), k
        previous = t.target_com
    # the risk stretches against the problem's margin are those of the μ lists
    risk = route_risk(plan, 250.0)
    for r in risk.saved_by_planning:
        inside = (plan.s >= r.start_s) & (plan.s <= r.end_s)
        assert np.all(plan.mu_stowed[inside] <= 250.0) and np.all(plan.mu_planned[inside] > 250)


def test_a_plane_heightmap_gives_the_ramps_answer(tmp_path, rough_small):
    """A straight route across a plane heightmap plans as the same route on the ramp."""
    _, ws = rough_small
    slope = 0.3
    data = rough_data(waypoints=[[-2.0, 0.0], [2.0, 0.0]])
    data["planner"]["spacing"] = 1.0
    data["terrain"] = {
        "generate": {
            "kind": "plane",
            "seed": 0,
            "size": [8.0, 6.0],
            "resolution": 0.1,
            "slope": slope,
            "azimuth": float(np.pi / 2),  # uphill +y_G, as the ramp's +y_S
        }
    }
    plane = problem_from_dict(data, tmp_path / "plane.yaml")
    ramp_data = copy.deepcopy(data)
    ramp_data["terrain"] = {"slope": slope}
    ramp = problem_from_dict(ramp_data, tmp_path / "ramp.yaml")
    a, b = plan_route(plane, ws), plan_route(ramp, ws)
    np.testing.assert_allclose(a.mu_stowed, b.mu_stowed, rtol=1e-6)
    np.testing.assert_allclose(a.mu_removed, b.mu_removed, rtol=1e-6)
    np.testing.assert_allclose(a.mu_planned, b.mu_planned, rtol=1e-3)


# ------------------------------------------------------------------------- the CLI
def _cli(args: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.run(
        [sys.executable, "-m", "mmstab", *args], cwd=cwd, env=env, capture_output=True, text=True
    )


@pytest.mark.slow
def test_plan_and_track_a_terrain_route_from_the_cli(tmp_path):
    data = rough_data(waypoints=[[-3.0, -0.6], [-1.5, -0.6]], speed=0.25)
    data["planner"]["spacing"] = 0.5
    data["controller"]["dt"] = 0.005
    data["terrain"]["friction"] = 1.0  # at 0.7 the tracks slide on this 38 deg stretch (exit 4)
    problem = write(tmp_path, data, "route.yaml")
    out = _cli(["plan", str(problem), "-o", "plan"], tmp_path)
    # rough.yaml's margin 250: between two poses the loaded support's μ falls to ~63 N rad
    # (a few road wheels carry the downhill side): the plan names the stretch, exit 3
    assert out.returncode == 3, out.stderr[-2000:]
    assert "along the path (every 5 cm" in out.stderr and "s = 0.30-0.45 m" in out.stderr
    data["planner"]["margin"] = 0.0
    problem = write(tmp_path, data, "route.yaml")
    out = _cli(["plan", str(problem), "-o", "plan"], tmp_path)
    assert out.returncode == 0, out.stderr[-2000:]
    s = json.loads((tmp_path / "plan" / "summary.json").read_text())
    for key in ("mu_planned", "mu_stowed", "mu_removed", "risk", "ms_per_pose"):
        assert key in s
    assert len(s["mu_planned"]) == len(s["s"]) == 4
    assert all(p >= q for p, q in zip(s["mu_planned"], s["mu_stowed"], strict=True))
    assert (tmp_path / "plan" / "route_mu.png").stat().st_size > 10_000
    assert_committed_has_the_keys(s, "results/rough/plan/summary.json")
    out = _cli(["track", str(problem), "-o", "track"], tmp_path)
    assert out.returncode == 0, out.stderr[-2000:]
    t = json.loads((tmp_path / "track" / "summary.json").read_text())
    wait = t["approach"]["base_wait_s"]  # the base's wait at the start for the arm, if any
    assert t["duration_s"] == pytest.approx(load_problem(problem).route.duration + wait, abs=0.01)
    # the bounds of docs/routes.md ("Bounds"): no QP failure; after the 1 s start-up
    # the base point within 2 mm and the arm CoM within 2 cm (the resting pose rocks over
    # the rough ground by up to ~0.1 rad between control periods: the CoM target in M jumps)
    assert t["qp_failures"] == 0
    assert t["after_transient"]["base_error_max_m"] < 2e-3
    assert t["after_transient"]["arm_com_error_max_m"] < 2e-2
    assert t["mu_min"]["reconfigured"] > 0
    assert all(t["qdot_max_abs"][j] <= t["qdot_limit"][j] + 1e-9 for j in t["qdot_limit"])
    # the tracked arm against the ground at the tracked rests, every 0.05 s: at run.npz's
    # 0.01 s samples, measured again, its least height is no higher and within 5 mm
    g = t["arm_in_ground"]
    assert not g["contact"] and g["unknown_samples"] == 0 and g["samples"] > 100
    run, p = np.load(tmp_path / "track" / "run.npz"), load_problem(problem)
    h = arm_heights_at_rest(p.robot, p.terrain, run["state"][:, :3], run["state"][:, 5:])
    assert h.min() <= g["height_min_m"] + 1e-12 and g["height_min_m"] - h.min() < 0.005
    assert_committed_has_the_keys(t, "results/rough/summary.json")


def test_a_bad_route_exits_2_with_one_line_and_writes_nothing(tmp_path):
    problem = write(tmp_path, rough_data(waypoints=[[0.0, 0.0], [0.0, 0.0]]), "bad.yaml")
    out = _cli(["plan", str(problem), "-o", "plan"], tmp_path)
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "bad.yaml: path.waypoints[1]" in lines[0], out.stderr
    assert not (tmp_path / "plan").exists()


class _Ball:
    """A ball of radius 1 m at the origin as a CoM region (contains, violation, diameter)."""

    diameter = 2.0

    def contains(self, points):
        return np.linalg.norm(np.atleast_2d(points), axis=1) <= 1.0

    def violation(self, points):
        return np.maximum(np.linalg.norm(np.atleast_2d(points), axis=1) - 1.0, 0.0)


@pytest.mark.parametrize("target", [[0.3, -0.2, 0.1], [2.0, 0.0, 0.0]])
def test_warm_cma_finds_a_known_optimum(target):
    """Inside: the peak itself; outside V: the nearest point of the ball (the constrained one)."""
    from mmstab.planner.searches.cmaes import warm_cma

    c = np.array(target)

    def fitness(x):
        return -np.sum((np.atleast_2d(x) - c) ** 2, axis=1)

    rng = np.random.default_rng(0)
    r = warm_cma(fitness, _Ball(), np.zeros(3), 0.1, rng, 16, 200, 3, 1e-6, 1e-14)
    expected = c if np.linalg.norm(c) <= 1 else c / np.linalg.norm(c)
    np.testing.assert_allclose(r.best_com, expected, atol=2e-3)
    assert np.linalg.norm(r.best_com) <= 1.0 and r.iterations < 200
    # the start is kept: started at the optimum with a tiny budget, it is never lost
    r0 = warm_cma(fitness, _Ball(), expected, 0.1, rng, 16, 1, 3, 1e-6, 1e-14)
    assert r0.best_fitness >= float(fitness(expected)[0])


def test_sequence_along_the_rough_route(rough_small):
    """method sequence on rough.yaml (its search before method roadmap): collision-free
    moves, never below stowed."""
    from mmstab.model.collision import CollisionChecker
    from mmstab.planner.searches.sequence import segments_collide

    problem, ws = rough_small
    s = PlannerSettings.from_section(yaml.safe_load(ROUGH.read_text())["planner"])
    assert s.method == "roadmap" and s.turret_window is not None
    problem = problem_from_dict(
        {**problem.data, "planner": {**problem.data["planner"], "method": "sequence"}},
        problem.path,
    )
    plan = plan_route(problem, ws)
    assert np.all(plan.mu_planned >= plan.mu_stowed)
    assert plan.collision_free.all() and np.nanmax(plan.realised_com_error) < 1e-12
    q = plan.postures
    checker = CollisionChecker(problem.robot)
    assert not np.asarray(checker.collides(q)).any()
    assert not segments_collide(checker, q[:-1], q[1:]).any()
    assert np.all(np.abs(np.diff(q[:, 0])) <= s.turret_window + 1e-9)
