"""The browser viewer: scene geometry, the stored run, the CLI, a real browser."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import ROOT, write_problem

from mmstab.core.files import ConfigError, MmstabError
from mmstab.core.problem import load_problem
from mmstab.runs.store import first_difference, load_run
from mmstab.stability.static import robot_force_angle
from mmstab.terrain import global_com_functions
from mmstab.viz.viewer.ground import (
    extent_around,
    grid_lines,
    problem_ground,
    terrain_mesh,
)
from mmstab.viz.viewer.scene import (
    ARM_MODES,
    arm_posture,
    instant,
    mu_color,
    robot_body_meshes,
    route_points,
    targets_G,
)

G = 9.81


def posture_plan(robot, k=8):
    """A plan of k postures (link0 swinging about 2 rad) and their FK CoMs."""
    s = np.arange(k) / k
    q = np.column_stack([2.0 + 0.4 * np.sin(2 * np.pi * s), 0.2 + 0.1 * np.cos(2 * np.pi * s)])
    q = np.column_stack([q, np.full(k, -0.3), np.zeros(k)])
    return SimpleNamespace(fractions=s, target_com=robot.arm_com(q), postures=q)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory, problem):
    """A real (short) run of `mmstab track`'s experiment on the default problem."""
    from mmstab.outputs.tracking import run_tracking

    d = tmp_path_factory.mktemp("run")
    run_tracking(problem, d, plan=posture_plan(problem.robot), duration=0.3, progress=False)
    return d


def steep(tmp_path, slope):
    return load_problem(
        write_problem(tmp_path, lambda p, r: p["terrain"].__setitem__("slope", slope))
    )


# ------------------------------------------------------------------------------ geometry
def test_body_meshes_are_the_collision_shapes(robot):
    meshes = robot_body_meshes(robot)
    assert [m.name for m in meshes] == [
        "body",
        "track_left",
        "track_right",
        "flipper_left",
        "flipper_right",
        *(f"arm_link_{i}" for i in range(4)),
    ]
    boxes = robot.base.collision_boxes()
    for m in meshes[:5]:
        corners = boxes[m.name].corners()
        assert m.link is None and len(m.vertices) == 8
        np.testing.assert_allclose(
            np.array(sorted(map(tuple, m.vertices))),
            np.array(sorted(map(tuple, corners))),
            atol=1e-12,
        )
    for i, m in enumerate(meshes[5:]):
        geo = robot.links[i].geometry
        assert m.link == i
        if geo.kind == "capsule":  # every vertex lies on the capsule's surface
            a, b = geo.p0, geo.p1
            t = np.clip((m.vertices - a) @ (b - a) / max((b - a) @ (b - a), 1e-300), 0, 1)
            dist = np.linalg.norm(m.vertices - (a + t[:, None] * (b - a)), axis=1)
            np.testing.assert_allclose(dist, geo.radius, atol=1e-9)
    kinds = {robot.links[i].geometry.kind for i in range(4)}
    assert "capsule" in kinds  # the default arm has capsules: the check above ran


def test_ramp_terrain_mesh_lies_on_the_slope_and_faces_up(problem):
    ground = problem_ground(problem)
    extent = extent_around(problem.circle.poses(50), 1.0)
    mesh = terrain_mesh(ground, extent, cells=6)
    n = np.array([0.0, -np.sin(problem.ramp.slope), np.cos(problem.ramp.slope)])  # rot_x z
    np.testing.assert_allclose(mesh.vertices @ n, 0.0, atol=1e-12)
    assert len(mesh.vertices) == 49 and len(mesh.faces) == 72
    tri = mesh.vertices[mesh.faces]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    assert np.all(normals @ n > 0)
    # the uphill edge (y_S = y_max) is higher in G by (y_max - y_min) sin(slope), and lighter
    rise = (extent.y_max - extent.y_min) * np.sin(problem.ramp.slope)
    assert np.ptp(mesh.vertices[:, 2]) == pytest.approx(rise)
    top, bottom = np.argmax(mesh.vertices[:, 2]), np.argmin(mesh.vertices[:, 2])
    assert mesh.colors[top].sum() > mesh.colors[bottom].sum()
    seg = grid_lines(ground, extent, spacing=0.5, samples=4)
    assert seg.shape[1:] == (2, 3) and np.all(seg.reshape(-1, 3) @ n > 0)  # just above


def test_a_heightmap_mesh_stays_on_its_map(robot):
    """Poses near the edge of a map: the mesh is cut to the map, where the ground exists."""
    from mmstab.terrain.generators import Grid, plane
    from mmstab.terrain.heightmap_terrain import HeightmapTerrain

    t = HeightmapTerrain(plane(Grid.of_size((3.0, 3.0), 0.05), 0.2, 0.3)).with_robot(robot)
    near_edge = np.array([[1.2, 0.0, 0.0], [0.0, -1.3, 0.0]])
    extent = extent_around(near_edge, 1.0, t.bounds)
    x0, x1, y0, y1 = t.bounds
    assert (extent.x_min, extent.x_max, extent.y_min, extent.y_max) == (-1.0, x1, y0, 1.0)
    mesh = terrain_mesh(t, extent, cells=6)
    assert np.isfinite(mesh.vertices).all()
    with pytest.raises(Exception, match="off the map"):  # uncut, it would sample off the map
        terrain_mesh(t, extent_around(near_edge, 1.0), cells=6)


def test_heightmap_like_terrain_is_meshed_through_height():
    class Bumps:  # M = G, z = height(x, y)
        def G_T_M(self):
            return np.eye(4)

        def height(self, x, y):
            return 0.1 * np.sin(x) * np.cos(y)

    mesh = terrain_mesh(Bumps(), extent_around(np.array([[-1.0, -1.0], [1.0, 1.0]]), 0.0), 8)
    x, y, z = mesh.vertices.T
    np.testing.assert_allclose(z, 0.1 * np.sin(x) * np.cos(y), atol=1e-15)


def test_problem_ground_is_the_ramp_through_the_terrain_interface(problem, rng):
    ground = problem_ground(problem)
    assert ground is problem.terrain  # the ramp implements mmstab.terrain.Terrain itself
    poses = rng.uniform([-2, -2, -np.pi], [2, 2, np.pi], size=(5, 3))
    T = ground.G_T_B(poses)
    for k, p in enumerate(poses):
        np.testing.assert_allclose(T[k], problem.ramp.G_T_B(p))
    # gravity in B, turned back to G, is G's gravity
    g_G = np.einsum("nij,nj->ni", T[:, :3, :3], ground.gravity_body(poses))
    np.testing.assert_allclose(g_G, np.tile([0, 0, -G], (5, 1)), atol=1e-12)


# ------------------------------------------------------------------------------- instant
def test_flat_ground_arm_removed_mu_by_hand(tmp_path):
    flat = steep(tmp_path, 0.0)
    now = instant(flat.robot, problem_ground(flat), [0.3, -0.2, 0.7], None)
    # base CoM 0.12 m above the middle of a 0.70 m x 0.52 m footprint: the long sides tip first
    base = flat.robot.base
    half_w = base.tracks.separation / 2 + base.tracks.width / 2
    assert now.mu == pytest.approx(base.mass * G * np.arctan2(half_w, base.com[2]), rel=1e-12)
    np.testing.assert_allclose(now.com_projection_G[:2], now.com_G[:2], atol=1e-12)
    assert now.com_projection_G[2] == pytest.approx(0.0, abs=1e-15)  # on the ground
    axis_B = (now.axis_G - now.G_T_B[:3, 3]) @ now.G_T_B[:3, :3]
    np.testing.assert_allclose(np.abs(axis_B[:, 1]), half_w, atol=1e-12)  # a long side


@pytest.mark.parametrize(
    ("heading", "coordinate", "value"), [(0.0, 1, -0.26), (np.pi / 2, 0, -0.35)]
)
def test_closest_tip_over_axis_is_downhill(tmp_path, heading, coordinate, value):
    """Heading 0: body +y is uphill, so the right side tips; heading pi/2: the rear."""
    ramp = steep(tmp_path, 0.4)
    now = instant(ramp.robot, problem_ground(ramp), [0.0, 0.0, heading], None)
    axis_B = (now.axis_G - now.G_T_B[:3, 3]) @ now.G_T_B[:3, :3]
    np.testing.assert_allclose(axis_B[:, coordinate], value, atol=1e-9)
    assert now.angles[now.axis] == now.angles.min()


def test_com_and_its_projection_against_the_casadi_global_com(problem, rng):
    ground = problem_ground(problem)
    com = global_com_functions(problem.robot, problem.ramp)
    for _ in range(5):
        pose = rng.uniform([-1, -1, -np.pi], [1, 1, np.pi])
        q = rng.uniform(problem.robot.joint_lower, problem.robot.joint_upper)
        now = instant(problem.robot, ground, pose, q)
        np.testing.assert_allclose(now.com_G, com.overall(q, pose), atol=1e-12)
        gravity_B = ground.gravity_body(pose[None])
        fa = robot_force_angle(problem.robot, gravity_B, problem.robot.arm_com(q))
        assert now.mu == pytest.approx(fa.mu[0], rel=1e-12)
        drop = now.com_projection_G - now.com_G
        assert np.linalg.norm(np.cross(drop, now.gravity_G)) < 1e-9 * np.linalg.norm(drop)
        assert drop @ now.gravity_G > 0  # down along gravity
        normal = np.cross(*(now.polygon_G[1:3] - now.polygon_G[0]))
        assert abs((now.com_projection_G - now.polygon_G[0]) @ normal) < 1e-12
        # the target mapping is the same Eq. 1 as CasADi's arm CoM
        np.testing.assert_allclose(
            targets_G(ground, pose[None], problem.robot.arm_com(q)[None])[0],
            com.arm(q, pose),
            atol=1e-12,
        )


class Bare:
    """Only the three methods every terrain has (no support, no surface_G)."""

    def __init__(self, ground):
        self.ground = ground

    def G_T_M(self):
        return self.ground.G_T_M()

    def G_T_B(self, poses):
        return self.ground.G_T_B(poses)

    def gravity_body(self, poses):
        return self.ground.gravity_body(poses)

    @property
    def kind(self):
        return self.ground.kind


class ClockwiseSupport(Bare):
    """A terrain that reports its support polygon clockwise (seen from above)."""

    def __init__(self, ground, robot):
        super().__init__(ground)
        self.robot = robot

    def support(self, robot, pose, com_body=None):
        from mmstab.stability.static import base_polygon
        from mmstab.terrain import Support

        T = np.asarray(self.ground.G_T_B(np.asarray(pose)[None])).reshape(-1, 4, 4)[0]
        ccw = base_polygon(robot).vertices @ T[:3, :3].T + T[:3, 3]
        contacts = np.asarray(robot.base.support_points()) @ T[:3, :3].T + T[:3, 3]
        return Support(T, contacts, ccw[::-1])


def test_terrain_support_polygon_in_either_order_gives_the_same_picture(problem, rng):
    ground = problem_ground(problem)
    bare, cw = ground, ClockwiseSupport(ground, problem.robot)
    for _ in range(3):
        pose = rng.uniform([-1, -1, -np.pi], [1, 1, np.pi])
        q = rng.uniform(problem.robot.joint_lower, problem.robot.joint_upper)
        a, b = instant(problem.robot, bare, pose, q), instant(problem.robot, cw, pose, q)
        assert a.mu > 0 and b.mu == pytest.approx(a.mu, rel=1e-12)
        # the polygon turned to the same order: the same force angles, the least one μ
        np.testing.assert_allclose(np.sort(b.angles), np.sort(a.angles), atol=1e-12)
        weight = problem.robot.total_mass * np.linalg.norm(b.gravity_G)
        assert b.angles.min() * weight == pytest.approx(b.mu, rel=1e-9)
        np.testing.assert_allclose(b.com_projection_G, a.com_projection_G, atol=1e-12)
        assert {tuple(np.round(p, 9)) for p in b.axis_G} == {
            tuple(np.round(p, 9)) for p in a.axis_G
        }


def test_mu_color_runs_red_to_green():
    red, mid, green = mu_color(-5.0, 100.0), mu_color(50.0, 100.0), mu_color(100.0, 100.0)
    assert red[0] > 150 and red[1] < 60  # RdYlGn: dark red ... yellow ... dark green
    assert green[1] > 100 and green[0] < 60 and green[2] < 60
    assert mid[0] > 200 and mid[1] > 200  # yellow
    assert mu_color(1e9, 100.0) == green


def test_arm_modes(robot):
    q = np.array([0.1, 0.2, 0.3, 0.4])
    assert arm_posture(robot, "planned", q).tolist() == q.tolist()
    assert arm_posture(robot, "stowed", q).tolist() == robot.stowed.tolist()
    assert arm_posture(robot, "arm removed", q) is None
    with pytest.raises(ValueError, match="arm mode"):
        arm_posture(robot, "folded", q)


# ----------------------------------------------------------------------------------- run
def test_run_is_read_and_its_mu_is_the_instant_mu(problem, run_dir):
    run = load_run(run_dir, problem)
    assert run.samples == 31 and run.t[-1] == pytest.approx(0.3)
    ground = problem_ground(problem)
    for k in (0, 15, 30):
        for mode in ARM_MODES:
            q = arm_posture(problem.robot, mode, run.q[k])
            now = instant(problem.robot, ground, run.poses[k], q)
            assert now.mu == pytest.approx(run.mu[mode][k], rel=1e-12), (k, mode)
    route = route_points(ground, run.poses)
    np.testing.assert_allclose(route[:, :2], run.poses[:, :2] * [1, np.cos(0.1)], atol=5e-4)


def test_missing_run_and_run_of_another_problem_are_refused(problem, run_dir, tmp_path):
    with pytest.raises(MmstabError, match="no such run folder"):
        load_run(tmp_path / "nowhere", problem)
    with pytest.raises(ConfigError, match="problem.yaml: terrain.slope: the run was made with 0.1"):
        load_run(run_dir, steep(tmp_path, 0.2))
    (tmp_path / "empty").mkdir()
    with pytest.raises(ConfigError, match="no problem.yaml"):
        load_run(tmp_path / "empty", problem)


def test_run_with_a_missing_array_is_refused(problem, run_dir, tmp_path):
    d = tmp_path / "cut"
    d.mkdir()
    (d / "problem.yaml").write_bytes((run_dir / "problem.yaml").read_bytes())
    with np.load(run_dir / "run.npz") as data:
        np.savez(d / "run.npz", **{k: data[k] for k in data.files if k != "mu_stowed"})
    with pytest.raises(ConfigError, match="run.npz: mu_stowed: missing"):
        load_run(d, problem)


def test_first_difference():
    assert first_difference({"a": [1, 2.0]}, {"a": [1, 2.0 + 1e-15]}) is None
    assert first_difference({"a": {"b": [1, 2]}}, {"a": {"b": [1, 3]}}) == "a.b[1]"
    assert first_difference({"a": 1}, {"a": 1, "c": 2}) == "c"
    assert first_difference({"a": "x"}, {"a": "y"}) == "a"


# ----------------------------------------------------------------------------------- CLI
def mmstab(*args, **kwargs):
    return subprocess.run(
        [sys.executable, "-m", "mmstab", *args],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=ROOT,
        **kwargs,
    )


def test_cli_bad_run_is_one_line_and_exit_2(run_dir, tmp_path):
    out = mmstab("view", "problems/ramp.yaml", "--run", str(tmp_path / "none"), "--no-browser")
    assert out.returncode == 2 and out.stdout == ""
    assert out.stderr.count("\n") == 1 and "no such run folder" in out.stderr
    other = write_problem(tmp_path, lambda p, r: r["base"].__setitem__("mass", 50.0))
    out = mmstab("view", str(other), "--run", str(run_dir), "--no-browser")
    assert out.returncode == 2 and out.stderr.count("\n") == 1
    assert "robot.base.mass: the run was made with 48.0" in out.stderr
    out = mmstab("view", "problems/ramp.yaml", "--host", "no.such.host.invalid", "--no-browser")
    assert out.returncode == 2 and out.stderr.startswith("mmstab: error: --host")
    out = mmstab("view", "problems/ramp.yaml", "--port", "70000")
    assert out.returncode == 2 and "port must be 0-65535" in out.stderr


def test_cli_serves_prints_the_url_and_stops_on_ctrl_c(run_dir):
    proc = subprocess.Popen(
        [sys.executable, "-m", "mmstab", "view", "problems/ramp.yaml", "--run", str(run_dir)]
        + ["--port", "0", "--no-browser"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        line = proc.stdout.readline()
        assert line.startswith("view: http://127.0.0.1:"), line
        url = line.split()[1]
        with urllib.request.urlopen(url, timeout=10) as page:
            assert page.status == 200 and b"<html" in page.read().lower()
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=10) == 130
        port = int(url.rsplit(":", 1)[1].strip("/"))
        with pytest.raises(OSError), socket.create_connection(("127.0.0.1", port), timeout=2):
            pass
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)


# ------------------------------------------------------------------------------- browser
def processes() -> dict[int, tuple[int, str]]:
    """pid -> (parent pid, command line) of every process we may read."""
    out = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
                cmd = (entry / "cmdline").read_bytes().decode(errors="replace")
            except OSError:
                continue
            out[int(entry.name)] = (int(stat.rsplit(")", 1)[1].split()[1]), cmd)
    return out


def leftovers(marker: str) -> list[str]:
    """Chromium with our profile marker, and any browser/driver child of this process."""
    me = os.getpid()
    return [
        cmd
        for ppid, cmd in processes().values()
        if marker in cmd or (ppid == me and ("playwright" in cmd or "chrom" in cmd))
    ]


@pytest.mark.browser
def test_viewer_renders_in_headless_chromium(problem, run_dir):
    from mmstab.viz.viewer.snapshot import find_chromium

    if find_chromium() is None:
        if os.environ.get("CI"):
            pytest.fail("chromium is missing on CI: .ci/run installs it")
        pytest.skip("no chromium on PATH (apt-get install chromium): browser test skipped")
    from mmstab.viz.viewer.server import NODES, RUN_NODES, Viewer
    from mmstab.viz.viewer.snapshot import screenshot

    viewer = Viewer(problem, load_run(run_dir, problem), host="127.0.0.1", port=0)
    try:
        for name in NODES + RUN_NODES:
            assert viewer.server.scene.get_handle_by_name(name) is not None, name
        now = viewer.show_sample(20)
        assert viewer.shown_mu() == pytest.approx(now.mu, rel=1e-12)

        def remove_arm(page):
            viewer.set_mode("arm removed")
            page.wait_for_timeout(1500)

        shot = screenshot(
            viewer.url,
            ROOT / "results" / "view" / "browser_test.png",
            size=(960, 640),
            timeout=25,
            connected=lambda: bool(viewer.server.get_clients()),
            before=remove_arm,
        )
        assert shot.drawn.scene_share > 0.3  # terrain and robot cover the view
        assert shot.drawn.arm_pixels >= 200
        assert shot.final.arm_pixels < shot.drawn.arm_pixels / 10  # the arm is gone
        assert viewer.current.q is None and viewer.current.mu == pytest.approx(
            viewer.run.mu["arm removed"][20], rel=1e-12
        )
    finally:
        viewer.stop()
    assert leftovers("mmstab-view-chromium-") == []
    with pytest.raises(OSError), socket.create_connection(("127.0.0.1", viewer.port), timeout=2):
        pass


def test_pose_editor_updates_mu_live(problem, run_dir):
    from mmstab.viz.viewer.server import Viewer

    viewer = Viewer(problem, load_run(run_dir, problem), host="127.0.0.1", port=0)
    try:
        ground = problem_ground(problem)
        pose, q = np.array([0.4, 0.5, 1.0]), np.array([0.5, 0.3, -0.2, 0.1])
        now = viewer.show_pose(pose, q)
        assert viewer.editing and viewer.shown_mu() == now.mu
        assert now.mu == pytest.approx(instant(problem.robot, ground, pose, q).mu, rel=1e-12)
        viewer._joint_sliders[1].value = -0.4  # as the user would drag it
        q[1] = -0.4
        assert viewer.current.mu == pytest.approx(
            instant(problem.robot, ground, pose, q).mu, rel=1e-12
        )
        viewer.set_mode("stowed")
        stowed = instant(problem.robot, ground, pose, problem.robot.stowed).mu
        assert viewer.current.mu == pytest.approx(stowed, rel=1e-12)
        viewer.show_sample(5)  # back on the timeline: the stored μ
        assert not viewer.editing and viewer.shown_mu() == viewer.run.mu["stowed"][5]
        assert viewer.toggle_play()  # plays to the end of the run, then pauses
        deadline = time.monotonic() + 10
        while viewer.playing and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not viewer.playing and viewer.index == viewer.run.samples - 1
    finally:
        viewer.stop()
