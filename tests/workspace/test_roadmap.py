"""The posture roadmap (mmstab.workspace.roadmap) and the planner on it (method: roadmap).

Coarse grids throughout (the roadmap of V's full grid is measured by make bench-roadmap).
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import yaml
from test_route_plan import ROUGH, rough_data

from mmstab.core.problem import problem_from_dict
from mmstab.model.collision import CollisionChecker
from mmstab.planner import PlannerSettings, plan_route
from mmstab.planner.searches.roadmap import NoPlanError, best_sequence, solve_roadmap_sequence
from mmstab.stability.static import mu_max
from mmstab.workspace import build_workspace
from mmstab.workspace.grid import joint_grid
from mmstab.workspace.roadmap import build_roadmap, load_or_build_roadmap

GRID = (10, 8, 8, 8)


@pytest.fixture(scope="module")
def small(robot):
    ws = build_workspace(robot, GRID, progress=False)
    return ws, build_roadmap(robot, ws)


def test_edges_join_grid_neighbours_and_are_collision_free(robot, small):
    ws, rm = small
    step = joint_grid(robot, GRID).step
    d = rm.nodes_q[rm.edges[:, 1]] - rm.nodes_q[rm.edges[:, 0]]
    d[:, 0] = (d[:, 0] + np.pi) % (2 * np.pi) - np.pi
    moved = np.abs(d) > 1e-9
    assert np.all(moved.sum(axis=1) == 1)  # one joint per edge, by one grid step
    np.testing.assert_allclose(np.abs(d[moved]), step[np.argmax(moved, axis=1)], rtol=1e-9)
    np.testing.assert_allclose(rm.lengths, np.abs(d[moved]), rtol=1e-9)
    # dense re-check of a seeded sample: 4 times the build's resolution, every pair in FCL
    rng = np.random.default_rng(7)
    pick = rng.choice(len(rm.edges), 150, replace=False)
    u = np.linspace(0, 1, 4 * (int(rm.steps.max()) + 1) + 1)[:, None, None]
    a = rm.nodes_q[rm.edges[pick, 0]]
    q = (a[None] + u * d[pick][None]).reshape(-1, 4)
    assert not np.asarray(CollisionChecker(robot).collides(q, cull=False)).any()
    # the resolution: a step's motion of the farthest point stays within it between checks
    assert np.all(rm.reach * step / (rm.steps + 1) <= rm.resolution + 1e-12)


def test_missing_edges_collide_or_lack_an_end(robot, small):
    """Every grid-neighbour pair of nodes without an edge has a colliding checked posture."""
    _, rm = small
    rng = np.random.default_rng(3)
    checker = CollisionChecker(robot)
    step = joint_grid(robot, GRID).step
    have = {tuple(e) for e in rm.edges.tolist()}
    q = rm.nodes_q[rng.choice(len(rm.nodes_q), 60, replace=False)]
    for j in range(1, 4):
        nxt = q.copy()
        nxt[:, j] += step[j]
        a, b = rm.nearest(q), rm.nearest(nxt)
        for k in np.flatnonzero(np.linalg.norm(rm.nodes_q[b] - nxt, axis=1) < 1e-9):
            if (int(a[k]), int(b[k])) in have:
                continue
            u = np.arange(1, rm.steps[j] + 1) / (rm.steps[j] + 1)
            inner = q[k] + u[:, None] * (nxt[k] - q[k])
            assert np.asarray(checker.collides(inner)).any()


def test_path_endpoints_and_length(small):
    from scipy.sparse.csgraph import dijkstra

    _, rm = small
    rng = np.random.default_rng(11)
    big = np.argmax(np.bincount(rm.component))
    nodes = np.flatnonzero(rm.component == big)
    for a, b in rng.choice(nodes, (5, 2)):
        p = rm.path(int(a), int(b))
        assert p[0] == a and p[-1] == b
        w = np.asarray(rm.graph[p[:-1], p[1:]]).ravel()
        assert np.all(w > 0)  # every step is an edge
        dist = dijkstra(rm.graph, indices=int(a))[int(b)]
        assert w.sum() == pytest.approx(dist, rel=1e-12)


@pytest.mark.parametrize("closed", [False, True])
def test_dynamic_programming_is_exact_against_brute_force(closed):
    rng = np.random.default_rng(5)
    for _ in range(20):
        K, M = 4, 3
        value = rng.normal(size=(K, M))
        value[rng.random((K, M)) < 0.15] = -np.inf
        n = K if closed else K - 1
        motion = [rng.uniform(0, 1, (M, M)) for _ in range(n)]
        allowed = [rng.random((M, M)) < 0.8 for _ in range(n)]
        best = -np.inf
        for c in itertools.product(range(M), repeat=K):
            pairs = list(zip(c[:-1], c[1:], strict=True)) + ([(c[-1], c[0])] if closed else [])
            if all(allowed[i][x, y] for i, (x, y) in enumerate(pairs)):
                total = sum(value[k, c[k]] for k in range(K))
                best = max(best, total - sum(motion[i][x, y] for i, (x, y) in enumerate(pairs)))
        path, total = best_sequence(value, motion, allowed, closed)
        assert total == pytest.approx(best) if np.isfinite(best) else not np.isfinite(total)


def test_a_pose_without_a_stable_posture_is_named(robot, small):
    _, rm = small
    g = np.tile([0.0, 0.0, -9.81], (4, 1))
    g[2] = [0.0, 0.0, 9.81]  # upside down: no posture is stable
    poses = np.column_stack([np.arange(4.0), np.zeros(4), np.zeros(4)])
    s = PlannerSettings.from_section(yaml.safe_load(ROUGH.read_text())["planner"])
    with pytest.raises(NoPlanError, match=r"at pose 2 \(x 2.00 m") as info:
        solve_roadmap_sequence(robot, g, rm, s, mu_max(robot), False, poses)
    assert info.value.pose_index == 2


def test_a_seeded_random_route_plans_on_the_roadmap(tmp_path, robot):
    rng = np.random.default_rng(2024)
    xy = np.cumsum(rng.uniform([2.0, -1.5], [3.0, 1.5], (4, 2)), axis=0)
    data = rough_data(waypoints=(xy - xy.mean(axis=0)).tolist())
    data["planner"].update(method="roadmap", spacing=1.5)
    problem = problem_from_dict(data, tmp_path / "p.yaml")
    from mmstab.workspace import load_or_build_workspace

    ws = load_or_build_workspace(problem, progress=False, cache_dir=tmp_path)
    plan = plan_route(problem, ws)
    assert np.all(plan.mu_planned >= plan.mu_stowed)
    assert len(plan.moves) == len(plan.poses)
    rm = load_or_build_roadmap(problem.robot, ws)
    np.testing.assert_allclose(plan.moves[0][0], problem.robot.stowed, atol=1e-12)
    checker = CollisionChecker(problem.robot)
    for k, move in enumerate(plan.moves):
        end = move[-1].copy()
        end[0] = (end[0] - plan.postures[k, 0] + np.pi) % (2 * np.pi) - np.pi + plan.postures[k, 0]
        np.testing.assert_allclose(end, plan.postures[k], atol=1e-9)
        if k:
            start = plan.postures[k - 1]
            assert np.allclose(np.cos(move[0][0] - start[0]), 1.0)
        # the move, checked densely: collision-free by construction
        u = np.linspace(0, 1, 4 * (int(rm.steps.max()) + 1) + 1)[:, None, None]
        q = (move[:-1][None] + u * np.diff(move, axis=0)[None]).reshape(-1, 4)
        assert not np.asarray(checker.collides(q)).any()


def test_clearance_is_zero_exactly_where_the_checker_finds_contact(robot):
    rng = np.random.default_rng(9)
    q = rng.uniform(robot.joint_lower, robot.joint_upper, (300, 4))
    checker = CollisionChecker(robot)
    d = checker.clearance(q)
    hit = np.asarray(checker.collides(q))
    assert hit.any() and (~hit).any()
    assert np.all(d[hit] == 0.0) and np.all(d[~hit] > 0.0)
    # 1-Lipschitz in point motion: a joint move dq moves no point more than reach . |dq|
    from mmstab.model.reach import joint_reach

    reach = joint_reach(robot, q)
    dq = rng.normal(scale=0.01, size=q.shape)
    moved = checker.clearance(q + dq)
    assert np.all(np.abs(moved - d) <= np.abs(dq) @ reach + 1e-9)


def test_arm_collision_verdict_and_exit_status():
    import argparse

    from mmstab.cli.commands import _arm_collision
    from mmstab.runs.verdict import MIN_CLEARANCE, arm_collision_verdict

    def summary(colliding: int, clearance: float) -> dict:
        return {
            "arm_self_collision": {
                "samples": 10,
                "pairs": {"upper_arm-track_left": colliding} if colliding else {},
                "min_clearance_time_s": 1.5,
                "verdict": arm_collision_verdict(colliding, clearance),
            }
        }

    strict, lenient = (
        argparse.Namespace(allow_collision=False),
        argparse.Namespace(allow_collision=True),
    )
    assert _arm_collision(summary(0, 2 * MIN_CLEARANCE), strict) is None
    assert _arm_collision(summary(0, 0.5 * MIN_CLEARANCE), strict) == 5
    assert _arm_collision(summary(3, 0.0), strict) == 5
    assert _arm_collision(summary(3, 0.0), lenient) is None


@pytest.mark.slow
def test_plan_and_track_a_route_on_the_roadmap_from_the_cli(tmp_path):
    """Method roadmap, planned and tracked: no arm contact, the clearance kept, no QP failure."""
    import json

    from test_route_plan import _cli, write

    from mmstab.runs.verdict import MIN_CLEARANCE

    data = rough_data(waypoints=[[-3.0, -0.6], [-1.0, -0.2]], speed=0.25)
    data["terrain"]["friction"] = 1.0  # a 36 deg pose would slide at 0.7 (exit 4)
    # rough.yaml's margin 250 is passed between its poses on the loaded support (a few road
    # wheels carry the downhill side: ~65 N rad; test_route_plan checks that refusal)
    data["planner"].update(method="roadmap", spacing=0.5, margin=0.0)
    data["controller"]["dt"] = 0.005
    problem = write(tmp_path, data, "route.yaml")
    out = _cli(["plan", str(problem), "-o", "plan"], tmp_path)
    assert out.returncode == 0, out.stderr[-2000:]
    out = _cli(["track", str(problem), "-o", "track"], tmp_path)
    assert out.returncode == 0, out.stderr[-2000:]
    t = json.loads((tmp_path / "track" / "summary.json").read_text())
    arm = t["arm_self_collision"]
    assert arm["colliding_samples"] == 0 and arm["verdict"]["safe"]
    assert arm["min_clearance_m"] >= MIN_CLEARANCE
    assert t["qp_failures"] == 0
    assert t["posture_reference"]["reference"]["colliding_samples"] == 0


def test_route_summary_reports_the_gap_to_the_per_pose_optima(tmp_path):
    """summary.json quality: optima by brute force here, planned <= optimum over the roadmap."""
    from mmstab.core.problem import load_problem
    from mmstab.outputs.routes import run_route_plan
    from mmstab.planner import gravity_body_at
    from mmstab.planner.fitness import support_polygons_at
    from mmstab.planner.searches.roadmap import node_coms
    from mmstab.stability.static import force_angle_batch
    from mmstab.stability.support import stability_along

    data = rough_data(waypoints=[[-3.0, -0.6], [-1.0, 0.2]])
    data["planner"].update(method="roadmap", spacing=1.0)
    path = tmp_path / "p.yaml"
    path.write_text(yaml.safe_dump(data))
    import os

    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        s = run_route_plan(load_problem(path), tmp_path / "plan")
        problem = load_problem(path)
        from mmstab.workspace import load_or_build_workspace

        ws = load_or_build_workspace(problem, progress=False)
        rm = load_or_build_roadmap(problem.robot, ws)
    finally:
        os.chdir(cwd)
    q = s["quality"]
    poses = np.array([p["pose"] for p in s["poses"]])
    from mmstab.model.plane_clearance import arm_ground_clearance

    # the nodes the planner may choose: the stowed arm's component, the arm clear of the ground
    ground = problem.section("planner")["ground_clearance"]
    assert ground == 0.05  # rough.yaml's
    above = arm_ground_clearance(problem.robot, rm.nodes_q) >= ground
    coms = node_coms(problem.robot, rm)[
        (rm.component == rm.component[rm.nearest(problem.robot.stowed)[0]]) & above
    ]
    # independent: μ of every reachable node at every pose on the search's basis (the
    # contacts that carry the stowed robot's load at its rest: its stowed μ is the plan's)
    g = gravity_body_at(problem.terrain, poses)
    assert len(g) == len(q["mu_searched"])
    polygons = support_polygons_at(problem.robot, problem.terrain, poses)
    stowed_com = problem.robot.overall_com(problem.robot.arm_com(problem.robot.stowed))
    for k in range(len(poses)):
        m = problem.robot.total_mass
        stowed = force_angle_batch(polygons[k], stowed_com[None], m * g[k][None]).mu[0]
        assert stowed == pytest.approx(s["poses"][k]["mu_stowed"], rel=1e-9)
        overall = problem.robot.overall_com(coms)
        mu = force_angle_batch(polygons[k], overall, m * np.tile(g[k], (len(coms), 1))).mu
        assert q["mu_optimum_roadmap"][k] == pytest.approx(mu.max(), rel=1e-9)
        assert q["mu_searched"][k] <= q["mu_optimum_roadmap"][k] + 1e-9
    np.testing.assert_allclose(
        q["gap_to_roadmap"],
        (np.array(q["mu_optimum_roadmap"]) - q["mu_searched"]) / np.abs(q["mu_optimum_roadmap"]),
    )
    # what the plan reports is the one μ: the planned postures on their loaded support
    realised = problem.robot.arm_com(np.array([p["posture"] for p in s["poses"]]))
    reported = stability_along(problem.robot, problem.terrain, poses, realised).reconfigured
    np.testing.assert_allclose([p["mu_planned"] for p in s["poses"]], reported, rtol=0, atol=1e-9)
    assert q["gap_to_V_median"] == pytest.approx(np.median(q["gap_to_V"]))
    # V's samples whose arm clears the ground as well: at most the optimum over all of V
    assert np.all(np.array(q["mu_optimum_V_clear"]) <= np.array(q["mu_optimum_V"]) + 1e-9)
    assert q["gap_to_V_clear_median"] == pytest.approx(np.median(q["gap_to_V_clear"]))


def test_shortcuts_keep_the_move_clearance(robot, small):
    """Every cut the shortcut makes keeps MOVE_CLEARANCE (dense FCL distance); lattice
    steps it keeps are edges of the roadmap."""
    from mmstab.workspace.roadmap import MOVE_CLEARANCE

    _, rm = small
    rng = np.random.default_rng(31)
    checker = CollisionChecker(robot)
    comp = np.flatnonzero(rm.component == np.bincount(rm.component).argmax())
    edges = {tuple(e) for e in np.sort(rm.edges, axis=1).tolist()}
    node_of = {tuple(q): i for i, q in enumerate(np.round(rm.nodes_q, 12).tolist())}
    cuts = 0
    for a, b in rng.choice(comp, (6, 2)):
        lattice = rm.path_postures(int(a), int(b))
        short = rm.shortcut(checker, lattice)
        np.testing.assert_array_equal(short[[0, -1]], lattice[[0, -1]])
        for qa, qb in zip(short[:-1], short[1:], strict=True):
            i, j = node_of[tuple(np.round(qa, 12))], node_of[tuple(np.round(qb, 12))]
            if tuple(sorted((i, j))) in edges:
                continue
            cuts += 1
            u = np.linspace(0.0, 1.0, 200)[:, None]
            assert checker.clearance(qa + u * (qb - qa)).min() >= MOVE_CLEARANCE
    assert cuts > 0


@pytest.mark.parametrize("cost", ["joints", "com"])
def test_the_motion_cost_is_the_lattice_distance_or_eq6(robot, small, cost):
    """Each pose's reported fitness: the stability term minus the motion cost of its move."""
    _, rm = small
    tilt = np.linspace(0.0, 0.5, 5)
    g = -9.81 * np.column_stack([np.sin(tilt), 0.4 * np.sin(tilt), np.cos(tilt)])
    s = PlannerSettings.from_section(yaml.safe_load(ROUGH.read_text())["planner"])
    s = s._replace(method="roadmap", motion_cost=cost, w_stability=0.5, w_motion=0.5)
    seq = solve_roadmap_sequence(robot, g, rm, s, mu_max(robot), False, np.zeros((5, 3)))
    reach = rm.component == rm.component[rm.connect(robot.stowed, robot)]
    if cost == "joints":
        before = np.vstack([robot.stowed, seq.postures[:-1]])
        span = np.ptp(rm.nodes_q[reach], axis=0).sum()
        moved = (np.abs(seq.postures - before).sum(axis=1) / span) ** 2
    else:
        before = np.vstack([robot.arm_com(robot.stowed), seq.com[:-1]])
        coms = robot.arm_com(rm.nodes_q[reach])
        moved = np.sum((seq.com - before) ** 2, axis=1) / np.ptp(coms, axis=0).max() ** 2
    expected = 0.5 * seq.mu / mu_max(robot) - 0.5 * moved
    np.testing.assert_allclose(seq.fitness, expected, rtol=1e-9, atol=1e-12)


def test_astar_moves_are_shortest_roadmap_paths(small):
    """A* with the L1 heuristic: a path of edges as short as Dijkstra's, pair by pair."""
    from scipy.sparse.csgraph import dijkstra

    from mmstab.planner.searches.roadmap import astar

    _, rm = small
    comp = np.flatnonzero(rm.component == np.bincount(rm.component).argmax())
    edges = {tuple(e) for e in np.sort(rm.edges, axis=1).tolist()}
    for a, b in np.random.default_rng(8).choice(comp, (12, 2)):
        path = astar(rm, int(a), int(b))
        assert path is not None and path[0] == a and path[-1] == b
        assert all(tuple(sorted(e)) in edges for e in zip(path[:-1], path[1:], strict=True))
        length = np.abs(np.diff(rm.nodes_q[path], axis=0)).sum()
        assert length == pytest.approx(dijkstra(rm.graph, indices=int(a))[b], rel=1e-12)


def test_astar_in_c_finds_the_pythons_paths(small, monkeypatch):
    """The C kernel against the Python loop, node for node: plain, masked, with a ground
    threshold and with too few expansions (None from both)."""
    from mmstab.planner.searches.roadmap import moves

    _, rm = small
    assert moves._astar_kernel() is not None  # the C kernel runs here
    rng = np.random.default_rng(21)
    ground = float(np.median(rm.node_ground))
    comp = np.flatnonzero(rm.component == np.bincount(rm.component).argmax())
    found = 0
    for a, b in rng.choice(comp, (30, 2)):
        path = moves.astar_python(rm, int(a), int(b))
        masked = frozenset(int(n) for n in (path[1:-1] if path is not None else ()))
        for g, m in ((None, frozenset()), (None, masked), (ground, frozenset())):
            want = moves.astar_python(rm, int(a), int(b), g, m)
            got = moves.astar(rm, int(a), int(b), g, m)
            assert (got is None) == (want is None)
            if want is not None:
                found += 1
                np.testing.assert_array_equal(got, want)
    assert found >= 40
    monkeypatch.setattr(moves, "ASTAR_EXPANSIONS", 3)  # the limit: neither reaches b
    a, b = (int(x) for x in comp[[0, -1]])
    assert moves.astar(rm, a, b) is None and moves.astar_python(rm, a, b) is None
    # past the limit the whole component is searched: a shortest path that avoids the
    # masked nodes too (their edges removed; an explicit zero would be a free edge)
    plain = moves._path_nodes(rm, a, b, None, None)
    masked = frozenset(int(n) for n in plain[1:-1:2])
    graph = rm.graph
    kept = (graph.indptr.copy(), graph.indices.copy(), graph.data.copy())
    detour = moves._path_nodes(rm, a, b, None, None, masked)
    assert detour is not None and not masked & set(detour.tolist())
    for before, now in zip(kept, (graph.indptr, graph.indices, graph.data), strict=True):
        np.testing.assert_array_equal(now, before)  # the kept graph is left whole
    monkeypatch.setattr(moves, "ASTAR_EXPANSIONS", 10**7)  # A* itself: the same length
    again = moves.astar(rm, a, b, None, masked)

    def length(p: np.ndarray) -> float:
        return float(np.abs(np.diff(rm.nodes_q[p], axis=0)).sum())

    assert again is not None and length(detour) == pytest.approx(length(again), rel=1e-12)
    arrays = moves._astar_arrays(rm, None)  # the work arrays are left clean
    assert np.isinf(arrays["best"]).all() and not arrays["masked"].any()


def test_no_path_is_proved_without_the_whole_component(small, monkeypatch):
    """A move whose end the masked nodes wall in: A* from either side empties its open list
    (proved, in C and in Python alike), so the whole component is not searched."""
    from mmstab.planner.searches.roadmap import moves

    _, rm = small
    comp = np.flatnonzero(rm.component == np.bincount(rm.component).argmax())
    a, b = (int(x) for x in comp[[0, -1]])
    g = rm.graph
    wall_b = frozenset(int(n) for n in g.indices[g.indptr[b] : g.indptr[b + 1]])
    wall_a = frozenset(int(n) for n in g.indices[g.indptr[a] : g.indptr[a + 1]])
    for search in (moves.astar_search, moves.astar_python_search):
        assert search(rm, a, b, None, wall_a)[0] is None and search(rm, a, b, None, wall_a)[1]
        assert search(rm, b, a, None, wall_b)[1]  # b's side, searched from b
        path, proved = search(rm, a, b)
        assert path is not None and not proved
    monkeypatch.setattr(moves, "dijkstra", None)  # the component search would fail here
    monkeypatch.setattr(moves, "ASTAR_EXPANSIONS", 50)  # a's side reaches the limit
    assert moves.astar_search(rm, a, b, None, wall_b) == (None, False)
    assert moves._path_nodes(rm, a, b, None, None, wall_b) is None
    assert moves._path_nodes(rm, a, b, None, None, wall_a) is None
    assert moves._path_nodes(rm, a, b, None, None, wall_b | {b}) is None
