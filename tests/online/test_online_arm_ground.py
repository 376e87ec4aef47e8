"""The online loop's arm against its map's ground: the record, the exit status, the way
along the planned moves (mmstab.runs.online)."""

from __future__ import annotations

import argparse

import numpy as np
import pytest

from mmstab.cli.online import follow_status
from mmstab.cli.status import EXIT_ARM_COLLISION, EXIT_UNSTABLE
from mmstab.runs.online.follow import FollowStep
from mmstab.runs.online.roadmap_horizon import along, pursue
from mmstab.runs.online.run import FollowRun, summarize


def arc_of(path: np.ndarray, x: np.ndarray) -> tuple[float, float]:
    """The arc length of the polyline's point nearest x, and the distance to it."""
    best = (np.inf, 0.0)
    cum = 0.0
    for a, b in zip(path[:-1], path[1:], strict=True):
        d = b - a
        t = float(np.clip((x - a) @ d / max(d @ d, 1e-18), 0, 1))
        dist = float(np.linalg.norm(a + t * d - x))
        if dist < best[0]:
            best = (dist, cum + t * float(np.linalg.norm(d)))
        cum += float(np.linalg.norm(d))
    return best[1], best[0]


def test_pursue_leads_along_the_polyline_never_back_nor_past_the_cap(rng) -> None:
    for _ in range(200):
        path = np.cumsum(rng.normal(0, 0.4, (int(rng.integers(2, 7)), 4)), axis=0)
        total = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())
        on = rng.uniform(0, total)
        q = along(path, on / total) + rng.normal(0, 0.01, 4)  # near the polyline
        reached, ahead = rng.uniform(0, total), rng.uniform(0.05, 0.5)
        cap = rng.uniform(0, total) if rng.random() < 0.5 else np.inf
        point, made = pursue(path, q, reached, ahead, cap)
        at, off = arc_of(path, point)
        assert off < 1e-9  # on the polyline
        assert made >= reached - 1e-12  # never back
        assert at == pytest.approx(min(made + ahead, cap, total), abs=1e-9)
    # a posture on the polyline, nothing made yet: its own arc length
    path = np.array([[0.0, 0, 0, 0], [1.0, 0, 0, 0], [1.0, 2.0, 0, 0]])
    point, made = pursue(path, np.array([1.0, 0.5, 0, 0]), 0.0, 0.2)
    assert made == pytest.approx(1.5) and np.allclose(point, [1.0, 0.7, 0, 0])


def step(time: float, arm_height: float, covered: bool = True, mu: float = 300.0) -> FollowStep:
    """A map's answer with only what the summary reads."""
    z = np.zeros(3)
    return FollowStep(
        time, 0.5 * time, z, covered, mu, 300.0, np.zeros(4), np.zeros(6), 0, 0, 0, 1.0, 1e-3,
        np.eye(4), np.zeros((0, 3)), 0.05, np.array([0.0, 0.0, -9.81]), False,
        arm_height=arm_height,
    )  # fmt: skip


def test_the_runs_arm_in_ground_record_by_hand() -> None:
    h = [0.1, -0.02, -0.05, 0.03, np.nan, -0.01, -0.3, 0.2]
    covered = [True] * 6 + [False, True]  # an uncovered map is no sample (its -0.3 unread)
    steps = [step(0.1 * i, x, c) for i, (x, c) in enumerate(zip(h, covered, strict=True))]
    got = summarize(FollowRun(steps, {}, 0, np.linspace(0.0, 2.0, 5), 0.8))["arm_in_ground"]
    assert got["contact"] and got["samples"] == 7 and got["unknown_samples"] == 1
    assert got["height_min_m"] == -0.05 and got["at_time_s"] == pytest.approx(0.2)
    want = [(0.1, 0.2, 0.05), (0.5, 0.5, 0.01)]
    assert [(x["start_s"], x["end_s"], x["by"]) for x in got["intervals_s"]] == [
        pytest.approx(w) for w in want
    ]
    clear = summarize(FollowRun([step(0.0, 0.2)], {}, 0, np.linspace(0.0, 2.0, 5), 0.8))
    assert clear["arm_in_ground"]["contact"] is False


def summary(tipped: bool, in_ground: bool) -> dict:
    ground = [{"start_s": 0.6, "end_s": 0.7, "by": 0.108}] if in_ground else []
    return {
        "tipped": {"time_s": 3.0, "s_m": 1.2} if tipped else None,
        "slides": None,
        "friction": 0.7,
        "arm_in_ground": {"contact": in_ground, "intervals_s": ground},
    }


def test_follow_exits_5_for_the_arm_in_the_ground_after_a_tip(capsys) -> None:
    args = argparse.Namespace(allow_unstable=False, allow_sliding=False, allow_collision=False)
    assert follow_status(summary(False, True), args) == EXIT_ARM_COLLISION
    err = capsys.readouterr().err
    assert "the arm is in its map's ground at t = 0.60-0.70 s (up to 10.8 cm in)" in err
    assert follow_status(summary(True, True), args) == EXIT_UNSTABLE  # both said, tip first
    assert "tips over" in (err := capsys.readouterr().err) and "arm collision" in err
    args.allow_collision = True
    assert follow_status(summary(False, True), args) is None
    assert "warning" in capsys.readouterr().err
    assert follow_status(summary(False, False), args) is None


def test_a_move_the_arm_cannot_start_is_passed_over_once() -> None:
    """The arm's posture at a chain's start reaches no roadmap node: the step takes the plan's
    own reference (None) instead of failing, does not try that move again, and leads the arm
    along the next planned pose's move."""
    from mmstab.core.files import MmstabError
    from mmstab.runs.online.follow import Follower
    from mmstab.runs.online.roadmap_horizon import RoadmapHorizon

    tried: list[int] = []

    class Horizon(RoadmapHorizon):
        def __init__(self) -> None:  # only what the way reads
            self.plans = {0: None, 1: None}  # type: ignore[dict-item]
            self.s_grid = np.array([0.0, 0.5])

        def schedule(self, s: float, spacing: float) -> tuple[int, float]:
            return 1, 0.5

        def move_key(self, k: int) -> tuple[int | None, int]:
            return (None, 7) if k == 0 else (7, 9)

        def move(self, k: int) -> np.ndarray:
            tried.append(k)
            if k == 0:
                raise MmstabError("roadmap: the posture [3.8, -0.2, 0.9, 2.2] rad reaches no node")
            return np.array([[0.0, 0, 0, 0], [1.0, 0, 0, 0]])

    f = object.__new__(Follower)
    f.horizon, f.way, f.no_way = Horizon(), None, set()
    q = np.array([0.1, 0.0, 0.0, 0.0])
    assert f._way(q, 0.25) is None and tried == [0]
    got = f._way(q, 0.25)  # move 1, from the arm's nearest point, up to half of it
    assert tried == [0, 1] and np.allclose(got, [0.3, 0, 0, 0])
    f._way(q, 0.25)
    assert 0 not in tried[2:]
