"""``method: sequence``: V's postures chosen along the whole path at once."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from test_turret_window import coarse  # noqa: F401  (module fixture: coarse problem + V)

from mmstab.core.files import MmstabError
from mmstab.model.collision import CollisionChecker
from mmstab.model.plane_clearance import arm_ground_clearance, lowest_along_moves
from mmstab.model.reach import joint_reach
from mmstab.planner import PlannerSettings, gravity_body_at, pose_fitness, solve_path
from mmstab.planner.regions import as_region
from mmstab.planner.searches.coarse import sample_index
from mmstab.planner.searches.sequence import (
    MoveCheck,
    _Graph,
    _search_lazily,
    _viterbi,
    segments_collide,
    solve_sequence,
)
from mmstab.planner.turret import sample_postures
from mmstab.stability.static import mu_max
from mmstab.workspace.roadmap import CLEARANCE_STEP

WINDOW = 0.8  # [rad]


def _settings(problem, **changes):
    s = PlannerSettings.from_section(problem.section("planner"))
    base = {"method": "sequence", "turret_window": WINDOW, "sequence_candidates": 64}
    return s._replace(**{**base, **changes})


def test_viterbi_equals_brute_force(rng):
    K, M = 4, 5
    value = rng.normal(size=(K, M))
    motion = [rng.uniform(0, 1, (M, M)) for _ in range(K - 1)]
    allowed = [rng.uniform(size=(M, M)) > 0.3 for _ in range(K - 1)]
    best, best_path = -np.inf, None
    for path in itertools.product(range(M), repeat=K):
        if not all(allowed[k][path[k], path[k + 1]] for k in range(K - 1)):
            continue
        total = sum(value[k, path[k]] for k in range(K)) - sum(
            motion[k][path[k], path[k + 1]] for k in range(K - 1)
        )
        if total > best:
            best, best_path = total, path
    path, total = _viterbi(value, motion, allowed)
    assert total == pytest.approx(best, abs=1e-12)
    assert tuple(path) == best_path


def test_sequence_moves_are_collision_free_and_within_the_window(coarse):  # noqa: F811
    problem, ws = coarse
    robot = problem.robot
    s = _settings(problem)
    poses = problem.circle.poses(s.poses)
    plan = solve_path(robot, problem.terrain, ws, poses, s, closed=True)
    q = plan.postures
    assert plan.collision_free.all()
    np.testing.assert_allclose(robot.arm_com(q), plan.target_com, atol=1e-12)
    assert not CollisionChecker(robot).collides(q).any()
    nxt = np.roll(q, -1, axis=0)  # every move, the closing one included
    assert np.all(np.abs(nxt[:, 0] - q[:, 0]) <= WINDOW + 1e-9)
    assert not segments_collide(CollisionChecker(robot), q, nxt).any()
    # fitness per pose is Eq. 6 with the previous pose's choice as previous CoM
    for k, t in enumerate(plan.targets):
        fitness = pose_fitness(
            robot,
            gravity_body_at(problem.terrain, t.pose)[0],
            plan.target_com[k - 1],  # k = 0: the closing move from the last pose
            s,
            mu_max(robot),
            ws.diameter,
        )
        assert t.fitness == pytest.approx(fitness(t.target_com)[0], abs=1e-9)
        assert t.mu == pytest.approx(fitness.mu(t.target_com)[0], abs=1e-9)


def test_sequence_without_constraints_is_the_per_pose_optimum_of_its_sum(coarse):  # noqa: F811
    """With no motion term, no window and only one pose, it is the exhaustive optimum."""
    problem, ws = coarse
    robot = problem.robot
    s = _settings(problem, w_stability=1.0, w_motion=0.0, turret_window=None)
    pose = problem.circle.poses(10)[3]
    g = gravity_body_at(problem.terrain, pose)
    f = pose_fitness(robot, g[0], robot.arm_com(robot.stowed), s, mu_max(robot), ws.diameter)
    mu = f.mu(sample_index(ws).samples)
    seq = solve_sequence(robot, g, ws, s._replace(ground_clearance=None), mu_max(robot), False)
    assert seq.mu[0] == pytest.approx(mu.max(), abs=1e-9)
    # with the ground check: the optimum over the samples whose arm clears the plane
    above = arm_ground_clearance(robot, as_region(ws).postures) >= s.ground_clearance
    seq = solve_sequence(robot, g, ws, s, mu_max(robot), closed=False)
    assert seq.mu[0] == pytest.approx(mu[above].max(), abs=1e-9)


def test_sequence_is_refused_when_nothing_fits(coarse):  # noqa: F811
    problem, ws = coarse
    s = _settings(problem, turret_window=1e-6, sequence_candidates=1)
    g = gravity_body_at(problem.terrain, problem.circle.poses(3))
    postures = sample_postures(ws)
    assert len(np.unique(postures[:, 0])) > 1
    with pytest.raises(MmstabError, match="no sequence"):
        solve_sequence(problem.robot, g, ws, s, mu_max(problem.robot), closed=True)


@pytest.mark.slow
def test_the_default_plan_is_tracked_without_collision_or_saturation(tmp_path):
    """The default problem's plan (method sequence), on a coarse V, tracked for a full lap."""
    from conftest import write_problem

    from mmstab.core.problem import load_problem
    from mmstab.planner import plan_path
    from mmstab.runs.tracking import simulate, summarize
    from mmstab.runs.tracking.checks import arm_collisions
    from mmstab.workspace import load_or_build_workspace

    path = write_problem(tmp_path, lambda p, r: p["workspace"].__setitem__("grid", COARSE))
    problem = load_problem(path)
    assert problem.section("planner")["method"] == "sequence"
    ws = load_or_build_workspace(problem, progress=False, cache_dir=tmp_path / "cache")
    plan = plan_path(problem, workspace=ws)
    run = simulate(problem, plan, progress=False)
    s = summarize(run)
    assert s["qp_failures"] == 0
    keep = np.arange(0, run.t.size, 10)  # every 10 ms, as the tracking experiment checks
    assert arm_collisions(problem.robot, run.t[keep], run.state[keep, 5:])["colliding_samples"] == 0
    assert s["last_saturated_time_s"] is None or s["last_saturated_time_s"] <= 1.0  # approach
    assert s["after_transient"]["arm_com_error_max_m"] < 0.005
    assert s["after_transient"]["base_error_max_m"] < 0.005
    # after the approach the reconfigured arm stays above the stowed and the removed arm
    mu = s["after_transient"]["mu_min"]
    assert mu["reconfigured"] > mu["stowed"] > mu["arm_removed"]


COARSE = [10, 8, 8, 8]


def test_diverse_top_by_bins_equals_the_full_sort(rng):
    from mmstab.planner.searches.sequence import _diverse_top, _turret_bins

    values = np.round(rng.normal(size=5000), 2)  # ties included
    bins = _turret_bins(rng.uniform(0, 6.28, 5000), 24)
    members = [np.flatnonzero(bins == b) for b in range(24)]
    for count in (1, 7, 64, 300):
        fast = _diverse_top(values, bins, count, members)
        np.testing.assert_array_equal(fast, _diverse_top(values, bins, count))


def test_the_sequence_plan_keeps_the_arm_above_the_plane(coarse):  # noqa: F811
    """Every posture and every move (the closing one too) keeps ground_clearance up."""
    problem, ws = coarse
    robot = problem.robot
    s = _settings(problem)
    assert s.ground_clearance == 0.02  # the default
    g = gravity_body_at(problem.terrain, problem.circle.poses(s.poses))
    region = as_region(ws)
    seq = solve_sequence(robot, g, ws, s, mu_max(robot), closed=True)
    q = region.postures[seq.rows]
    assert arm_ground_clearance(robot, q).min() >= s.ground_clearance
    nxt = np.roll(q, -1, axis=0)  # sampled 4x finer than the check's own rule
    reach = joint_reach(robot, region.valid_q)
    low = lowest_along_moves(robot, reach, q, nxt, CLEARANCE_STEP / 4)
    assert low.min() >= s.ground_clearance - 1e-3  # the 4 mm rule: ~mm between samples
    # V holds postures in the ground: the check is what keeps them out of the candidates
    below = arm_ground_clearance(robot, region.postures) < s.ground_clearance
    assert below.any()
    assert not below[seq.rows].any()


def test_a_move_dipping_below_the_plane_is_refused(coarse):  # noqa: F811
    """Two postures above the plane whose straight wrist move sweeps through the ground."""
    problem, _ = coarse
    robot = problem.robot
    a = np.array([4.54, 0.65, -1.85, -1.98])  # wrist swung one way ...
    b = np.array([4.54, 0.65, -1.85, 0.86])  # ... and the other: the move points it down
    c = np.array([4.54, 0.65, -1.85, 1.3])
    q = np.array([a, b, c])
    checker = CollisionChecker(robot)
    reach = joint_reach(robot, q)
    assert arm_ground_clearance(robot, q).min() >= 0.02
    assert not segments_collide(checker, q[[0, 2]], q[[1, 1]]).any()
    low = lowest_along_moves(robot, reach, q[[0, 2]], q[[1, 1]], CLEARANCE_STEP)
    assert low[0] < 0.0 < 0.02 <= low[1]
    check = MoveCheck(checker, robot, reach, 0.02)
    np.testing.assert_array_equal(check.refused(q[[0, 2]], q[[1, 1]]), [True, False])
    assert not MoveCheck(checker, robot, reach).refused(q[[0]], q[[1]]).any()  # no ground check
    # the search: pose 0 prefers a (value 1 against 0.5), pose 1 has b only
    graph = _Graph(
        cand=np.array([[0, 2], [1, 1]]),
        value=np.array([[1.0, 0.5], [0.0, -np.inf]]),
        fits=[],
        pairs=[(0, 1)],
        motion=[np.zeros((2, 2))],
        allowed=[np.ones((2, 2), dtype=bool)],
    )
    path, _, forbidden = _search_lazily(graph, q, MoveCheck(checker, robot, reach), closed=False)
    assert path.tolist() == [0, 0]  # unchecked: a, through the ground
    graph.allowed[0][:] = True
    path, rounds, forbidden = _search_lazily(graph, q, check, closed=False)
    assert path.tolist() == [1, 0] and forbidden == 1 and rounds == 2  # c, above
