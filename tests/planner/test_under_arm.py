"""planner.ground_clearance against the ground under the arm (mmstab.planner.ground.under_arm).

On a plane the check is the support-plane check; on bumps and kerbs a dense independent
check (points over every link's collision shape, the heightmap's own bilinear surface at
their map x, y) finds every planned posture ``ground_clearance`` above the ground at its pose
and every move above the ground of both poses it joins, where the plane check alone lets
the arm into the ground. Coarse roadmaps throughout.
"""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from conftest import PROBLEMS

from mmstab.core.problem import load_problem
from mmstab.model.parts import Box
from mmstab.planner import PlannerSettings
from mmstab.planner.ground.under_arm import SWEEP, GroundUnderArm
from mmstab.planner.searches.roadmap import solve_roadmap_sequence
from mmstab.stability.static import mu_max
from mmstab.terrain.generators import (
    Grid,
    bumps,
    bumps_elevation,
    kerb,
    plane,
    plane_elevation,
)
from mmstab.terrain.heightmap_terrain import HeightmapTerrain
from mmstab.workspace import build_workspace
from mmstab.workspace.roadmap import build_roadmap

GRID = (10, 8, 8, 8)
GROUND = 0.05
#: Round-off of the dense check's placements [m] (the check is exact on lattice-aligned maps).
TOL = 1e-9


@pytest.fixture(scope="module")
def small(robot):
    return build_roadmap(robot, build_workspace(robot, GRID, progress=False))


def _settings(ground: float | None) -> PlannerSettings:
    s = PlannerSettings.from_section(
        yaml.safe_load((PROBLEMS / "kerb.yaml").read_text())["planner"]
    )
    return s._replace(method="roadmap", ground_clearance=ground)


def _sphere(n: int = 96) -> np.ndarray:
    """n unit directions spread over the sphere (a Fibonacci lattice)."""
    i = np.arange(n) + 0.5
    z, phi = 1 - 2 * i / n, np.pi * (1 + 5**0.5) * i
    r = np.sqrt(1 - z**2)
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def _shape_points(g) -> np.ndarray:
    """Many points over a link's collision shape's surface, in the link frame (~1-2 cm apart)."""
    u = np.linspace(0.0, 1.0, 21)
    if isinstance(g, Box):
        s = np.stack(np.meshgrid(u, u, u), -1).reshape(-1, 3) - 0.5
        R = g.frame_T_shape[:3, :3]
        return (s * g.size) @ R.T + g.center
    axis = g.p1 - g.p0
    ring = np.linspace(0.0, 2 * np.pi, 24, endpoint=False)
    e1 = np.cross(axis, [0.0, 0.0, 1.0] if abs(axis[2]) < 0.9 * np.linalg.norm(axis) else [1, 0, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis / np.linalg.norm(axis), e1)
    # the capsule's surface: its side and its end spheres
    across = np.cos(ring)[:, None] * e1 + np.sin(ring)[:, None] * e2
    side = g.p0 + u[:, None, None] * axis + g.radius * across[None]
    caps = np.vstack([g.p0 + g.radius * _sphere(), g.p1 + g.radius * _sphere()])
    return np.vstack([side.reshape(-1, 3), caps])


def dense_heights(robot, terrain, M_T_B: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Least height of the arm above the ground under it, per posture (n,) [m], densely."""
    q = np.atleast_2d(q)
    frames = robot.kinematics.link_frames(q)
    M_T_G = np.linalg.inv(terrain.G_T_M())
    low = np.full(len(q), np.inf)
    for i, link in enumerate(robot.links):
        g = link.geometry
        pts = _shape_points(g)
        # (BLAS: the einsum took most of these tests' time)
        p_B = pts @ frames[:, i, :3, :3].transpose(0, 2, 1) + frames[:, i, None, :3, 3]
        p_M = p_B @ M_T_B[:3, :3].T + M_T_B[:3, 3]
        x, y = p_M[..., 0], p_M[..., 1]
        b = terrain.bounds
        if b is not None:
            x, y = np.clip(x, b[0], b[1]), np.clip(y, b[2], b[3])
        s_M = terrain.surface_G(x, y) @ M_T_G[2, :3] + M_T_G[2, 3]
        low = np.minimum(low, (p_M[..., 2] - s_M).min(axis=1))
    return low


def _map(robot, kind: str, seed: int = 0) -> HeightmapTerrain:
    grid = Grid.of_size((6.0, 6.0), 0.04)
    if kind == "flat":
        hm = plane(grid, 0.0, 0.0)
    elif kind == "tilted":
        hm = plane(grid, 0.3, 0.7)
    elif kind == "bumps":
        hm = bumps(grid, 0.1, 1.0, np.random.default_rng(seed))
    elif kind == "slope-bumps":  # bumps on a side slope rising toward +y
        e = bumps_elevation(grid, 0.12, 0.7, np.random.default_rng(seed))
        hm = grid.heightmap(plane_elevation(grid, 0.3, np.pi / 2) + e, "side slope with bumps")
    elif kind == "kerb":
        hm = kerb(grid, 0.15, 0.45, np.pi / 2)  # a kerb beside the route, rising toward +y
    else:  # a side slope rising toward +y (where a low arm helps most) with a kerb up there
        e = plane_elevation(grid, 0.3, np.pi / 2) + np.where(grid.along(np.pi / 2) >= 0.45, 0.15, 0)
        hm = grid.heightmap(e, "side slope with a kerb")
    return HeightmapTerrain(hm).with_robot(robot)


def _poses(n: int = 6) -> np.ndarray:
    return np.column_stack([np.linspace(-1.0, 1.0, n), np.zeros(n), np.zeros(n)])


@pytest.mark.parametrize("kind", ["ramp", "flat", "tilted"])
def test_on_a_plane_the_check_is_the_plane_check(robot, small, kind):
    terrain = load_problem(PROBLEMS / "ramp.yaml").terrain if kind == "ramp" else _map(robot, kind)
    poses = _poses()
    under = GroundUnderArm(robot, terrain, poses)
    rows = np.arange(len(small.nodes_q))  # every node
    q = small.nodes_q[rows]
    for ground in (0.02, GROUND):
        above = small.node_ground[rows] >= ground
        for k in range(len(poses)):
            # every node above the support plane is above the ground: the plane check decides
            assert under.clear(k, q[above], ground).all()
    g = terrain.gravity_body(poses)
    s = _settings(GROUND)
    on = solve_roadmap_sequence(robot, g, small, s, mu_max(robot), False, poses, under=under)
    off = solve_roadmap_sequence(robot, g, small, s, mu_max(robot), False, poses)
    np.testing.assert_array_equal(on.nodes, off.nodes)
    for a, b in zip(on.moves, off.moves, strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.slow
def test_the_check_is_a_lower_bound_of_the_dense_heights(robot, small, seed):
    terrain = _map(robot, "bumps", seed)
    poses = _poses(4)
    under = GroundUnderArm(robot, terrain, poses)
    rng = np.random.default_rng(seed)
    up = np.flatnonzero(small.node_ground >= GROUND)
    rows = rng.choice(up, min(400, len(up)), replace=False)
    q = small.nodes_q[rows]
    gaps, low = [], 0
    for k in range(len(poses)):
        dense = dense_heights(robot, terrain, under.poses[k].M_T_B, q)
        clear = under.clear(k, q, GROUND)
        assert np.all(dense[clear] >= GROUND - TOL), dense[clear].min()
        h = under.heights(k, q)
        assert np.all(dense >= h - TOL)  # a lower bound everywhere, not only at the threshold
        gaps.append((dense - h)[np.isfinite(h)])
        low += int((~clear).sum())
    assert low > 0  # the bumps do reach the arm
    # conservative by about the pieces' squares (~10 cm) times the bumps' slope (< 0.63)
    assert np.median(np.concatenate(gaps)) < 0.06


def _move_lowest(robot, terrain, under, ks, move) -> float:
    """The arm's least height along a move (n, 4), densely, at the poses ``ks``."""
    if len(move) == 1:
        q = move
    else:
        u = np.linspace(0.0, 1.0, 25)[:, None, None]
        q = (move[:-1][None] + u * np.diff(move, axis=0)[None]).reshape(-1, move.shape[1])
    return min(float(dense_heights(robot, terrain, under.poses[k].M_T_B, q).min()) for k in ks)


@pytest.mark.parametrize("kind", ["slope-kerb", "slope-bumps"])
def test_planned_postures_and_moves_clear_the_ground_under_the_arm(robot, small, kind):
    # seed 3: of seeds 0-3 the bumps where this coarse roadmap's plane-checked plan dips
    # into them (2.9 cm up, not the 5 cm asked for); beside the kerb it is 7.3 cm into it
    terrain = _map(robot, kind, 3)
    poses = _poses(6)
    g = terrain.gravity_body(poses)
    s = _settings(GROUND)
    under = GroundUnderArm(robot, terrain, poses)
    old = solve_roadmap_sequence(robot, g, small, s, mu_max(robot), False, poses)
    new = solve_roadmap_sequence(robot, g, small, s, mu_max(robot), False, poses, under=under)
    T = under.poses
    old_low = [dense_heights(robot, terrain, T[k].M_T_B, old.postures[k])[0] for k in range(6)]
    new_low = [dense_heights(robot, terrain, T[k].M_T_B, new.postures[k])[0] for k in range(6)]
    assert min(old_low) < GROUND - 0.01  # the support-plane check lets the arm into the ground
    assert min(new_low) >= GROUND - TOL
    assert new.total <= old.total + 1e-9  # the check only removes candidates
    # every move: above the ground of both poses it joins (the first: pose 0's), within the
    # samples' spacing (no arm point moves more than SWEEP between two checked samples)
    for k, move in enumerate(new.moves):
        ks = (0,) if k == 0 else (k - 1, k)
        path = move[1:] if k == 0 else move  # the first move leaves the start posture itself
        assert _move_lowest(robot, terrain, under, ks, path) >= GROUND - SWEEP


def test_a_move_whose_end_is_too_low_at_the_other_pose_is_not_taken(robot, small):
    from mmstab.model.collision import CollisionChecker
    from mmstab.planner.searches.roadmap.moves import ground_move

    terrain = _map(robot, "kerb")
    poses = np.array([[0.0, -1.5, 0.0], [0.0, 0.0, 0.0]])  # far from the kerb, then beside it
    under = GroundUnderArm(robot, terrain, poses)
    rows = np.flatnonzero(small.node_ground >= GROUND)
    ok0 = under.clear(0, small.nodes_q[rows], GROUND)
    ok1 = under.clear(1, small.nodes_q[rows], GROUND)
    assert ok0.all() and not ok1.all()
    start = small.connect(robot.stowed, robot)
    b = int(rows[np.flatnonzero(~ok1)[0]])  # clear far away, too low beside the kerb
    checker = CollisionChecker(robot)
    assert ground_move(robot, small, checker, start, b, GROUND, under, (0,)) is not None
    assert ground_move(robot, small, checker, start, b, GROUND, under, (0, 1)) is None
    c = int(rows[np.flatnonzero(ok1)[-1]])
    move = ground_move(robot, small, checker, start, c, GROUND, under, (0, 1))
    if move is not None:
        assert _move_lowest(robot, terrain, under, (0, 1), move) >= GROUND - SWEEP


def test_a_move_through_nodes_too_low_is_searched_again_without_them(robot, small):
    """The masked re-route: the shortest path between two clear nodes dips into the kerb."""
    from mmstab.model.collision import CollisionChecker
    from mmstab.planner.searches.roadmap.moves import _path_nodes, ground_move

    terrain = _map(robot, "kerb")
    poses = np.array([[0.0, 0.0, 0.0]])  # beside the kerb
    under = GroundUnderArm(robot, terrain, poses)
    up = np.flatnonzero(small.node_ground >= GROUND)
    clear = np.zeros(len(small.nodes_q), dtype=bool)
    clear[up] = under.clear(0, small.nodes_q[up], GROUND)
    rng = np.random.default_rng(4)
    checker = CollisionChecker(robot)
    found = 0
    for a, b in rng.choice(np.flatnonzero(clear), (300, 2)):
        plain = _path_nodes(small, int(a), int(b), None, GROUND)
        if plain is None or clear[plain].all():
            continue
        move = ground_move(robot, small, checker, int(a), int(b), GROUND, under, (0,))
        if move is None:
            continue  # no path avoids the low nodes within the re-routes
        found += 1
        assert _move_lowest(robot, terrain, under, (0,), move) >= GROUND - SWEEP
        if found == 3:
            break
    assert found == 3  # shortest paths that dipped, searched again without the low nodes


def test_kept_pieces_added_in_batches_equal_the_pieces_computed_at_once(robot, small):
    """KeptPieces makes room for FIRST_ROWS, then grows by doubling: every row's pieces stay
    those of its batch.

    (A batch's products may differ from another's in the last bit: the reference is built
    from the same batches, each row's new ones.)
    """
    from mmstab.planner.ground.under_arm import FIRST_ROWS, KeptPieces

    under = GroundUnderArm(robot, _map(robot, "flat"), _poses(1))
    kept = KeptPieces(under, small.nodes_q)
    rng = np.random.default_rng(2)
    n = len(small.nodes_q)
    low, centre, seen = (
        np.zeros((n, len(under.pieces.link))),
        np.zeros((n, len(under.pieces.link), 3)),
        np.zeros(n, bool),
    )
    for size in (1, 7, 300, 3, 50, 900, 2):
        rows = rng.integers(0, n, size)
        kept.add(rows)
        new = np.unique(rows)
        new = new[~seen[new]]
        if not new.size:
            continue
        body = under.body(small.nodes_q[new])
        low[new], centre[new], seen[new] = body.low, body.centre, True
    rows = np.flatnonzero(seen)[::-1]
    assert kept.size == len(rows) <= len(kept.low) == min(n, FIRST_ROWS)  # room at once
    got = kept(rows)
    np.testing.assert_array_equal(got.low, low[rows])
    np.testing.assert_array_equal(got.centre, centre[rows])


def test_nodes_found_too_low_are_masked_for_the_next_moves_between_the_same_poses(robot, small):
    """``known``: what one move found too low the next masks once its first path dips."""
    from mmstab.model.collision import CollisionChecker
    from mmstab.planner.searches.roadmap.moves import _path_nodes, ground_move

    terrain = _map(robot, "kerb")
    under = GroundUnderArm(robot, terrain, np.array([[0.0, 0.0, 0.0]]))  # beside the kerb
    up = np.flatnonzero(small.node_ground >= GROUND)
    clear = np.zeros(len(small.nodes_q), dtype=bool)
    clear[up] = under.clear(0, small.nodes_q[up], GROUND)
    rng = np.random.default_rng(6)
    checker = CollisionChecker(robot)
    known: set[int] = set()
    dipped = straight = 0
    for a, b in rng.choice(np.flatnonzero(clear), (400, 2)):
        plain = _path_nodes(small, int(a), int(b), None, GROUND)
        if plain is None:
            continue
        alone = ground_move(robot, small, checker, int(a), int(b), GROUND, under, (0,))
        shared = ground_move(robot, small, checker, int(a), int(b), GROUND, under, (0,),
                             known=known)  # fmt: skip
        assert not clear[list(known)].any()  # only nodes too low at the pose are kept
        nodes_ok, steps_ok = under.sweep_clear((0,), small.nodes_q[plain], small.reach, GROUND)
        if nodes_ok.all() and steps_ok.all():  # a first path that clears: the same move
            straight += 1
            assert (alone is None) == (shared is None)
            if alone is not None:
                np.testing.assert_array_equal(shared, alone)
        else:
            dipped += 1
        if shared is not None:
            assert _move_lowest(robot, terrain, under, (0,), shared) >= GROUND - SWEEP
        if dipped >= 4 and straight >= 4:
            break
    assert dipped >= 4 and straight >= 4 and len(known) > 0


def test_sweeps_and_cuts_kept_between_calls_give_the_answers_computed_afresh(robot, small):
    """A move's reroutes keep the segments swept at its poses and the cuts tested: paths
    that share postures (and one of no length) get the answers of fresh calls."""
    from mmstab.core.steps import drain
    from mmstab.model.collision import CollisionChecker
    from mmstab.planner.searches.roadmap.moves import _path_nodes

    terrain = _map(robot, "kerb")
    under = GroundUnderArm(robot, terrain, np.array([[0.0, 0.0, 0.0], [0.3, 0.0, 0.2]]))
    rng = np.random.default_rng(11)
    checker = CollisionChecker(robot)
    swept: dict = {}
    cuts: dict = {}
    low = paths = 0
    for a, b in rng.choice(np.flatnonzero(small.node_ground >= GROUND), (300, 2)):
        plain = _path_nodes(small, int(a), int(b), None, GROUND)
        if plain is None or len(plain) < 3:
            continue
        paths += 1
        q = small.nodes_q[plain]
        q = np.vstack([q[:2], q[1:]])  # a posture twice: a segment of no length
        for part in (q, q[: max(2, len(q) // 2)], q[len(q) // 3 :]):  # shared postures
            fresh = under.sweep_clear((0, 1), part, small.reach, GROUND)
            kept = under.sweep_clear((0, 1), part, small.reach, GROUND, swept)
            for f, k in zip(fresh, kept, strict=True):
                np.testing.assert_array_equal(k, f)
            low += int((~fresh[0]).sum() + (~fresh[1]).sum())
            np.testing.assert_array_equal(
                drain(small.shortcut_steps(checker, part, memo=cuts)),
                small.shortcut(checker, part),
            )
        if low >= 3 and paths >= 10:
            break
    assert low >= 3 and paths >= 10
