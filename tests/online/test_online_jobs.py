"""The horizon's re-plans as budgeted jobs that land on a fixed map (runs/online/replan_jobs)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_online import problem_file

import mmstab
from mmstab.outputs.recording import record_route
from mmstab.runs.online import roadmap_horizon
from mmstab.runs.online.follow import Follower
from mmstab.runs.online.replan_jobs import LAND_AFTER, Job, Jobs, pause
from mmstab.runs.online.run import FollowRun, follow_recording


def _counting(log: list[str], name: str, pauses: int):
    """A computation that logs each of its steps and returns its name."""

    def compute() -> str:
        for i in range(pauses):
            log.append(f"{name}{i}")
            pause()
        log.append(f"{name}{pauses}")
        return name

    return compute


def test_pause_outside_a_job_does_nothing() -> None:
    pause()  # no coroutine running: returns at once


def test_a_job_is_computed_a_step_a_time_and_lands_on_its_map() -> None:
    log: list[str] = []
    jobs: Jobs[str] = Jobs(budget=0.0)  # no time: one step per map
    jobs.add(Job(_counting(log, "a", 2), land_at=5, invalid=frozenset({7})))
    jobs.advance(until=0.0)
    assert log == ["a0"] and jobs.pending()
    assert jobs.due(4, near={1, 2, 3}) == []  # not due: its map not reached, pose 7 far
    jobs.advance(until=0.0)
    jobs.advance(until=0.0)
    assert log == ["a0", "a1", "a2"] and not jobs.pending()
    assert jobs.due(4, near=set()) == []  # computed, but lands on map 5 only
    assert jobs.due(5, near=set()) == ["a"] and jobs.queue == []
    assert jobs.steps == 3


def test_jobs_are_computed_in_order_and_land_with_those_before() -> None:
    log: list[str] = []
    jobs: Jobs[str] = Jobs(budget=0.0)
    jobs.add(Job(_counting(log, "a", 3), land_at=20, invalid=frozenset()))
    jobs.add(Job(_counting(log, "b", 1), land_at=21, invalid=frozenset({4})))
    jobs.add(Job(_counting(log, "c", 1), land_at=22, invalid=frozenset({9})))
    jobs.advance(until=0.0)
    # pose 4 near: b lands now, a before it; both computed now (a first), c stays queued
    assert jobs.due(3, near={3, 4, 5}) == ["a", "b"]
    assert log == ["a0", "a1", "a2", "a3", "b0", "b1"]
    assert [j.compute() for j in jobs.queue] == ["c"]  # (run by hand: c's own steps)


def test_a_move_that_touches_a_queued_job_lands_it() -> None:
    jobs: Jobs[str] = Jobs(budget=0.0)
    jobs.add(Job(_counting([], "a", 1), land_at=20, invalid=frozenset(), touches=frozenset({3})))
    jobs.add(Job(_counting([], "b", 1), land_at=20, invalid=frozenset(), touches=frozenset({8})))
    assert jobs.due(0, set(), touching={5, 6}) == []
    assert jobs.due(0, set(), touching={2, 3}) == ["a"]
    assert jobs.due(0, set(), everything=True) == ["b"]


def test_without_a_budget_every_job_is_computed_and_lands_at_once() -> None:
    jobs: Jobs[str] = Jobs(budget=None)
    jobs.add(Job(_counting([], "a", 4), land_at=99, invalid=frozenset()))
    assert jobs.due(0, set()) == ["a"]


@pytest.fixture(scope="module")
def seeded(tmp_path_factory: pytest.TempPathFactory) -> tuple[mmstab.Problem, Path]:
    """The first 12 s of the rough route's recording: seeded noise and unknown patches."""
    d = tmp_path_factory.mktemp("seeded")
    problem = mmstab.load_problem(problem_file(d))
    path = d / "rough.mcap"
    record_route(problem, path, duration=12.0)
    return problem, path


def _follow(
    problem: mmstab.Problem, path: Path, budget: float | None, monkeypatch: pytest.MonkeyPatch
) -> tuple[FollowRun, list[dict[int, int]]]:
    """Follow with the re-plans' budget (None: each on its map); the landed nodes per map."""
    nodes: list[dict[int, int]] = []
    update = Follower.update

    def kept(self: Follower, u: object) -> object:
        step = update(self, u)  # type: ignore[arg-type]
        nodes.append(dict(self.horizon.nodes))  # type: ignore[union-attr]
        return step

    with monkeypatch.context() as m:
        m.setattr(roadmap_horizon, "Jobs", lambda: Jobs(budget))
        m.setattr(Follower, "update", kept)
        run = follow_recording(problem, path)
    return run, nodes


@pytest.mark.slow
def test_deferred_re_plans_plan_as_re_planning_at_once(
    seeded: tuple[mmstab.Problem, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The same plans as re-planning every pose on its map; only later, never clock-bound.

    Re-planned on their maps (no budget), with the default budget and with no time at all
    (one step a map): the same re-plans on the same maps and the same final plans; the
    landed nodes lag those of re-planning at once by at most ``LAND_AFTER`` maps and are
    always ones it had; the two budgets give the same answers map by map.
    """
    problem, path = seeded
    now, now_nodes = _follow(problem, path, None, monkeypatch)
    later, later_nodes = _follow(problem, path, 0.005, monkeypatch)
    slow, _ = _follow(problem, path, 0.0, monkeypatch)
    assert len(now.steps) == len(later.steps) == len(slow.steps) > 100
    assert [s.replanned for s in now.steps] == [s.replanned for s in later.steps]
    assert sum(s.replanned for s in now.steps) >= 10
    assert sorted(now.plans) == sorted(later.plans)
    for k, p in now.plans.items():
        q = later.plans[k]
        assert np.array_equal(p.q, q.q) and p.mu == q.mu and p.planned_at == q.planned_at
        assert np.array_equal(p.target_com, q.target_com)
    assert now.arm_ground is not None and later.arm_ground is not None
    for name in ("ground_rescored", "reach_unknown", "unknown_rescored", "moves_plane_only"):
        assert now.arm_ground[name] == later.arm_ground[name], name
    lagged = 0
    for i, landed in enumerate(later_nodes):
        for k, node in landed.items():
            had = [n[k] for n in now_nodes[max(i - LAND_AFTER, 0) : i + 1] if k in n]
            assert node in had, (i, k)  # a node re-planning at once had, not long before
        lagged += landed != now_nodes[i]
    assert lagged > 0  # some re-plans did land later
    for name in ("s", "mu", "q", "qdot", "replanned", "status"):
        a = np.array([getattr(x, name) for x in later.steps])
        b = np.array([getattr(x, name) for x in slow.steps])
        assert np.array_equal(a, b, equal_nan=True), name


def test_the_spare_time_work_waits_for_the_answer(
    seeded: tuple[mmstab.Problem, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The queued re-plans' steps and the moves ahead run after each map's answer
    (``Follower.spare``), never inside ``Follower.update``; a second ``spare`` does nothing."""
    problem, path = seeded
    inside, where = [False], {"update": 0, "spare": 0}
    update, spare, advance = Follower.update, Follower.spare, Jobs.advance

    def in_update(self: Follower, u: object) -> object:
        inside[0] = True
        try:
            return update(self, u)  # type: ignore[arg-type]
        finally:
            inside[0] = False

    def counted(self: Jobs, until: float) -> None:
        where["update" if inside[0] else "spare"] += 1
        advance(self, until)

    def twice(self: Follower) -> float:
        seconds = spare(self)
        assert spare(self) == 0.0  # the map's spare time is spent
        return seconds

    monkeypatch.setattr(Follower, "update", in_update)
    monkeypatch.setattr(Follower, "spare", twice)
    monkeypatch.setattr(Jobs, "advance", counted)
    run = follow_recording(problem, path, limit=60)
    assert len(run.steps) == 60
    assert where["update"] == 0 and where["spare"] > 0
    assert all(x.command_latency <= x.latency for x in run.steps)
