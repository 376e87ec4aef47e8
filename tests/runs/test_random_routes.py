"""Seeded random routes over seeded random heightmaps: every one plans and tracks.

A generator (:func:`random_pair`, one ``numpy.random.Generator`` per pair) draws a heightmap
(fractal rough ground on a Gaussian bump on a plane tilted 0-20 deg at any azimuth, now and
then a kerb across it) and a route over it (3-5 waypoints, legs 2-4 m, corners up to 90 deg,
at least one pivot turn: ``turn_radius: 0`` on half of the routes, on the others a radius
whose arc does not fit the sharpest corner), written as a problem YAML file. Each pair is
planned on the posture roadmap (``planner.method: roadmap``: collision-free arm moves by
construction) and tracked over its whole route, and must hold:

- a plan exists (no :class:`~mmstab.planner.searches.roadmap.NoPlanError`);
- planned μ >= stowed μ at every planned pose (within :data:`MU_RTOL`);
- the tracking run: 0 QP failures, 0 samples where an arm link touches the robot, and the
  smallest clearance at least the verdict's (:data:`mmstab.runs.verdict.MIN_CLEARANCE`).

The default test run checks :data:`FAST_PAIRS` pairs on a coarse workspace grid. The full
set, :data:`FULL_PAIRS` pairs on the problems' default grid, runs with the environment
variable ``MMSTAB_RANDOM_ROUTES=1`` (``make random-routes``) and writes
``results/random_routes/summary.json`` (per pair: what was drawn, pass/fail, the numbers and
timings); docs/routes.md, "Random routes", has its result.
"""

from __future__ import annotations

import json
import os
import time
import traceback
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from conftest import ROOT

from experiments.random_routes import random_route
from mmstab.control.approach import ArmReferences
from mmstab.core.problem import Problem, load_problem
from mmstab.paths import Pivot
from mmstab.runs.verdict import MIN_CLEARANCE

ROBOT = ROOT / "problems" / "robots" / "cameleon.yaml"
#: Environment variable that runs the full set (any non-empty value but ``0``).
FULL_ENV = "MMSTAB_RANDOM_ROUTES"
#: Pairs of the full set (the issue's 20 routes over 20 maps) and of the default run.
FULL_PAIRS = 20
#: Environment variable of the full set's size (default :data:`FULL_PAIRS`): pairs 0 .. n - 1.
PAIRS_ENV = "MMSTAB_RANDOM_PAIRS"
FAST_PAIRS = (0, 1, 2, 3)
#: Seed of pair k: ``SEED_BASE + k``.
SEED_BASE = 2400
#: Workspace grid of the fast pairs (the full set uses the problems' default grid).
COARSE = [10, 8, 8, 8]
#: Relative tolerance of "planned μ >= stowed μ" [-]: both are the same float computation
#: (one force-angle call per pose) on CoMs that differ, so only rounding of the order of
#: 1e-12 separates a tie; 1e-9 is far above that and far below any real difference.
MU_RTOL = 1e-9
#: Controller period of the runs [s] (coarser than the shipped 2 ms: whole routes).
TRACK_DT = 0.01
#: Side slope of the maps [deg] and the largest corner of the routes [deg].
SLOPE_MAX_DEG = 20.0
TURN_MAX_DEG = 90.0
#: Free ground around the route's waypoints on the map [m] (the footprint reaches 0.67 m).
MAP_MARGIN = 1.5
RESULTS = ROOT / "results" / "random_routes"


def random_terrain(rng: np.random.Generator, size: list[float]) -> dict[str, Any]:
    """A ``terrain.generate`` section: rough ground on a bump on a 0-20 deg plane.

    RMS roughness 0.5-3 cm (correlation 0.3-0.8 m), a Gaussian bump or dip of up to 0.25 m
    (radius 1-2.5 m) at the map's centre, the plane's uphill azimuth anywhere; one map in
    three also has a kerb 3-8 cm high across it.
    """
    generate: dict[str, Any] = {
        "kind": "rough",
        "seed": int(rng.integers(0, 2**31)),
        "size": size,
        "resolution": 0.05,
        "amplitude": float(rng.uniform(0.005, 0.03)),
        "correlation_length": float(rng.uniform(0.3, 0.8)),
        "hill_height": float(rng.uniform(-0.25, 0.25)),
        "hill_radius": float(rng.uniform(1.0, 2.5)),
        "slope": float(np.radians(rng.uniform(0.0, SLOPE_MAX_DEG))),
        "azimuth": float(rng.uniform(-np.pi, np.pi)),
    }
    if rng.uniform() < 1 / 3:
        generate["features"] = {
            "kerb": {
                "height": float(rng.uniform(0.03, 0.08)),
                "distance": float(rng.uniform(-1.0, 1.0)),
                "azimuth": float(rng.uniform(-np.pi, np.pi)),
            }
        }
    return {"generate": generate}


def random_pair(rng: np.random.Generator, pivot_everywhere: bool) -> dict[str, Any]:
    """A whole problem (robot, terrain, path, planner, controller): one route over one map."""
    route = random_route(rng, pivot_everywhere)
    extent = route.waypoints.max(axis=0) - route.waypoints.min(axis=0)
    size = [float(np.ceil(e + 2 * MAP_MARGIN)) for e in extent]
    return {
        "robot": str(ROBOT),
        "terrain": random_terrain(rng, size),
        "path": {
            "waypoints": np.round(route.waypoints, 3).tolist(),
            "speed": route.speed,
            "turn_radius": round(route.turn_radius, 3),
        },
        "planner": {"method": "roadmap", "spacing": 0.5},
        "controller": {"dt": TRACK_DT},
    }


def pair_problem(k: int, directory: Path, grid: list[int] | None = None) -> Path:
    """Pair k's problem file in ``directory`` (seed ``SEED_BASE + k``; even k pivot everywhere)."""
    data = random_pair(np.random.default_rng(SEED_BASE + k), pivot_everywhere=k % 2 == 0)
    if grid is not None:
        data["workspace"] = {"grid": grid}
    path = directory / f"pair{k:02d}.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


# ------------------------------------------------------------------------- one pair checked
def pivots_of(problem: Problem) -> int:
    """Pivot turns on the problem's route."""
    assert problem.route is not None
    return sum(isinstance(p, Pivot) for p in problem.route.route.pieces)


def check_pair(problem: Problem, cache_dir: Path | None = None) -> dict[str, Any]:
    """Plan and track one pair; the numbers the checks need, and timings [s]."""
    from mmstab import app
    from mmstab.model.plane_clearance import arm_ground_clearance
    from mmstab.planner.searches.roadmap import NoPlanError
    from mmstab.runs.tracking.checks import arm_collisions

    record: dict[str, Any] = {"pivots": pivots_of(problem)}
    assert problem.route is not None
    record["route_length_m"] = problem.route.length
    t0 = time.perf_counter()
    ws = app.workspace(problem, progress=False, cache_dir=cache_dir)
    try:
        plan = app.plan(problem, ws=ws)
    except NoPlanError as e:
        return record | {"planned": False, "error": str(e)}
    record["plan_seconds"] = time.perf_counter() - t0
    # the search's own time per pose (the roadmap warm after the first pair; no IK)
    record["plan_ms_per_pose"] = 1e3 * float(np.median(plan.search_seconds))
    # on the search's basis (each pose's support at the stowed arm's rest: the stowed arm
    # scores its reported μ there) the plan is never below the stowed arm
    below = plan.mu_search < plan.mu_stowed - MU_RTOL * np.abs(plan.mu_stowed)
    record |= {
        "planned": True,
        "poses": len(plan.s),
        "mu_planned_min": float(plan.mu_planned.min()),
        "mu_margin_over_stowed_min": float(np.min(plan.mu_search - plan.mu_stowed)),
        # the one μ (each state re-rested under its own arm): better than stowed in the median
        "mu_gain_over_stowed_median": float(np.median(plan.mu_planned - plan.mu_stowed)),
        "poses_below_stowed": np.flatnonzero(below).tolist(),
        # the arm's lowest point above the support plane at the planned postures [m]
        "arm_ground_min_m": float(arm_ground_clearance(problem.robot, plan.postures).min()),
        "arm_ground_moves_min_m": moves_lowest(problem.robot, plan.moves),
        "ground_clearance_m": problem.section("planner")["ground_clearance"],
    }
    t0 = time.perf_counter()
    _, _, run = app.track(problem, plan, progress=False)
    record["track_seconds"] = time.perf_counter() - t0
    collisions = arm_collisions(problem.robot, run.t, run.state[:, 5:])
    record |= {
        "duration_s": float(run.t[-1]),
        # the real time the run takes for the route's driving time: the base's wait at the
        # start for the arm (if any) and the arm's time law
        "route_duration_s": ArmReferences(run.posture, run.approach, run.timing).real_time(
            problem.route.duration
        ),
        "qp_failures": len(run.failures),
        "tipped": run.tipped is not None,
        "colliding_samples": collisions["colliding_samples"],
        "min_clearance_m": collisions["min_clearance_m"],
        "base_error_max_m": float(run.base_error.max()),
    }
    return record


def moves_lowest(robot: Any, moves: Any) -> float:
    """The arm's lowest point above the support plane along the plan's moves [m] (60
    samples per straight piece; inf without moves)."""
    from mmstab.model.plane_clearance import arm_ground_clearance

    u, low = np.linspace(0.0, 1.0, 60)[:, None, None], np.inf
    for m in moves or ():
        if len(m) > 1:
            q = (m[:-1][None] + u * np.diff(m, axis=0)[None]).reshape(-1, m.shape[1])
            low = min(low, float(arm_ground_clearance(robot, q).min()))
    return low


def failures(record: dict[str, Any]) -> list[str]:
    """What a pair's record fails of the issue's checks (empty: it passes)."""
    if not record.get("planned"):
        return [f"no plan: {record.get('error')}"]
    bad = []
    if record["pivots"] < 1:
        bad.append("no pivot turn on the route")
    if record["poses_below_stowed"]:
        bad.append(f"planned mu below stowed at poses {record['poses_below_stowed']}")
    if record["arm_ground_min_m"] < record["ground_clearance_m"]:
        bad.append(f"arm {record['arm_ground_min_m'] * 100:.1f} cm above the support plane")
    # between two nodes above the threshold a lattice step may dip a few millimetres
    if record["arm_ground_moves_min_m"] < record["ground_clearance_m"] - 0.005:
        bad.append(f"moves {record['arm_ground_moves_min_m'] * 100:.1f} cm above the plane")
    if record["qp_failures"]:
        bad.append(f"{record['qp_failures']} QP failures")
    if record["tipped"]:
        bad.append("tipped over")
    if record["colliding_samples"] or record["min_clearance_m"] < MIN_CLEARANCE:
        bad.append(
            f"arm self-collision: {record['colliding_samples']} samples, clearance "
            f"{record['min_clearance_m'] * 1e3:.2f} mm"
        )
    if record["duration_s"] < record["route_duration_s"] - 2 * TRACK_DT:
        bad.append("the run stopped before the route's end")
    return bad


# ------------------------------------------------------------------------- the generator
@pytest.mark.parametrize("k", range(FULL_PAIRS))
def test_the_generator_draws_what_the_issue_asks(k, tmp_path):
    rng = np.random.default_rng(SEED_BASE + k)
    data = random_pair(rng, pivot_everywhere=k % 2 == 0)
    w = np.asarray(data["path"]["waypoints"])
    legs = np.linalg.norm(np.diff(w, axis=0), axis=1)
    assert 3 <= len(w) <= 5 and np.all((legs > 2.0 - 2e-3) & (legs < 4.0 + 2e-3))
    d = np.diff(w, axis=0)
    turn = np.degrees(np.abs(np.angle(np.exp(1j * np.diff(np.arctan2(d[:, 1], d[:, 0]))))))
    assert turn.max() <= TURN_MAX_DEG + 0.1 and turn.max() >= 60.0 - 0.1
    g = data["terrain"]["generate"]
    assert 0.0 <= np.degrees(g["slope"]) <= SLOPE_MAX_DEG
    # the problem loads (the route stays on the map) and pivots at least once
    problem = load_problem(pair_problem(k, tmp_path))
    assert pivots_of(problem) >= 1
    if k % 2 == 0:
        assert pivots_of(problem) == len(w) - 2  # turn_radius 0: every corner


# ------------------------------------------------------------------------- plan and track
@pytest.fixture(scope="module")
def coarse_cache(tmp_path_factory) -> Path:
    """One workspace cache for the fast pairs (their coarse grid)."""
    return tmp_path_factory.mktemp("random_routes_cache")


@pytest.mark.parametrize("k", FAST_PAIRS)
@pytest.mark.slow
def test_a_random_route_plans_and_tracks(k, tmp_path, coarse_cache):
    """Plan found, μ planned >= stowed, no QP failure, no arm contact, the clearance kept."""
    problem = load_problem(pair_problem(k, tmp_path, COARSE))
    record = check_pair(problem, coarse_cache)
    assert record["planned"], record.get("error")
    assert record["pivots"] >= 1 and record["poses"] >= 10
    assert record["poses_below_stowed"] == [] and record["mu_margin_over_stowed_min"] > 0
    assert record["mu_gain_over_stowed_median"] > 0
    assert record["qp_failures"] == 0 and not record["tipped"]
    assert record["colliding_samples"] == 0 and record["min_clearance_m"] >= MIN_CLEARANCE
    assert record["duration_s"] == pytest.approx(record["route_duration_s"], abs=2 * TRACK_DT)
    assert failures(record) == []


def _full_set() -> bool:
    return os.environ.get(FULL_ENV, "0") not in ("", "0")


@pytest.mark.skipif(not _full_set(), reason=f"the full set: {FULL_ENV}=1 (make random-routes)")
def test_the_full_set_of_random_routes(tmp_path):
    """The issue's 20 routes over 20 maps, default grid: results/random_routes/summary.json."""
    count = int(os.environ.get(PAIRS_ENV) or FULL_PAIRS)  # make random-routes PAIRS=60
    pairs = []
    for k in range(count):
        path = pair_problem(k, tmp_path)
        t0 = time.perf_counter()
        try:
            record = check_pair(load_problem(path))
        except Exception:  # noqa: BLE001 - reported in the summary, the test fails below
            record = {"planned": False, "error": traceback.format_exc(limit=3)}
        record["seconds"] = time.perf_counter() - t0
        record["failures"] = failures(record)
        drawn = yaml.safe_load(path.read_text())
        drawn["robot"] = str(ROBOT.relative_to(ROOT))  # the summary names no machine's folder
        pairs.append({"pair": k, "seed": SEED_BASE + k, "problem": drawn} | record)
        print(f"pair {k}: {'pass' if not record['failures'] else record['failures']}", flush=True)
    passed = sum(not p["failures"] for p in pairs)
    summary = {
        "pairs": count,
        "passed": passed,
        "failed": [p["pair"] for p in pairs if p["failures"]],
        "planner_method": "roadmap",
        "controller_dt_s": TRACK_DT,
        "checks": (
            "plan found; planned mu >= stowed mu at every pose (rtol 1e-9); the arm "
            "planner.ground_clearance above the support plane at every pose (its moves: "
            "5 mm less); whole route "
            "tracked: 0 QP failures, 0 arm-contact samples, min clearance >= "
            f"{MIN_CLEARANCE} m; at least one pivot turn"
        ),
        "seconds_total": sum(p["seconds"] for p in pairs),
        "plan_ms_per_pose_median": float(
            np.median([p["plan_ms_per_pose"] for p in pairs if "plan_ms_per_pose" in p])
        ),
        "results": pairs,
    }
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    assert passed == count, summary["failed"]


# ------------------------------------------------------------------------- the fixes
def test_a_polyline_reference_stays_on_its_moves_and_rests_at_each_knot(rng):
    from mmstab.control.approach_path import eased_polyline
    from mmstab.control.reference import periodic_polyline

    f = np.array([0.1, 0.3, 0.35, 0.8])
    q = rng.uniform(-1, 1, (4, 4))
    ref = periodic_polyline(f, q)
    # on the straight move from knot 1 to knot 2, at the smoothstep of the fraction
    s = 0.3 + 0.05 * np.array([0.0, 0.25, 0.5, 1.0])
    tau = np.array([0.0, 0.25, 0.5, 1.0])
    expected = q[1] + (3 * tau**2 - 2 * tau**3)[:, None] * (q[2] - q[1])
    np.testing.assert_allclose(ref(s).value, expected, atol=1e-12)
    np.testing.assert_allclose(ref(f).rate, 0.0, atol=1e-12)  # at rest at every knot
    np.testing.assert_allclose(ref(0.1 + 1.0).value, q[[0]], atol=1e-12)  # period 1
    # mid-way through the closing move (0.8 -> 1.1) at 1.5 times its mean rate
    mid = ref(0.95)
    np.testing.assert_allclose(mid.value[0], 0.5 * (q[3] + q[0]), atol=1e-12)
    np.testing.assert_allclose(mid.rate[0], 1.5 * (q[0] - q[3]) / 0.3, rtol=1e-12)
    u = rng.uniform(0, 1, 50)
    h = 1e-7
    fd = (ref(u + h).value - ref(u - h).value) / (2 * h)
    np.testing.assert_allclose(ref(u).rate, fd, atol=1e-5)
    # the approach's open form: the same pieces on [0, 1]
    path = eased_polyline(np.array([0.0, 0.4, 1.0]), q[:3])
    np.testing.assert_allclose(path(0.2), 0.5 * (q[0] + q[1]), atol=1e-12)
    np.testing.assert_allclose(path(np.array([0.0, 0.4, 1.0]), 1), 0.0, atol=1e-12)
    np.testing.assert_allclose(path(1.0), q[2], atol=1e-12)


def test_roadmap_knots_give_every_piece_the_same_peak_acceleration(robot):
    """Pieces 0.05-1 rad long, filling one interval: equal smoothstep accelerations 6 Δ / h²
    (pair 5 overshot the end of a 0.05 rad piece placed by its time at the speed limit)."""
    from mmstab.control.posture import roadmap_knots

    steps = np.array([1.0, 0.05, 0.4, 0.2])
    move = np.zeros((5, 4))
    move[:, 0] = 0.5 + np.r_[0.0, np.cumsum(steps)]
    postures = np.vstack([move[0], move[-1]])
    f, q = roadmap_knots(robot, np.array([0.0, 0.5]), postures, (move[[0]], move))
    np.testing.assert_allclose(
        f, [0.0, *(0.5 * np.cumsum(np.sqrt(steps))[:-1] / np.sqrt(steps).sum()), 0.5]
    )
    np.testing.assert_allclose(q, move, atol=1e-12)
    h = np.diff(f)
    accel = 6 * steps / h**2
    np.testing.assert_allclose(accel, accel[0], rtol=1e-9)
