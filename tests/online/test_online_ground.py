"""The online roadmap horizon keeps the arm off the ground under it, map by map.

A side slope (0.3 rad, rising to +y) and a straight route along x: on it the roadmap plan
reaches uphill, its lowest arm piece beside the route 8.6 cm above the slope. A bump is
laid where that piece hangs at one pose (found from the plan itself, not set by hand), so
the posture chosen without the ground check touches it. Every clearance is measured
independently: the arm's collision shapes sampled densely (capsule surfaces, box volumes)
against the map's heights under each sample (:func:`dense_clearance`).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from conftest import ROOT

import mmstab
from mmstab.model.parts import Box
from mmstab.outputs.online import offline_plan
from mmstab.outputs.recording import record_route
from mmstab.runs.online.follow import Follower, build_follower
from mmstab.runs.online.roadmap_horizon import RoadmapHorizon
from mmstab.runs.online.run import follow_recording
from mmstab.runs.online.stream import MapUpdate, map_updates
from mmstab.terrain.heightmap import Heightmap
from mmstab.terrain.io import save_npz

SLOPE = 0.3  # [rad], rising toward +y
BUMP_K = 4  # the pose whose arm the bump lies under
BUMP_HEIGHT, BUMP_RADIUS = 0.15, 0.15  # [m]
TOPICS = ("/elevation_mapping/elevation_map", "/odom")


def slope_height(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    return np.tan(SLOPE) * y + 0.0 * x


def bump(x: np.ndarray, y: np.ndarray, centre: np.ndarray, height: float = BUMP_HEIGHT) -> Any:
    """A smooth bump (cos^2 profile) of ``height`` [m] and radius BUMP_RADIUS at centre."""
    r = np.hypot(x - centre[0], y - centre[1])
    return np.where(r < BUMP_RADIUS, height * np.cos(np.pi * r / (2 * BUMP_RADIUS)) ** 2, 0.0)


def make_problem(d: Path, centre: np.ndarray | None = None) -> mmstab.Problem:
    """The slope (with a bump at ``centre``) as a map file, the route, a clean recording."""
    res, ny, nx = 0.05, 121, 201
    x = -5.0 + res * np.arange(nx)[None, :]
    y = -3.0 + res * np.arange(ny)[:, None]
    z = slope_height(x, y) + (0.0 if centre is None else bump(x, y, centre))
    d.mkdir(parents=True, exist_ok=True)
    save_npz(d / "ground.npz", Heightmap.build(z, res, np.array([-5.0, -3.0]), "slope"))
    data = yaml.safe_load((ROOT / "problems" / "rough.yaml").read_text())
    data["robot"] = str(ROOT / "problems" / "robots" / "cameleon.yaml")
    data["terrain"] = {"file": "ground.npz"}
    data["path"]["waypoints"] = [[-3.0, 0.0], [3.0, 0.0]]
    # fully seen: no noise, no occluded patches, the whole arm's reach within range
    data["online"] = {"record": {"noise": 0.0, "unknown": 0.0, "range": 4.5, "window": 9.0}}
    (d / "p.yaml").write_text(yaml.safe_dump(data))
    return mmstab.load_problem(d / "p.yaml")


def dense_clearance(problem: mmstab.Problem, q: np.ndarray, M_T_B: np.ndarray, ground: Any) -> Any:
    """The arm's least height [m] above ``ground(x, y)`` (its shapes sampled every ~5 mm).

    Also the samples in M (n, 3). Independent of mmstab's pieces and lattice.
    """
    robot = problem.robot
    frames = robot.kinematics.link_frames(np.atleast_2d(q))[0]
    phi = np.pi * (3.0 - np.sqrt(5.0)) * np.arange(400)  # Fibonacci sphere directions
    zs = 1 - 2 * (np.arange(400) + 0.5) / 400
    sphere = np.stack([np.sqrt(1 - zs**2) * np.cos(phi), np.sqrt(1 - zs**2) * np.sin(phi), zs], 1)
    points = []
    for i, link in enumerate(robot.links):
        g = link.geometry
        if isinstance(g, Box):
            axes = [np.linspace(-s / 2, s / 2, max(int(np.ceil(s / 0.005)), 1) + 1) for s in g.size]
            local = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
            pts = local @ g.frame_T_shape[:3, :3].T + g.center
        else:
            n = max(int(np.ceil(np.linalg.norm(g.p1 - g.p0) / 0.005)), 1) + 1
            axis = g.p0 + np.linspace(0, 1, n)[:, None] * (g.p1 - g.p0)
            pts = (axis[:, None, :] + g.radius * sphere[None]).reshape(-1, 3)
        T = M_T_B @ frames[i]
        points.append(pts @ T[:3, :3].T + T[:3, 3])
    p = np.vstack(points)
    return float((p[:, 2] - ground(p[:, 0], p[:, 1])).min()), p


def follow(problem: mmstab.Problem, updates: list[MapUpdate]) -> Follower:
    f = build_follower(problem)
    for u in updates:
        f.update(u)
    settle(f)
    return f


def settle(f: Follower) -> None:
    """Land the horizon's queued re-plans (as at the end of ``follow_recording``)."""
    assert isinstance(f.horizon, RoadmapHorizon)
    f.horizon.settle()


@pytest.fixture(scope="module")
def scene(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The plain slope's run, and where its arm hangs lowest at pose BUMP_K."""
    d = tmp_path_factory.mktemp("slope")
    problem = make_problem(d / "plain")
    rec = d / "plain" / "run.mcap"
    record_route(problem, rec, duration=6.0)
    updates = list(map_updates(rec, *TOPICS))
    f = follow(problem, updates)
    plan = f.horizon.plans[BUMP_K]
    M_T_B = problem.terrain.M_T_B(plan.pose)
    low, pts = dense_clearance(problem, plan.q, M_T_B, slope_height)
    centre = pts[np.argmin(pts[:, 2] - slope_height(pts[:, 0], pts[:, 1])), :2]
    return {"dir": d, "problem": problem, "updates": updates, "plain": f, "centre": centre}


def test_the_unchecked_plan_would_put_the_arm_on_the_bump(scene: dict[str, Any]) -> None:
    problem, centre = scene["problem"], scene["centre"]
    plan = scene["plain"].horizon.plans[BUMP_K]
    assert abs(centre[1] - plan.pose[1]) > 0.6  # beside the route, off the tracks
    M_T_B = problem.terrain.M_T_B(plan.pose)
    plain, _ = dense_clearance(problem, plan.q, M_T_B, slope_height)
    on_bump, _ = dense_clearance(
        problem, plan.q, M_T_B, lambda x, y: slope_height(x, y) + bump(x, y, centre)
    )
    assert 0.05 <= plain < 0.10  # the plan hangs its arm low over the plain slope...
    assert on_bump < 0.0  # ...where the bump would be inside the arm


def test_online_and_offline_keep_the_arm_above_a_bump_beside_the_route(
    scene: dict[str, Any],
) -> None:
    d, centre = scene["dir"], scene["centre"]
    problem = make_problem(d / "bumped", centre)
    rec = d / "bumped" / "run.mcap"
    record_route(problem, rec, duration=6.0)
    run = follow_recording(problem, rec)
    ground = problem.terrain
    clearance = problem.section("planner")["ground_clearance"]
    gravity = ground.gravity_body(np.array([p.pose for p in run.plans.values()]))
    plain = scene["plain"].horizon.plans
    for (k, p), g in zip(sorted(run.plans.items()), gravity, strict=True):
        assert np.allclose(p.gravity_body, g, atol=1e-3)  # the bump leaves every rest alone
        assert np.allclose(p.gravity_body, plain[k].gravity_body, atol=1e-9)
        h, _ = dense_clearance(
            problem, p.q, ground.M_T_B(p.pose), lambda x, y: ground.surface_G(x, y)[..., 2]
        )
        assert h >= clearance - 1e-6, (k, h)
    assert not np.allclose(run.plans[BUMP_K].q, plain[BUMP_K].q)  # replaced, not dropped
    assert run.arm_ground is not None and run.arm_ground["reach_unknown"] == 0  # fully seen
    off = offline_plan(problem, run, None)  # method roadmap, its own ground check
    assert off.postures is not None
    for k, p in run.plans.items():  # μ within 2 % (docs/online.md's agreement)
        assert abs(p.mu - off.mu_planned[k]) <= 0.02 * abs(off.mu_planned[k]), k
    h, _ = dense_clearance(
        problem, off.postures[BUMP_K], ground.M_T_B(run.plans[BUMP_K].pose),
        lambda x, y: ground.surface_G(x, y)[..., 2],
    )  # fmt: skip
    assert h >= clearance - 1e-6


def with_heights(u: MapUpdate, change: Any) -> MapUpdate:
    """The update with its map's elevation changed: ``change(x, y, z) -> z``."""
    hm = u.grid.heightmap
    ny, nx = hm.shape
    x = hm.origin[0] + hm.resolution * np.arange(nx)[None, :]
    y = hm.origin[1] + hm.resolution * np.arange(ny)[:, None]
    new = Heightmap.build(change(x, y, hm.elevation.copy()), hm.resolution, hm.origin, hm.source)
    return u._replace(grid=dataclasses.replace(u.grid, heightmap=new))


def planned_once_then_changed(scene: dict[str, Any], change: Any) -> tuple[Follower, float]:
    """Follow the plain maps until pose BUMP_K is planned and kept, then ``change`` them."""
    updates, plain = scene["updates"], scene["plain"].horizon.plans
    first = next(i for i, u in enumerate(updates) if u.time > plain[BUMP_K].planned_at + 0.5)
    f = follow(scene["problem"], updates[:first])
    assert isinstance(f.horizon, RoadmapHorizon)
    assert f.horizon.nodes[BUMP_K] == scene["plain"].horizon.nodes[BUMP_K]  # kept as planned
    for u in updates[first:]:
        f.update(with_heights(u, change))
    settle(f)
    return f, updates[first].time


def test_a_bump_appearing_later_rescores_the_pose_though_its_gravity_stands(
    scene: dict[str, Any],
) -> None:
    centre, problem = scene["centre"], scene["problem"]
    f, when = planned_once_then_changed(scene, lambda x, y, z: z + bump(x, y, centre))
    h = f.horizon
    assert isinstance(h, RoadmapHorizon)
    assert h.arm_ground["ground_rescored"] >= 1
    p = h.plans[BUMP_K]
    assert p.planned_at == pytest.approx(when)  # re-scored on the first map with the bump
    assert np.allclose(p.gravity_body, scene["plain"].horizon.plans[BUMP_K].gravity_body)
    clearance = problem.section("planner")["ground_clearance"]
    M_T_B = problem.terrain.M_T_B(p.pose)
    bumped = lambda x, y: slope_height(x, y) + bump(x, y, centre)  # noqa: E731
    hb, _ = dense_clearance(problem, p.q, M_T_B, bumped)
    assert hb >= clearance - 1e-6
    # the moves into and out of the pose clear the bump at both poses they join
    for k in (BUMP_K, BUMP_K + 1):
        for j in (k - 1, k):
            T = problem.terrain.M_T_B(h.plans[j].pose)
            for q in h.move(k)[:: max(len(h.move(k)) // 20, 1)]:
                assert dense_clearance(problem, q, T, bumped)[0] >= clearance - 2e-3, (k, j)
    assert h.arm_ground["moves_plane_only"] == 0


def test_unknown_cells_under_the_arm_count_as_the_highest_mapped_ground_in_reach(
    scene: dict[str, Any],
) -> None:
    """A NaN patch under the arm: on the plain slope the arm may pass over it (reported);
    with a 0.2 m bump mapped on the downhill side, within reach, not above 0.2 m + clearance.
    """
    centre, problem = scene["centre"], scene["problem"]
    plain = scene["plain"].horizon
    patch = lambda x, y: np.hypot(x - centre[0], y - centre[1]) < 0.1  # noqa: E731
    f, _ = planned_once_then_changed(scene, lambda x, y, z: np.where(patch(x, y), np.nan, z))
    h = f.horizon
    assert isinstance(h, RoadmapHorizon)
    assert h.nodes[BUMP_K] == plain.nodes[BUMP_K] and h.arm_ground["ground_rescored"] == 0
    assert h.arm_ground["over_unknown"] > 0  # the arm passes over the patch, counted
    far = np.array([centre[0], -0.9])  # downhill, beside the route, within the arm's reach
    high = 0.2

    def change(x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
        return np.where(patch(x, y), np.nan, z + bump(x, y, far, high))

    f, _ = planned_once_then_changed(scene, change)
    h = f.horizon
    assert isinstance(h, RoadmapHorizon) and h.arm_ground["ground_rescored"] >= 1
    p = h.plans[BUMP_K]
    clearance = problem.section("planner")["ground_clearance"]
    _, pts = dense_clearance(problem, p.q, problem.terrain.M_T_B(p.pose), slope_height)
    over = patch(pts[:, 0], pts[:, 1])
    rise = pts[over, 2] - slope_height(pts[over, 0], pts[over, 1])
    assert (rise >= high + clearance - 0.01).all()  # over the patch only above the bump's top
