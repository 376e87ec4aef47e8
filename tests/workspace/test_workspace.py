"""Workspace V: collision labels, culling vs brute force, hull difference, cache, fig3 CLI."""

from __future__ import annotations

import itertools
import json
import os
import subprocess
import sys
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor

import numpy as np
import pytest
from conftest import random_postures, write_problem

import mmstab.workspace as wsm
from mmstab.core.files import ConfigError, MmstabError
from mmstab.core.problem import load_problem
from mmstab.model.collision import CollisionChecker
from mmstab.workspace import (
    arm_com_from_frames,
    build_workspace,
    grid_postures,
    joint_grid,
    load_or_build_workspace,
    workspace_from_clouds,
)
from mmstab.workspace.fidelity import measure_fidelity

COARSE = [6, 6, 6, 6]


@pytest.fixture(scope="module")
def checker(robot):
    return CollisionChecker(robot)


@pytest.fixture(scope="module")
def coarse(robot):
    return build_workspace(robot, COARSE, progress=False)


def _set_grid(grid):
    def edit(p, r):
        p["workspace"]["grid"] = grid

    return edit


# ----------------------------------------------------------------------- collision labels
def _aim_at(robot, target):
    """Posture with joints 1-3 stretched in one line from the joint-1 axis through target."""
    axis = robot.kinematics.link_frames(np.zeros(4))[0][:3, 3]  # joint-1 axis: fixed point
    d = target - axis
    return np.array(
        [np.arctan2(d[1], d[0]) % (2 * np.pi), np.arctan2(d[2], np.hypot(*d[:2])), 0, 0]
    )


def test_stretched_arm_through_a_raised_flipper(robot, checker):
    flipper = robot.base.flippers
    tip_dir = np.array([np.cos(flipper.angle), 0, np.sin(flipper.angle)])
    for side, sign in (("left", 1.0), ("right", -1.0)):
        pivot = flipper.pivot * [1, sign, 1]
        # a point of the flipper's centre line ahead of the tracks' front end
        target = pivot + tip_dir * 0.75 * flipper.length
        assert target[0] > robot.base.tracks.length / 2
        q = _aim_at(robot, target)
        assert checker.colliding_pairs(q) == [f"upper_arm-flipper_{side}"]
        assert checker.collides(q)


@pytest.mark.parametrize(
    ("q", "pair"),
    [
        # upper arm at its lowest pitch, pointing back over the body: it dives into the body
        ([np.pi, -0.8, 0.0, 0.0], "upper_arm-body"),
        # pointing left at the lowest pitch: through the body and the left track
        ([np.pi / 2, -0.8, 0.0, 0.0], "upper_arm-track_left"),
        # forearm folded fully down under a slightly raised upper arm: wrist into the body
        ([0.0, 0.5, -2.9, 0.0], "wrist-body"),
        # forearm folded back up and the wrist folded down onto the upper arm
        ([0.0, 1.2, -2.9, -2.2], "upper_arm-wrist"),
    ],
)
def test_folded_postures_collide(checker, q, pair):
    assert pair in checker.colliding_pairs(q)
    assert checker.collides(q) is True


@pytest.mark.parametrize("q0", [0.0, np.pi / 2, 2.0, np.pi, 5.0])
def test_stretched_and_stowed_postures_are_free(robot, checker, q0):
    assert checker.colliding_pairs([q0, 0, 0, 0]) == []
    assert checker.colliding_pairs(robot.stowed) == []
    assert checker.collides(np.array([[q0, 0, 0, 0], robot.stowed])).tolist() == [False, False]


def test_culling_never_changes_the_answer(robot, checker, rng):
    q = random_postures(robot, rng, 2000)
    fast = checker.collides(q)
    assert 0.1 < fast.mean() < 0.9  # both labels occur, so the comparison means something
    np.testing.assert_array_equal(fast, checker.collides(q, cull=False))
    # grid postures: many share joints, so the answer reuse is exercised too
    g = grid_postures(joint_grid(robot, [7, 6, 6, 5]))
    np.testing.assert_array_equal(checker.collides(g), checker.collides(g, cull=False))


@pytest.mark.parametrize("j", range(4))
def test_a_free_posture_moved_in_one_joint_checks_only_the_pairs_it_moves(robot, checker, rng, j):
    """``collides(moving=j)``: the roadmap's edge checks skip the pairs joint j does not move."""
    q = random_postures(robot, rng, 3000)
    free = q[~checker.collides(q, cull=False)]
    moved = free.copy()
    moved[:, j] += rng.uniform(-0.8, 0.8, len(free))
    expected = checker.collides(moved, cull=False)
    assert 10 < expected.sum() < 0.9 * len(expected)  # the moves do collide at times
    np.testing.assert_array_equal(checker.collides(moved, moving=j), expected)
    skipped = [p for p in checker.pairs if j not in p.columns]
    assert skipped  # the turret moves no link against another, the wrist no link but itself


@pytest.mark.parametrize("j", range(4))
def test_edge_moves_grouped_once_per_joint_are_fcl_on_every_pair(robot, checker, rng, j):
    """``free_moves``: the rows' groups found once per joint give FCL's answer on every pair
    at every interior posture of every edge, row by row."""
    from mmstab.workspace.roadmap_checks import free_moves, groups_of, move_groups

    g = grid_postures(joint_grid(robot, [7, 6, 6, 5]))
    nodes = g[~checker.collides(g, cull=False)]
    nodes = nodes[rng.permutation(len(nodes))]  # grouped rows out of grid order
    step, steps = 1.5, 5
    got = free_moves(checker, nodes, j, step, steps)
    shifts = [nodes + np.eye(4)[j] * step * s / (steps + 1) for s in range(1, steps + 1)]
    expected = ~np.any([checker.collides(q, cull=False) for q in shifts], axis=0)
    assert 40 < (~expected).sum() < 0.3 * len(expected)  # some moves collide, most do not
    np.testing.assert_array_equal(got, expected)
    # the groups handed in are the caller's: a call that groups other pairs adds none to them
    part = np.arange(len(nodes))
    given = groups_of(move_groups(checker, nodes, j), part)
    keys = set(given)
    np.testing.assert_array_equal(checker.collides(nodes, groups=given), np.zeros(len(nodes), bool))
    assert set(given) == keys and {p.columns for p in checker.pairs} - keys


def test_capsule_shape_follows_its_segment(robot, checker):
    q = np.array([[0.3, 0.4, -0.5, 0.6]])
    R, p = checker.shape_poses(q)
    frames = robot.kinematics.link_frames(q)[0]
    for i, link in enumerate(robot.links[1:], start=1):
        g = link.geometry
        ends = (frames[i][:3, :3] @ np.array([g.p0, g.p1]).T).T + frames[i][:3, 3]
        axis = R[0, i][:, 2] * g.length / 2  # capsule along its local z
        np.testing.assert_allclose(
            np.sort([p[0, i] - axis, p[0, i] + axis], axis=0), np.sort(ends, axis=0), atol=1e-12
        )


# --------------------------------------------------------------------------------- grid
def test_joint_grid_skips_the_repeated_end_of_a_full_turn(robot):
    jg = joint_grid(robot, [8, 5, 6, 7])
    assert jg.shape == (8, 5, 6, 7) and jg.size == 8 * 5 * 6 * 7
    assert jg.axes[0][0] == 0 and np.isclose(jg.axes[0][-1], 2 * np.pi * 7 / 8)
    np.testing.assert_allclose(jg.step[0], 2 * np.pi / 8)
    for j in (1, 2, 3):
        assert jg.axes[j][0] == robot.joint_lower[j] and jg.axes[j][-1] == robot.joint_upper[j]
        np.testing.assert_allclose(np.diff(jg.axes[j]), jg.step[j])


def test_grid_postures_enumerate_the_product_once(robot):
    jg = joint_grid(robot, [4, 3, 2, 3])
    q = grid_postures(jg)
    expected = np.array(list(itertools.product(*jg.axes)))
    assert len(q) == jg.size
    assert sorted(map(tuple, q)) == sorted(map(tuple, expected))
    np.testing.assert_array_equal(grid_postures(jg, 5, 17), q[5:17])


def test_arm_com_from_frames_matches_kinematics(robot, rng):
    q = random_postures(robot, rng, 50)
    np.testing.assert_allclose(
        arm_com_from_frames(robot, robot.kinematics.link_frames(q)), robot.arm_com(q), atol=1e-12
    )


# -------------------------------------------------------------------------- hull difference
def _cube(half, n=5):
    s = np.linspace(-half, half, n)
    return np.array(list(itertools.product(s, s, s)))


def test_hull_difference_cube_minus_cube():
    outer, inner = _cube(1.0), _cube(0.5)
    ws = workspace_from_clouds(
        (2, 2, 2, 2), np.zeros((len(outer), 4)), outer, np.zeros((len(inner), 4)), inner
    )
    assert len(ws.b_all) == 6 and len(ws.b_bad) == 6  # coplanar triangles merged
    pts = np.array(
        [
            [0, 0, 0],
            [0.4, -0.4, 0.4],
            [0.75, 0, 0],
            [0, -0.9, 0.9],
            [1, 1, 1],
            [0.5, 0, 0],
            [1.2, 0, 0],
            [0, 0, -1.01],
        ]
    )
    # (0.5, 0, 0) is on the boundary of hull(invalid): not in V (docs/design.md, "Workspace")
    assert ws.contains(pts).tolist() == [False, False, True, True, True, False, False, False]
    assert ws.contains([0.75, 0.0, 0.0]).tolist() == [True]
    np.testing.assert_allclose(ws.diameter, 2 * np.sqrt(3))
    np.testing.assert_allclose([ws.volume_all, ws.volume_invalid, ws.volume_V], [8, 1, 7])


def test_violation_is_the_distance_to_the_nearest_facet_and_zero_exactly_in_V(rng):
    outer, inner = _cube(1.0), _cube(0.5)
    ws = workspace_from_clouds(
        (2, 2, 2, 2), np.zeros((len(outer), 4)), outer, np.zeros((len(inner), 4)), inner
    )
    # outside hull(all): distance past the face; inside hull(invalid): depth to its face
    np.testing.assert_allclose(
        ws.violation([[1.3, 0, 0], [0, 0, 0], [0.4, 0.1, 0], [0.75, 0, 0]]),
        [0.3, 0.5, 0.1, 0.0],
        atol=1e-12,
    )
    pts = rng.uniform(-1.5, 1.5, (5000, 3))
    v = ws.violation(pts)
    assert np.array_equal(v == 0, ws.contains(pts)) and np.all(v >= 0)


def test_no_invalid_posture_means_no_subtraction():
    outer = _cube(1.0, 3)
    ws = workspace_from_clouds((2, 2, 2, 2), np.zeros((27, 4)), outer, [], [])
    assert ws.A_bad.shape == (0, 3) and ws.volume_invalid == 0
    assert ws.contains([[0, 0, 0], [0.99, 0, 0], [1.01, 0, 0]]).tolist() == [True, True, False]


@pytest.mark.parametrize(
    ("invalid", "message"),
    [
        (np.array([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0]]), "3 points"),
        (np.c_[np.random.default_rng(0).uniform(-0.5, 0.5, (20, 2)), np.zeros(20)], "plane"),
    ],
)
def test_degenerate_invalid_cloud_is_a_clear_error(invalid, message):
    outer = _cube(1.0, 3)
    with pytest.raises(MmstabError, match=f"invalid.*{message}"):
        workspace_from_clouds(
            (2,) * 4, np.zeros((27, 4)), outer, np.zeros((len(invalid), 4)), invalid
        )


def test_flat_cloud_of_all_coms_is_a_clear_error():
    flat = np.c_[np.random.default_rng(1).uniform(size=(30, 2)), np.full(30, 0.3)]
    with pytest.raises(MmstabError, match="all arm CoMs.*plane"):
        workspace_from_clouds((2,) * 4, np.zeros((30, 4)), flat, [], [])


# ------------------------------------------------------------------------ built workspace
def test_coarse_workspace_labels_and_clouds(robot, checker, coarse):
    q = grid_postures(joint_grid(robot, COARSE))
    free = ~checker.collides(q, cull=False)
    assert coarse.postures == 6**4
    assert len(coarse.valid_q) == free.sum() and len(coarse.invalid_q) == (~free).sum()
    assert sorted(map(tuple, coarse.valid_q)) == sorted(map(tuple, q[free]))
    np.testing.assert_allclose(coarse.valid_com, robot.arm_com(coarse.valid_q), atol=1e-12)
    np.testing.assert_allclose(coarse.invalid_com, robot.arm_com(coarse.invalid_q), atol=1e-12)
    # every CoM is in hull(all); no invalid CoM is in V (it lies in hull(invalid))
    everything = np.vstack([coarse.valid_com, coarse.invalid_com])
    assert np.all(everything @ coarse.A_all.T <= coarse.b_all[None] + 1e-9)
    assert not coarse.contains(coarse.invalid_com).any()
    far = everything[np.argmax(np.linalg.norm(everything - everything[0], axis=1))]
    assert coarse.diameter >= np.linalg.norm(far - everything[0])


@pytest.mark.parametrize("make", [lambda: ThreadPoolExecutor(2), lambda: ProcessPoolExecutor(2)])
def test_any_executor_gives_the_same_workspace(robot, coarse, make):
    with make() as ex:
        other = build_workspace(robot, COARSE, executor=ex, chunk=200, progress=False)
    for name in ("valid_q", "valid_com", "invalid_q", "A_all", "b_all", "A_bad", "b_bad"):
        np.testing.assert_array_equal(getattr(other, name), getattr(coarse, name))


def test_nearest_valid_posture(robot, coarse, rng):
    np.testing.assert_array_equal(
        coarse.nearest_valid_posture(coarse.valid_com[7]), coarse.valid_q[7]
    )
    points = rng.uniform(-0.5, 0.5, (20, 3))
    got = coarse.nearest_valid_posture(points)
    d = np.linalg.norm(coarse.valid_com[None] - points[:, None], axis=2)
    np.testing.assert_allclose(robot.arm_com(got), coarse.valid_com[d.argmin(axis=1)])


def test_fidelity_numbers(robot, coarse):
    fid = measure_fidelity(robot, coarse, samples=500, seed=4)
    assert fid.recall == coarse.contains(coarse.valid_com).mean() and 0 < fid.recall <= 1
    assert 0 <= fid.precision_half_cell <= fid.precision <= 1 and fid.samples == 500
    # a cell of the coarse grid is larger than one of the 24^4 grid
    fine = measure_fidelity(robot, build_workspace(robot, [8, 8, 8, 8], progress=False), 10, 4)
    assert fid.cell_size > fine.cell_size > 0
    assert measure_fidelity(robot, coarse, samples=500, seed=4) == fid  # seeded


# ---------------------------------------------------------------------------------- cache
def test_cache_reused_then_invalidated_by_a_robot_change(tmp_path, monkeypatch):
    problem = load_problem(write_problem(tmp_path, _set_grid(COARSE)))
    cache = tmp_path / "cache"
    built = []
    real_build = wsm.build_workspace

    def counting_build(*args, **kwargs):
        built.append(args[1])
        return real_build(*args, **kwargs)

    monkeypatch.setattr(wsm.cache, "build_workspace", counting_build)
    first = load_or_build_workspace(problem, progress=False, cache_dir=cache)
    files = list(cache.glob("*.npz"))
    assert len(built) == 1 and len(files) == 1
    mtime = files[0].stat().st_mtime_ns
    again = load_or_build_workspace(problem, progress=False, cache_dir=cache)
    assert len(built) == 1 and files[0].stat().st_mtime_ns == mtime
    np.testing.assert_array_equal(again.valid_com, first.valid_com)
    np.testing.assert_array_equal(again.b_bad, first.b_bad)
    assert again.grid == first.grid == tuple(COARSE) and again.diameter == first.diameter
    load_or_build_workspace(problem, force=True, progress=False, cache_dir=cache)
    assert len(built) == 2

    def fatter_wrist(p, r):
        _set_grid(COARSE)(p, r)
        r["arm"]["links"][3]["geometry"]["radius"] = 0.05

    changed = load_problem(write_problem(tmp_path, fatter_wrist))
    other = load_or_build_workspace(changed, progress=False, cache_dir=cache)
    assert len(built) == 3 and len(list(cache.glob("*.npz"))) == 2
    assert len(other.invalid_q) > len(first.invalid_q)  # a fatter wrist collides more


def test_bad_workspace_grid_names_the_field(tmp_path):
    path = write_problem(tmp_path, _set_grid([24, 1, 24, 24]))
    with pytest.raises(ConfigError, match=r"problem.yaml: workspace.grid\[1\]"):
        load_problem(path)


# ------------------------------------------------------------------------------------ CLI
@pytest.mark.slow
def test_fig3_and_workspace_commands(tmp_path):
    problem = write_problem(tmp_path, _set_grid([8, 6, 6, 6]))
    env = {**os.environ, "MPLBACKEND": "Agg", "MMSTAB_CACHE": str(tmp_path / "cache")}

    def run(*args, program="mmstab"):
        return subprocess.run(
            [sys.executable, "-m", program, *args],
            check=True,
            env=env,
            cwd=tmp_path,
            capture_output=True,
            text=True,
        ).stdout

    out = run("fig3", str(problem), "-o", "fig3", program="experiments")
    s = json.loads((tmp_path / "fig3" / "summary.json").read_text())
    assert s["postures"] == 8 * 6**3 == s["valid"] + s["invalid"] and s["invalid"] > 0
    assert 0 < s["recall"] <= 1 and 0 <= s["precision"] <= 1
    assert 0 < s["volume_invalid"] < s["volume_all"]
    assert s["volume_V"] == pytest.approx(s["volume_all"] - s["volume_invalid"])
    assert s["diameter"] > 0 and s["build_seconds"] > 0
    assert s["postures_per_second"] == pytest.approx(s["postures"] / s["build_seconds"])
    for name in ("fig3a_V.png", "fig3b_invalid_hull.png", "fig3c_all_hull.png"):
        assert (tmp_path / "fig3" / name).stat().st_size > 10_000
    assert f"{s['valid']} valid" in out
    # fig3 cached the workspace in the cache folder ($MMSTAB_CACHE); the command reuses it
    out = run("workspace", str(problem))
    assert f"{s['postures']} postures, {s['valid']} valid, {s['invalid']} invalid" in out
    assert "loaded" in out and len(list((tmp_path / "cache").glob("*.npz"))) == 1
    assert not (tmp_path / "results").exists()  # nothing in the working folder
    assert "built" in run("workspace", str(problem), "--force")


def test_mmstab_cache_moves_the_cache_for_every_working_folder(tmp_path):
    problem = write_problem(tmp_path, _set_grid([6, 5, 5, 5]))
    cache, one, two = tmp_path / "shared cache", tmp_path / "one", tmp_path / "two"
    one.mkdir(), two.mkdir()
    env = {**os.environ, "MPLBACKEND": "Agg", "MMSTAB_CACHE": str(cache)}

    def run(cwd):
        cmd = [sys.executable, "-m", "mmstab", "workspace", str(problem)]
        return subprocess.run(cmd, check=True, env=env, cwd=cwd, capture_output=True, text=True)

    assert "built" in run(one).stdout
    assert "loaded" in run(two).stdout  # another folder, the same cache
    assert len(list(cache.glob("*.npz"))) == 1
    assert not (one / "results" / "workspace").exists() and not (two / "results").exists()
