"""Benchmark: the online loop's latency per map beside the offline planner.

Usage: ``python benchmarks/bench_online.py [PROBLEM.yaml] [--recording FILE] [--repeats N]
[--attitude-margin RAD] [--validation-route K] [--out FILE]``; writes
``results/bench/online.json``. ``--validation-route K``: route K of ``make validate-routes``
(user-like ground: ditches, kerbs, bumps) instead of a problem file. The recording
(``mmstab record``, written if missing) is followed ``repeats`` times on one core (the
process pinned to one CPU, BLAS threads 1); per map: the wall time from the map to its
answer (rest of the robot, its reference and the horizon on the map, re-plan of the poses
whose ground changed, one controller step: the command; then the verdicts: the support's
flags, the arm's height, the rock check), to the command alone (``command_latency_ms``),
and the spare time's work after the answer (the queued re-plans' steps and the moves ahead,
``spare_ms``; ``busy_ms``: answer and spare time, the loop's time per map). Beside it, in
the same run, the offline warm-started planner on the same route poses on the problem's own
terrain (its per-pose search time, the resting pose included), and the whole offline plan
per pose. Medians over the repeats of each percentile.

The slow maps: per repeat, the slowest 1 % of the answers (p99 is the least of them),
each with what it did: the map's index (the first sets the horizon up), the poses whose
re-plan it triggered and the poses it left uncovered, the steps it ran to land re-plans
due on it (:mod:`mmstab.runs.online.replan_jobs`; the spare time's steps and moves ahead
run after the answer, so ``job_steps`` and ``ahead_steps`` count none), the arm's moves it
computed for the reference, and the garbage collector's time within it (``gc.callbacks``
around ``Follower.update``); a cause per map, the first that applies: ``first map``,
``re-plan at once`` (a re-plan computed on its map: a pose near the robot without a valid
plan), ``landing`` (a re-plan due on the map not computed yet), ``move`` (a move the
reference needed), ``re-plan steps``, ``moves ahead``, ``garbage collection`` (half of the
update or more), else ``other``; the count of each among the slow maps, and the slowest map
of the run with its cause. ``startup_excluded``: the percentiles without the first map (the
horizon's set-up, before the robot can move).
"""

from __future__ import annotations

import argparse
import copy
import gc
import os
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from common import machine_info  # noqa: E402

from mmstab.core.files import write_json  # noqa: E402
from mmstab.core.problem import load_problem, problem_from_dict  # noqa: E402
from mmstab.outputs.online import offline_plan  # noqa: E402
from mmstab.outputs.recording import record_route  # noqa: E402
from mmstab.runs.online.follow import Follower  # noqa: E402
from mmstab.runs.online.moves_ahead import MovesAhead  # noqa: E402
from mmstab.runs.online.replan_jobs import Jobs  # noqa: E402
from mmstab.runs.online.roadmap_horizon import RoadmapHorizon  # noqa: E402
from mmstab.runs.online.run import follow_recording, summarize  # noqa: E402
from mmstab.workspace import load_or_build_workspace  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

#: Seconds the garbage collector ran, in total and during each update of the current run.
GC_TOTAL, GC_PER_UPDATE = [0.0, 0.0], []  # [total, the running pass's start]
#: Counts of what the current update did (:func:`_counted`), and per update of the run.
WORK: dict[str, int] = {}
WORK_PER_UPDATE: list[dict[str, int]] = []
CPU_PER_UPDATE: list[float] = []  # the loop thread's processor time per update [s]
SPARE_PER_UPDATE: list[float] = []  # the spare time's wall time after each answer [s]
KINDS = ("job_steps", "landing_steps", "at_once", "moves", "ahead_steps")


def _gc_clock(phase: str, info: dict) -> None:
    if phase == "start":
        GC_TOTAL[1] = time.perf_counter()
    else:
        GC_TOTAL[0] += time.perf_counter() - GC_TOTAL[1]


def _timed_update(update):
    """``Follower.update`` that records the collector's time and the work within each update."""

    def wrapped(self, u):
        before = GC_TOTAL[0]
        WORK.clear()
        step = update(self, u)
        CPU_PER_UPDATE.append(self.cpu_time)  # the timed part's, as the latency
        GC_PER_UPDATE.append(GC_TOTAL[0] - before)
        WORK_PER_UPDATE.append({k: WORK.get(k, 0) for k in KINDS})
        return step

    return wrapped


def _timed_spare(spare):
    """``Follower.spare`` that records its wall time per map."""

    def wrapped(self):
        seconds = spare(self)
        SPARE_PER_UPDATE.append(seconds)
        return seconds

    return wrapped


def _counted() -> None:
    """Count the re-plans' steps (spare time, landing), the moves and the moves ahead."""
    step, due, move, ahead = Jobs.step, Jobs.due, RoadmapHorizon._move, MovesAhead.advance
    landing = [False]

    def counted_step(self):
        ran = step(self)
        key = "landing_steps" if landing[0] else "job_steps"
        WORK[key] = WORK.get(key, 0) + int(ran)
        return ran

    def counted_due(self, index, near, everything=False, touching=None):
        landing[0] = True
        try:
            out = due(self, index, near, everything, touching)
        finally:
            landing[0] = False
        if everything and out:
            WORK["at_once"] = WORK.get("at_once", 0) + 1
        return out

    def counted_move(self, *args, **kwargs):
        WORK["moves"] = WORK.get("moves", 0) + 1
        return move(self, *args, **kwargs)

    def counted_ahead(self, *args, **kwargs):
        n = ahead(self, *args, **kwargs)
        WORK["ahead_steps"] = WORK.get("ahead_steps", 0) + n
        return n

    Jobs.step, Jobs.due = counted_step, counted_due  # type: ignore[method-assign]
    RoadmapHorizon._move = counted_move  # type: ignore[method-assign]
    MovesAhead.advance = counted_ahead  # type: ignore[method-assign]


def cause(index: int, step, gc_s: float, work: dict[str, int]) -> str:
    """What made an update slow (module text)."""
    if index == 0:
        return "first map"
    if work["at_once"]:
        return "re-plan at once"
    if work["landing_steps"]:
        return "landing"
    if work["moves"]:
        return "move"
    if work["job_steps"]:
        return "re-plan steps"
    if work["ahead_steps"]:
        return "moves ahead"
    if gc_s >= 0.5 * step.latency:
        return "garbage collection"
    return "other"


CAUSES = (
    "first map", "re-plan at once", "landing", "move", "re-plan steps", "moves ahead",
    "garbage collection", "other",
)  # fmt: skip


def slow_maps(run, gc_per_update: list[float], work: list[dict[str, int]]) -> list[dict]:
    """The slowest 1 % of a run's updates (at least one), slowest first, with their causes."""
    lat = np.array([x.latency for x in run.steps])
    count = max(1, int(np.ceil(0.01 * len(lat))))
    out = []
    for i in np.argsort(-lat)[:count]:
        st, g, w = run.steps[int(i)], gc_per_update[int(i)], work[int(i)]
        out.append(
            {
                "index": int(i),
                "time_s": float(st.time),
                "latency_ms": 1e3 * float(st.latency),
                "replanned_poses": int(st.replanned),
                "uncovered_poses": int(st.uncovered),
                **w,
                "gc_ms": 1e3 * g,
                "cause": cause(int(i), st, g, w),
            }
        )
    return out


def latency_stats(latency_s: np.ndarray) -> dict[str, float]:
    """p50, p99, max and mean [ms] of latencies [s]."""
    ms = 1e3 * np.asarray(latency_s)
    return {
        "p50": float(np.percentile(ms, 50)),
        "p99": float(np.percentile(ms, 99)),
        "max": float(ms.max()),
        "mean": float(ms.mean()),
    }


def validation_route(k: int) -> str:
    """Route ``k`` of ``make validate-routes`` written as a problem file (a temporary folder)."""
    import tempfile

    import yaml

    sys.path.insert(0, str(ROOT))
    from experiments.validate_routes import load_settings, route_problem

    data = route_problem(load_settings(ROOT / "problems" / "validate_routes.yaml"), k)
    path = Path(tempfile.mkdtemp(prefix="mmstab-bench-")) / f"route{k:02d}.yaml"
    path.write_text(yaml.safe_dump(data))
    return str(path)


def main() -> None:
    """Follow the recording ``--repeats`` times, plan offline beside it, write the JSON."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("problem", nargs="?", default="problems/rough.yaml")
    ap.add_argument(
        "--recording", help="default: results/online/rough.mcap; a validation route's: its own"
    )
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", default="results/bench/online.json")
    ap.add_argument(
        "--attitude-margin", type=float, help="planner.attitude_margin [rad] instead of the file's"
    )
    ap.add_argument(
        "--validation-route",
        type=int,
        help="route K of make validate-routes (problems/validate_routes.yaml) instead of PROBLEM",
    )
    args = ap.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    name = args.problem
    if args.validation_route is not None:
        args.problem = validation_route(args.validation_route)
        name = f"problems/validate_routes.yaml route {args.validation_route}"
    if args.recording is None:
        args.recording = (
            "results/online/rough.mcap"
            if args.validation_route is None
            else str(Path(args.problem).with_suffix(".mcap"))  # recorded here, not kept
        )
    problem = load_problem(args.problem)
    if args.attitude_margin is not None:  # as a file naming it would plan
        data = copy.deepcopy(problem.data)
        data["planner"]["attitude_margin"] = args.attitude_margin
        problem = problem_from_dict(data, problem.path)
    rec = Path(args.recording)
    if not rec.exists():
        record_route(problem, rec)
    ws = load_or_build_workspace(problem)
    gc.callbacks.append(_gc_clock)
    Follower.update = _timed_update(Follower.update)  # type: ignore[method-assign]
    Follower.spare = _timed_spare(Follower.spare)  # type: ignore[method-assign]
    _counted()
    runs, offline_pose, offline_total, slow, rest, cpu, cpu_rest, first = ([] for _ in range(8))
    spare, busy = [], []
    for _ in range(args.repeats):
        GC_PER_UPDATE.clear()
        WORK_PER_UPDATE.clear()
        CPU_PER_UPDATE.clear()
        SPARE_PER_UPDATE.clear()
        run = follow_recording(problem, rec, ws)
        answer = np.array([x.latency for x in run.steps])
        spare.append(latency_stats(np.array(SPARE_PER_UPDATE)))
        busy.append(latency_stats(answer + np.array(SPARE_PER_UPDATE)))
        cpu.append(latency_stats(np.array(CPU_PER_UPDATE)))
        cpu_rest.append(latency_stats(np.array(CPU_PER_UPDATE[1:])))
        runs.append(summarize(run))
        rest.append(latency_stats(np.array([x.latency for x in run.steps[1:]])))
        first.append(run.steps[0].latency)
        slow.append(slow_maps(run, list(GC_PER_UPDATE), list(WORK_PER_UPDATE)))
        t0 = time.perf_counter()
        off = offline_plan(problem, run, ws)
        offline_total.append((time.perf_counter() - t0) / len(off.s))
        offline_pose.append(float(np.median(off.search_seconds)))
    lat = [r["latency_ms"] for r in runs]
    command = [r["command_latency_ms"] for r in runs]

    def median_of(stats: list[dict[str, float]]) -> dict[str, float]:
        return {k: statistics.median(x[k] for x in stats) for k in ("p50", "p99", "max", "mean")}

    result = {
        "problem": name,
        "attitude_margin": problem.section("planner")["attitude_margin"],
        "recording": str(rec),
        "updates": runs[0]["updates"],
        "replanned_poses": runs[0]["replanned_poses"],
        "online_latency_ms": median_of(lat),  # from the map to the answer
        "command_latency_ms": median_of(command),
        "spare_ms": median_of(spare),  # after the answer
        "busy_ms": median_of(busy),  # answer and spare time: the loop's time per map
        "startup_excluded": {
            "first_map_ms": 1e3 * statistics.median(first),
            "latency_ms": {
                k: statistics.median(x[k] for x in rest) for k in ("p50", "p99", "max", "mean")
            },
        },
        # the same percentiles of the loop thread's processor time per map (what other
        # processes on the shared core do not inflate), and without the first map
        "online_cpu_ms": {
            k: statistics.median(x[k] for x in cpu) for k in ("p50", "p99", "max", "mean")
        },
        "online_cpu_ms_startup_excluded": {
            k: statistics.median(x[k] for x in cpu_rest) for k in ("p50", "p99", "max", "mean")
        },
        "offline_ms_per_pose": {
            "search_median": 1e3 * statistics.median(offline_pose),
            "whole_plan_mean": 1e3 * statistics.median(offline_total),
        },
        "targets_ms": {"p50": 2.0, "p99": 10.0},  # a map every 50-100 ms, an MPC at 4 ms
        "slow_maps": {
            "per_repeat": slow,
            "causes": {c: sum(m["cause"] == c for r in slow for m in r) for c in CAUSES},
            "slowest": max((m for r in slow for m in r), key=lambda m: m["latency_ms"]),
        },
        "repeats": args.repeats,
        "machine": machine_info(one_core=True),
    }
    write_json(args.out, result)
    print(
        f"online: p50 {result['online_latency_ms']['p50']:.2f} ms, p99 "
        f"{result['online_latency_ms']['p99']:.2f} ms per map ({result['updates']} maps); "
        f"offline: {result['offline_ms_per_pose']['search_median']:.2f} ms per pose (search), "
        f"{result['offline_ms_per_pose']['whole_plan_mean']:.2f} ms per pose (whole plan)"
    )
    w, c = result["slow_maps"]["slowest"], result["slow_maps"]["causes"]
    x = result["startup_excluded"]["latency_ms"]
    print(
        f"online: max {result['online_latency_ms']['max']:.1f} ms; the slowest map: "
        f"{w['latency_ms']:.1f} ms, map {w['index']} ({w['cause']}: {w['replanned_poses']} "
        f"poses re-planned, gc {w['gc_ms']:.1f} ms); the slowest 1 % of maps by cause: "
        + ", ".join(f"{k} {v}" for k, v in c.items() if v)
        + f"; without the first map: p50 {x['p50']:.2f}, p99 {x['p99']:.2f}, max {x['max']:.1f} ms"
    )
    y = result["online_cpu_ms"]
    print(f"online CPU: p50 {y['p50']:.2f}, p99 {y['p99']:.2f}, max {y['max']:.1f} ms per map")
    c, b = result["command_latency_ms"], result["busy_ms"]
    print(
        f"online: to the command p50 {c['p50']:.2f}, p99 {c['p99']:.2f} ms; with the spare "
        f"time after the answer p50 {b['p50']:.2f}, p99 {b['p99']:.2f} ms per map"
    )


if __name__ == "__main__":
    main()
