"""The arm's moves computed ahead (runs/online/moves_ahead.py) are the moves computed at once.

A move's paths and cuts (by the nodes masked) are kept from a run on another map, stopped
anywhere; the map that needs the move runs it again with them. Its answer must be the one
it computes alone: on the kerb, where the shortest paths dip and are searched again
without their low nodes, from tries made on a plane, on bumps, or cut short.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_under_arm import GROUND, _map, small  # noqa: F401  (small: the roadmap fixture)

from mmstab.core.steps import drain
from mmstab.model.collision import CollisionChecker
from mmstab.planner.ground.under_arm import GroundUnderArm
from mmstab.planner.grounded import shortcut_above
from mmstab.planner.searches.roadmap.moves import (
    REROUTES,
    _path_nodes,
    ground_move,
    ground_move_steps,
)
from mmstab.runs.online.moves_ahead import MovesAhead

POSE = np.array([[0.0, 0.0, 0.0]])  # beside the kerb


@pytest.fixture(scope="module")
def rerouted(robot, small):  # noqa: F811
    """Pairs of clear nodes whose shortest path and its cut dip into the kerb: searched again."""
    under = GroundUnderArm(robot, _map(robot, "kerb"), POSE)
    up = np.flatnonzero(small.node_ground >= GROUND)
    clear = np.zeros(len(small.nodes_q), dtype=bool)
    clear[up] = under.clear(0, small.nodes_q[up], GROUND)
    checker, pairs = CollisionChecker(robot), []
    for a, b in np.random.default_rng(4).choice(np.flatnonzero(clear), (1500, 2)):
        plain = _path_nodes(small, int(a), int(b), None, GROUND)
        if plain is None or clear[plain].all():
            continue
        tries: dict = {}
        steps = ground_move_steps(robot, small, checker, a, b, GROUND, under, (0,), tries=tries)
        drain(steps)
        if len(tries) > 1:
            pairs.append((int(a), int(b)))
        if len(pairs) == 4:
            break
    assert len(pairs) == 4
    return under, pairs


def _alone(robot, roadmap, checker, a, b, under):
    """The move as computed before its tries could be kept (the loop, written out)."""
    nodes, masked = _path_nodes(roadmap, a, b, None, GROUND), set()
    for _ in range(REROUTES):
        q = roadmap.nodes_q[nodes]
        short = shortcut_above(robot, roadmap, checker, q, GROUND)
        same = len(short) == len(q) and np.array_equal(short, q)
        if not same and under.sweep_clear((0,), short, roadmap.reach, GROUND)[1].all():
            return short
        node_ok, seg_ok = under.sweep_clear((0,), q, roadmap.reach, GROUND)
        if seg_ok.all() and node_ok.all():
            return q
        low = {int(n) for n in nodes[~node_ok]}
        if a in low or b in low:
            return None
        for i in np.flatnonzero(~seg_ok):
            ends = {int(n) for n in nodes[i : i + 2]} - {a, b}
            if not ends:
                return None
            low |= ends
        masked |= low
        nodes = _path_nodes(roadmap, a, b, None, GROUND, frozenset(masked))
        if nodes is None:
            return None
    return None


def _same(x: np.ndarray | None, y: np.ndarray | None) -> bool:
    return (x is None and y is None) or (x is not None and y is not None and np.array_equal(x, y))


@pytest.mark.parametrize("ahead_on", ["flat", "bumps", "kerb"])
def test_a_move_from_tries_made_on_another_map_is_the_move_computed_alone(
    robot,
    small,  # noqa: F811
    rerouted,
    ahead_on,
):
    under, pairs = rerouted
    other = GroundUnderArm(robot, _map(robot, ahead_on), POSE)
    checker = CollisionChecker(robot)
    masked_reused = 0
    for a, b in pairs:
        alone = _alone(robot, small, checker, a, b, under)
        assert _same(ground_move(robot, small, checker, a, b, GROUND, under, (0,)), alone)
        tries: dict = {}
        drain(ground_move_steps(robot, small, checker, a, b, GROUND, other, (0,), tries=tries))
        kept = {m: list(t) for m, t in tries.items()}
        again = ground_move(robot, small, checker, a, b, GROUND, under, (0,), tries=tries)
        assert _same(again, alone)
        assert all(np.array_equal(tries[m][0], t[0]) for m, t in kept.items())  # reused
        masked_reused += sum(1 for m in kept if m)
    if ahead_on == "kerb":
        assert masked_reused > 0  # the same ground masks the same nodes: searches kept


def test_moves_ahead_stepped_a_little_each_map_give_the_moves_computed_alone(
    robot,
    small,  # noqa: F811
    rerouted,
):
    """Steps on a plane, a few at a time (and stopped), then the kerb's map takes each."""
    under, pairs = rerouted
    plane = GroundUnderArm(robot, _map(robot, "flat"), POSE)
    checker = CollisionChecker(robot)
    ahead = MovesAhead(robot, small, checker, GROUND)
    ahead.want(pairs)
    steps = [ahead.advance(0.0, lambda p: plane) for _ in range(12)]  # one step a call
    assert steps == [1] * 12
    for a, b in pairs:
        alone = _alone(robot, small, checker, a, b, under)
        taken = ahead.take(a, b)
        got = ground_move(robot, small, checker, a, b, GROUND, under, (0,), tries=taken)
        assert _same(got, alone)
    assert not ahead.queue and not ahead.running and not ahead.tries


def test_a_pair_chosen_again_is_dropped(robot, small):  # noqa: F811
    ahead = MovesAhead(robot, small, CollisionChecker(robot), GROUND)
    ahead.want([(1, 2), (3, 4)])
    ahead.advance(0.0, lambda p: None)
    assert (1, 2) in ahead.running
    ahead.want([(3, 4)])
    assert ahead.queue == [(3, 4)] and (1, 2) not in ahead.running and (1, 2) not in ahead.tries
