"""Benchmark: the posture roadmap against OMPL (PRM*, RRT-Connect) on the shipped robot.

Usage: ``python benchmarks/bench_roadmap.py [PROBLEM.yaml] [--queries N] [--budget S]``;
writes ``results/bench/roadmap.json``. The roadmap is the lattice over V's grid
(:mod:`mmstab.workspace.roadmap`), built (timed) or read from its cache. Queries: N seeded
pairs of roadmap nodes in the stowed arm's component. Per query and method: wall time [ms]
and joint-space path length [rad] (Euclidean in the four joints, the turret within its
stops, the same metric for every method). Methods: the roadmap's shortest path (lattice
staircase), the
same shortcut (:meth:`Roadmap.shortcut`, straight moves checked at the roadmap's
resolution), and OMPL 2.x (``pip install ompl``) RRT-Connect (+ its path simplifier) and
PRM* (one planner for every query: multi-query, ``budget`` seconds each), all with
mmstab's FCL checker as validity checker and a motion resolution matching the roadmap's
(no arm point moves more than ``resolution`` between checked states). Medians.
LazyPRM* is not in the ompl 2.0.1 wheel's bindings.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np
from common import machine_info

from mmstab.core.files import write_json
from mmstab.core.problem import load_problem
from mmstab.model.collision import CollisionChecker
from mmstab.planner.searches.roadmap import roadmap_move
from mmstab.workspace import load_or_build_workspace
from mmstab.workspace.roadmap import Roadmap, build_roadmap, load_or_build_roadmap


def _ompl_setup(robot: Any, checker: CollisionChecker, rm: Roadmap) -> tuple[Any, Any]:
    from ompl import base as ob
    from ompl import geometric as og

    # R^4 within the joint limits: the turret's [0, 2 pi] ends at a stop (no SO(2) wrap)
    space = ob.RealVectorStateSpace(4)
    bounds = ob.RealVectorBounds(4)
    for i in range(4):
        bounds.setLow(i, float(robot.joint_lower[i]))
        bounds.setHigh(i, float(robot.joint_upper[i]))
    space.setBounds(bounds)
    ss = og.SimpleSetup(space)
    ss.setStateValidityChecker(lambda s: not checker.collides(_q(s)))
    # the roadmap's resolution: a joint step moving no point more than `resolution`
    step = rm.resolution / float(rm.reach.max())
    ss.getSpaceInformation().setStateValidityCheckingResolution(step / space.getMaximumExtent())
    return ss, space


def _q(s: Any) -> np.ndarray:
    return np.array([s[0], s[1], s[2], s[3]])


def _set(space: Any, q: np.ndarray) -> Any:
    st = space.allocState()
    for i in range(4):
        st[i] = float(q[i])
    return st


def _length(q: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(np.asarray(q, dtype=float), axis=0), axis=1).sum())


def _ompl_query(ss: Any, space: Any, planner: Any, qa: Any, qb: Any, budget: float, simplify: bool):
    ss.clearStartStates()
    ss.setStartAndGoalStates(_set(space, qa), _set(space, qb))
    t0 = time.perf_counter()
    solved = ss.solve(budget)
    ok = bool(solved) and ss.haveExactSolutionPath()
    if ok and simplify:
        ss.simplifySolution()
    ms = (time.perf_counter() - t0) * 1e3
    if not ok:
        return ms, None
    states = ss.getSolutionPath().getStates()
    return ms, _length(np.array([_q(s) for s in states]))


def query_pairs(robot: Any, rm: Roadmap, queries: int, seed: int = 0) -> np.ndarray:
    """``queries`` seeded pairs of nodes (queries, 2) in the stowed arm's component."""
    start = rm.connect(robot.stowed, robot)
    comp = np.flatnonzero(rm.component == rm.component[start])
    return np.random.default_rng(seed).choice(comp, (queries, 2))


def compare_queries(
    robot: Any, rm: Roadmap, pairs: np.ndarray, budget: float
) -> tuple[dict[str, Any], list[float]]:
    """Per method (roadmap, shortcut, rrtconnect, prmstar): solved, median ms and length.

    Returns the summary per method and the straight-line length of each pair [rad].
    """
    from ompl import geometric as og

    checker = CollisionChecker(robot)
    rows: dict[str, list[Any]] = {k: [] for k in ("roadmap", "shortcut", "rrtconnect", "prmstar")}
    ss, space = _ompl_setup(robot, checker, rm)
    prm = og.PRMstar(ss.getSpaceInformation())
    rrt = og.RRTConnect(ss.getSpaceInformation())
    straight: list[float] = []
    for a, b in pairs:
        qa, qb = rm.nodes_q[a], rm.nodes_q[b]
        t0 = time.perf_counter()
        path = roadmap_move(rm, int(a), int(b))
        t1 = time.perf_counter()
        cut = rm.shortcut(checker, path)
        t2 = time.perf_counter()
        straight.append(float(np.linalg.norm(qb - qa)))
        rows["roadmap"].append(((t1 - t0) * 1e3, _length(path)))
        rows["shortcut"].append(((t2 - t0) * 1e3, _length(cut)))
        ss.setPlanner(rrt)
        rrt.clear()
        rows["rrtconnect"].append(_ompl_query(ss, space, rrt, qa, qb, budget, True))
        ss.setPlanner(prm)
        prm.clearQuery()
        rows["prmstar"].append(_ompl_query(ss, space, prm, qa, qb, budget, False))
    summary = {}
    for name, r in rows.items():
        solved = [x for x in r if x[1] is not None]
        summary[name] = {
            "solved": len(solved),
            "median_ms": statistics.median(x[0] for x in r),
            "median_length_rad": statistics.median(x[1] for x in solved) if solved else None,
            "per_query": [{"ms": x[0], "length_rad": x[1]} for x in r],
        }
    return summary, straight


def main() -> None:
    """Run the queries and write the JSON (module text)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("problem", nargs="?", default="problems/rough.yaml")
    ap.add_argument("--queries", type=int, default=10)
    ap.add_argument("--budget", type=float, default=2.0, help="OMPL seconds per query")
    ap.add_argument("--rebuild", action="store_true", help="time a fresh roadmap build")
    ap.add_argument("--out", default="results/bench/roadmap.json")
    args = ap.parse_args()
    problem = load_problem(args.problem)
    robot = problem.robot
    ws = load_or_build_workspace(problem, progress=False)
    if args.rebuild:
        rm = build_roadmap(robot, ws)
    else:
        rm = load_or_build_roadmap(robot, ws)
    start = rm.connect(robot.stowed, robot)
    comp = np.flatnonzero(rm.component == rm.component[start])
    summary, straight = compare_queries(
        robot, rm, query_pairs(robot, rm, args.queries), args.budget
    )
    out = {
        "problem": args.problem,
        "queries": args.queries,
        "ompl_budget_s": args.budget,
        "roadmap": {
            "nodes": len(rm.nodes_q),
            "edges": len(rm.edges),
            "components": int(rm.component.max()) + 1,
            "start_component_nodes": len(comp),
            "resolution_m": rm.resolution,
            "reach_m": rm.reach.tolist(),
            "interior_checks_per_edge": rm.steps.tolist(),
            "build_seconds": rm.build_seconds,
        },
        "straight_line_rad": straight,
        "straight_line_median_rad": statistics.median(straight),
        "methods": summary,
        "machine": machine_info(ompl="2.0.1"),
    }
    write_json(Path(args.out), out)
    for name, s in summary.items():
        print(
            f"{name:11s} solved {s['solved']}/{args.queries}  median {s['median_ms']:.1f} ms  "
            f"length {s['median_length_rad']} rad"
        )
    print(f"roadmap build {rm.build_seconds:.1f} s, {len(rm.nodes_q)} nodes, {len(rm.edges)} edges")


if __name__ == "__main__":
    main()
