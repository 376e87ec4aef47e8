"""One tip rule for every run (``mmstab.runs.tip_rule``): ``track``'s samples and ``follow``'s
maps call a tip where μ < 0 that no rock catches lasts ``TIP_HOLD``, placed where it began.

The time rule (:func:`first_tip`) is held to the tracking run's chunked sample rule
(:class:`TipWatch`) on seeded random tipping sequences; the online summary is held to the
rule on scripted maps (a rock that holds, a flicker shorter than the hold, a stretch).
"""

from __future__ import annotations

import numpy as np
import pytest
from test_track_tip_rule import Scripted

from mmstab.runs.online.follow import FollowStep
from mmstab.runs.online.run import FollowRun, summarize
from mmstab.runs.tip_rule import TIP_HOLD, first_tip


def watch_tip(mask: np.ndarray, hold: int, chunk: int) -> int | None:
    """The tracking run's answer on ``mask``, chunk after chunk: the absolute index or None."""
    chunks = [mask[i : i + chunk].tolist() for i in range(0, len(mask), chunk)]
    watch = Scripted(chunks, hold, len(mask))
    for c, part in enumerate(chunks):
        at = watch(np.zeros((len(part), 9)))
        if at is not None:
            return c * chunk + at
    return None


@pytest.mark.parametrize("seed", range(6))
def test_the_time_rule_is_the_tracking_runs_sample_rule(seed: int) -> None:
    rng = np.random.default_rng(seed)
    dt = 0.004
    hold = int(round(TIP_HOLD / dt))  # 13 samples
    found = 0
    for _ in range(40):
        n = int(rng.integers(20, 120))
        # runs of tipping samples of random lengths about the hold
        mask = np.zeros(n, dtype=bool)
        for start in rng.integers(0, n, size=int(rng.integers(0, 4))):
            mask[start : start + int(rng.integers(1, 2 * hold))] = True
        times = dt * np.arange(1, n + 1)
        want = watch_tip(mask, hold, int(rng.integers(3, 30)))
        assert first_tip(times, mask, hold * dt) == want
        found += want is not None
    assert found > 5  # the draws hold tips as well as flickers


def step(time: float, mu: float, rocks: bool = False) -> FollowStep:
    """A map's answer with only what the summary reads."""
    z = np.zeros(3)
    return FollowStep(
        time, 0.5 * time, z, True, mu, 300.0, np.zeros(4), np.zeros(6), 0, 0, 0, 1.0, 1e-3,
        np.eye(4), np.zeros((0, 3)), 0.05, np.array([0.0, 0.0, -9.81]), False, rocks=rocks,
    )  # fmt: skip


def tipped(mus: list[float], rocks: list[bool], period: float) -> dict | None:
    steps = [step(period * i, m, r) for i, (m, r) in enumerate(zip(mus, rocks, strict=True))]
    return summarize(FollowRun(steps, {}, 0, np.linspace(0.0, 2.0, 5), 0.8))["tipped"]


def test_follow_tips_where_no_rock_holds_for_the_hold() -> None:
    mus, clear = [200.0, -50.0, 180.0, 190.0], [False] * 4
    # maps 0.1 s apart: one map with μ < 0 stands for 0.1 s, a tip unless a rock holds it
    assert tipped(mus, clear, 0.1) == {"time_s": pytest.approx(0.1), "s_m": pytest.approx(0.05)}
    assert tipped(mus, [False, True, False, False], 0.1) is None
    # maps 10 ms apart: one map is a flicker; five on end (50 ms) a tip, at the first
    assert tipped(mus, clear, 0.01) is None
    long = [200.0] + [-50.0] * 5 + [180.0]
    assert tipped(long, [False] * 7, 0.01)["time_s"] == pytest.approx(0.01)
    # still below at the last map: a tip
    assert tipped([200.0, 150.0, -1.0], [False] * 3, 0.01)["time_s"] == pytest.approx(0.02)
