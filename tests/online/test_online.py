"""On a robot: generated recordings, the online loop, runs written as recordings."""

from __future__ import annotations

import gc
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import ROOT

import mmstab
from mmstab.core.bags import BagWriter
from mmstab.model.urdf import robot_to_urdf
from mmstab.outputs.online import run_follow
from mmstab.outputs.recording import record_route
from mmstab.runs.online.follow import build_follower
from mmstab.runs.online.run import follow_recording
from mmstab.runs.online.stream import ODOMETRY, map_updates, odometry_of
from mmstab.runs.recording import TOPICS, RunFrames, joint_names, write_run
from mmstab.runs.store import load_run
from mmstab.terrain.gridmap import GRIDMAP, typestore
from mmstab.terrain.recording import messages


def problem_file(tmp_path: Path, planner: str = "roadmap", **record: float) -> Path:
    """problems/rough.yaml with the given ``online.record`` settings and online planner."""
    data = yaml.safe_load((ROOT / "problems" / "rough.yaml").read_text())
    data["robot"] = str(ROOT / "problems" / "robots" / "cameleon.yaml")
    data["online"] = {"record": dict(record), "planner": planner}
    path = tmp_path / "rough.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.fixture(scope="module")
def clean(tmp_path_factory: pytest.TempPathFactory) -> tuple[mmstab.Problem, Path]:
    """A noise-free, fully seen recording of the first 8 s of the rough route."""
    d = tmp_path_factory.mktemp("clean")
    problem = mmstab.load_problem(problem_file(d, noise=0.0, unknown=0.0))
    path = d / "clean.mcap"
    record_route(problem, path, duration=8.0)
    return problem, path


def test_recordings_are_seeded_and_look_like_elevation_maps(tmp_path: Path) -> None:
    problem = mmstab.load_problem(problem_file(tmp_path, noise=0.01, unknown=0.02, range=2.0))
    a, b = (
        record_route(problem, tmp_path / "a.mcap", 2.0),
        record_route(problem, tmp_path / "b.bag", 2.0),
    )
    (tmp_path / "again").mkdir()
    record_route(problem, tmp_path / "again" / "a.mcap", 2.0)  # (the file's name is inside it)
    assert a.maps == 21 and a.odometry == 101  # 10 Hz and 50 Hz over [0, 2] s
    assert (tmp_path / "a.mcap").read_bytes() == (tmp_path / "again" / "a.mcap").read_bytes()
    route = problem.route
    assert route is not None
    truth = problem.terrain.heightmap  # type: ignore[attr-defined]
    for path in (a.path, b.path):
        ups = list(map_updates(path, "/elevation_mapping/elevation_map", "/odom"))
        assert len(ups) == 21  # odometry written first at each instant: no map skipped
        for u in ups[::7]:
            hm = u.grid.heightmap
            expected = route.pose_at(np.array([u.odometry.time / route.lap_time]))[0]
            assert np.allclose(u.odometry.pose, expected, atol=1e-9)
            y, x = np.mgrid[0 : hm.shape[0], 0 : hm.shape[1]]
            cx, cy = hm.origin[0] + hm.resolution * x, hm.origin[1] + hm.resolution * y
            far = np.hypot(cx - u.odometry.pose[0], cy - u.odometry.pose[1]) > 2.0 + 1e-9
            assert np.isnan(hm.elevation[far]).all()  # beyond the sensor's range: unknown
            seen = np.isfinite(hm.elevation)
            err = hm.elevation[seen] - truth.height(np.stack([cx[seen], cy[seen]], axis=1))
            assert 0.005 < np.std(err) < 0.015 and abs(np.mean(err)) < 0.003  # 1 cm RMS noise


@pytest.mark.slow
def test_follow_reproduces_the_offline_plan_where_the_map_agrees(
    clean: tuple[mmstab.Problem, Path], tmp_path: Path
) -> None:
    problem, path = clean
    s = run_follow(problem, path, tmp_path)
    off = s["offline"]
    assert s["updates"] == 81 and s["qp_failures"] == 0 and s["tipped"] is None
    assert s["robot_not_covered_updates"] == 0  # a clean map covers the robot
    assert off["agreeing_poses"] == off["poses"] >= 5
    assert off["relative_difference"]["max"] <= 0.02  # the 2 %
    # each route pose planned once, and once more when its arm's whole reach (beyond the
    # sensor's 3 m range at first) has come into the map; the map confirms it afterwards
    ag = s["arm_ground"]
    assert s["planned_poses"] == off["poses"] and ag["ground_rescored"] == 0
    assert 0 < ag["unknown_rescored"] <= ag["reach_unknown"] <= s["planned_poses"]
    assert s["replanned_poses"] == s["planned_poses"] + ag["unknown_rescored"]
    assert s["planned_collision_free"] == s["planned_poses"]
    assert (tmp_path / "online.png").is_file() and (tmp_path / "online.mcap").is_file()
    assert json.loads((tmp_path / "summary.json").read_text())["updates"] == 81
    # the viewer replays the run: a stored run of this problem, frame for frame
    replay = load_run(tmp_path, problem)
    st = [x for x in follow_recording(problem, path).steps if x.covered]
    assert replay.samples == len(st) == 81
    assert np.allclose(replay.poses, [x.pose for x in st])
    assert np.allclose(replay.q, [x.q for x in st])
    assert np.allclose(replay.mu["planned"], [x.mu for x in st], rtol=1e-9)  # μ the loop gave
    assert (replay.mu["stowed"] < replay.mu["arm removed"]).all()  # the stowed arm hangs back
    route = problem.route
    planned_s = [r["s_m"] for r in off["per_pose"]]
    assert route is not None and np.allclose(route.s_at(replay.plan_fractions), planned_s)


@pytest.mark.slow
def test_the_warm_planner_online_reproduces_its_offline_plan(
    clean: tuple[mmstab.Problem, Path], tmp_path: Path
) -> None:
    _, path = clean  # the same recording, planned by CMA-ES in V (online.planner: warm)
    problem = mmstab.load_problem(problem_file(tmp_path, "warm", noise=0.0, unknown=0.0))
    s = run_follow(problem, path, tmp_path, limit=50)
    off = s["offline"]
    assert s["qp_failures"] == 0 and s["planned_collision_free"] == s["planned_poses"] >= 3
    # both rank on each pose's loaded support, which the map's cells move by a few per cent;
    # the warm-started searches then follow their own basins at a pose or two (up to 20 %)
    rel = off["relative_difference"]
    assert off["agreeing_poses"] == off["poses"] and rel["median"] <= 0.02 and rel["max"] <= 0.25


def test_online_roadmap_moves_are_collision_free_and_the_reference_follows_them(
    clean: tuple[mmstab.Problem, Path],
) -> None:
    from mmstab.model.collision import CollisionChecker
    from mmstab.runs.online.roadmap_horizon import RoadmapHorizon, along

    problem, path = clean
    follower = build_follower(problem)
    horizon = follower.horizon
    assert isinstance(horizon, RoadmapHorizon)
    steps = [
        follower.update(u) for u in map_updates(path, "/elevation_mapping/elevation_map", "/odom")
    ]
    checker, roadmap = CollisionChecker(problem.robot), horizon.roadmap
    ks = sorted(horizon.plans)
    assert len(ks) >= 5 and ks == list(range(ks[0], ks[-1] + 1))
    for k in ks:
        move = horizon.move(k)
        start = horizon.plans[k - 1].q if k - 1 in horizon.plans else problem.robot.stowed
        assert np.allclose(move[0], start) and np.allclose(move[-1], horizon.plans[k].q)
        for a, b in zip(move[:-1], move[1:], strict=True):  # every segment checked with FCL
            assert roadmap.move_is_free(checker, a, b)
        assert np.allclose(along(move, 0.0), move[0]) and np.allclose(along(move, 1.0), move[-1])
    # between two planned poses the posture reference lies on the move into the second
    k = ks[len(ks) // 2]
    a, b = horizon.plans[k - 1].s, horizon.plans[k].s
    _, q_ref, _ = horizon.reference(0.25 * a + 0.75 * b, b - a)
    assert q_ref is not None and np.allclose(q_ref, along(horizon.move(k), 0.75))
    assert all(x.status == 0 for x in steps)


def test_along_a_polyline() -> None:
    from mmstab.runs.online.roadmap_horizon import along

    path = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 3.0]])  # length 4
    assert np.allclose(along(path, 0.125), [0.5, 0.0])
    assert np.allclose(along(path, 0.5), [1.0, 1.0])
    assert np.allclose(along(path[:1], 0.7), [0.0, 0.0])


@pytest.mark.slow
def test_the_same_recording_gives_the_same_answers(clean: tuple[mmstab.Problem, Path]) -> None:
    problem, path = clean
    a, b = follow_recording(problem, path, limit=40), follow_recording(problem, path, limit=40)
    for name in ("s", "mu", "mu_planned", "q", "qdot", "covered_ahead", "status"):
        va = np.array([getattr(x, name) for x in a.steps])
        vb = np.array([getattr(x, name) for x in b.steps])
        assert np.array_equal(va, vb, equal_nan=True), name


def test_the_loop_runs_with_the_set_up_frozen_for_the_collector_and_thaws_it(
    clean: tuple[mmstab.Problem, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The set-up's objects are out of the collector's passes during the loop, back after."""
    from mmstab.runs.online.follow import Follower

    problem, path = clean
    frozen: list[int] = []
    update = Follower.update

    def counted(self: Follower, u: object) -> object:
        frozen.append(gc.get_freeze_count())
        return update(self, u)  # type: ignore[arg-type]

    monkeypatch.setattr(Follower, "update", counted)
    assert gc.get_freeze_count() == 0
    follow_recording(problem, path, limit=3)
    assert len(frozen) == 3 and min(frozen) > 10_000  # V, the roadmap, CasADi's objects
    assert gc.get_freeze_count() == 0


def test_what_the_map_does_not_cover_is_reported(tmp_path: Path) -> None:
    problem = mmstab.load_problem(problem_file(tmp_path, noise=0.0, unknown=0.0, range=1.2))
    path = tmp_path / "short_range.mcap"
    record_route(problem, path, 4.0)
    run = follow_recording(problem, path)
    assert all(0 <= x.covered_ahead < 1.2 for x in run.steps)  # never past what the sensor saw
    assert all(x.uncovered > 0 for x in run.steps)  # the 2 m horizon reaches beyond it
    planned = {k for k in run.plans}
    reached = max(x.s for x in run.steps) + 1.2
    assert all(run.s_grid[k] <= reached for k in planned)  # nothing planned unseen


def _short_recording(tmp_path: Path) -> tuple[mmstab.Problem, Path, list]:
    """A noiseless 1 s recording of the test route, and its maps' and odometry's messages."""
    problem = mmstab.load_problem(problem_file(tmp_path, noise=0.0, unknown=0.0))
    path = tmp_path / "r.mcap"
    record_route(problem, path, 1.0)
    msgs = list(messages(path, {"/elevation_mapping/elevation_map": GRIDMAP, "/odom": ODOMETRY}))
    return problem, path, msgs


def test_maps_before_odometry_are_skipped_and_frames_must_match(tmp_path: Path) -> None:
    problem, path, msgs = _short_recording(tmp_path)
    store = typestore(False)
    late = tmp_path / "late.mcap"
    with BagWriter(late, store) as w:  # maps from 0 s, odometry only from 0.5 s
        for m in msgs:
            if m.topic == "/odom" and m.time < 0.5:
                continue
            if m.topic == "/odom":
                m.message.header.frame_id = "map" if m.time > 0.9 else "odom"
            w.write(m.topic, m.msgtype, m.time, m.message)
    counts = [0]
    ups = map_updates(late, "/elevation_mapping/elevation_map", "/odom", counts)
    first = next(ups)
    assert counts[0] == 5 and first.time == pytest.approx(0.5)
    with pytest.raises(mmstab.ConfigError, match="map in 'odom' but odometry in 'map'"):
        list(ups)


def test_a_map_in_another_frame_takes_the_odometry_through_tf(tmp_path: Path) -> None:
    from mmstab.runs.online.frames import pose_matrix
    from mmstab.runs.recording import transform_stamped

    problem, path, msgs = _short_recording(tmp_path)
    store = typestore(False)
    truth = [
        u.odometry.pose for u in map_updates(path, "/elevation_mapping/elevation_map", "/odom")
    ]
    map_T_site = pose_matrix(np.array([1.0, -2.0, 0.3]))  # static: map -> site
    site_T_odom = pose_matrix(np.array([-0.5, 0.7, -1.1]))  # moving: site -> odom
    odom_T_map = np.linalg.inv(map_T_site @ site_T_odom)
    tf_type = "tf2_msgs/msg/TFMessage"
    out = tmp_path / "tf.mcap"
    with BagWriter(out, store) as w:
        static = transform_stamped(store, False, 0.0, "map", "site", map_T_site)
        w.write("/tf_static", tf_type, 0.0, store.types[tf_type](transforms=[static]))
        for m in msgs:
            if m.topic == "/odom":  # the odometry in its own frame, the map stays in 'map'
                moving = transform_stamped(store, False, m.time, "site", "odom", site_T_odom)
                w.write("/tf", tf_type, m.time, store.types[tf_type](transforms=[moving]))
                pp = m.message.pose.pose
                T = odom_T_map @ pose_matrix(odometry_of(m.time, m.message).pose)
                pp.position.x, pp.position.y = T[0, 3], T[1, 3]
                h = np.arctan2(T[1, 0], T[0, 0]) / 2
                q = pp.orientation  # the heading alone: the loop reads no more of it
                q.x, q.y, q.z, q.w = 0.0, 0.0, np.sin(h), np.cos(h)
                m.message.header.frame_id = "odom"
            else:
                m.message.header.frame_id = "map"
            w.write(m.topic, m.msgtype, m.time, m.message)
    got = list(map_updates(out, "/elevation_mapping/elevation_map", "/odom"))
    assert len(got) == len(truth) and all(u.odometry.frame_id == "map" for u in got)
    for u, pose in zip(got, truth, strict=True):  # back in the map's frame
        assert np.allclose(u.odometry.pose[:2], pose[:2], atol=1e-9)
        assert np.isclose(np.angle(np.exp(1j * (u.odometry.pose[2] - pose[2]))), 0.0, atol=1e-9)


def with_joint_states(src: Path, out: Path, names: list[str], q: np.ndarray) -> None:
    """``src``'s maps and odometry, and a ``/joint_states`` message with each odometry."""
    store = typestore(False)
    msgs = list(messages(src, {"/elevation_mapping/elevation_map": GRIDMAP, "/odom": ODOMETRY}))
    with BagWriter(out, store) as w:
        for m in msgs:
            w.write(m.topic, m.msgtype, m.time, m.message)
            if m.topic == "/odom":
                js = store.types["sensor_msgs/msg/JointState"](
                    header=m.message.header, name=names, position=np.array(q, dtype=float),
                    velocity=np.zeros(0), effort=np.zeros(0),
                )  # fmt: skip
                w.write("/joint_states", "sensor_msgs/msg/JointState", m.time, js)


@pytest.mark.slow
def test_measured_joint_states_replace_the_integrated_posture(
    clean: tuple[mmstab.Problem, Path], tmp_path: Path
) -> None:
    problem, path = clean
    robot = problem.robot
    names = joint_names(robot)
    held = np.array(robot.stowed, dtype=float)  # the arm reports it never left the stow
    rec = tmp_path / "joints.mcap"
    with_joint_states(path, rec, names[::-1], held[::-1])  # any order: picked by name
    data = yaml.safe_load(problem.path.read_text())
    data["online"]["joints_topic"] = "/joint_states"
    (tmp_path / "p.yaml").write_text(yaml.safe_dump(data))
    measured = follow_recording(mmstab.load_problem(tmp_path / "p.yaml"), rec, limit=30)
    integrated = follow_recording(problem, rec, limit=30)
    assert all(x.measured and np.array_equal(x.q, held) for x in measured.steps)
    assert not any(x.measured for x in integrated.steps)
    assert max(np.abs(x.q - held).max() for x in integrated.steps) > 0.05  # the arm moved
    bad = tmp_path / "bad.mcap"
    with_joint_states(path, bad, names[:-1], held[:-1])
    with pytest.raises(mmstab.ConfigError, match=f"no joint '{names[-1]}'"):
        follow_recording(mmstab.load_problem(tmp_path / "p.yaml"), bad, limit=3)


@pytest.mark.parametrize("name", ["run.mcap", "run.bag", "run_dir"])
def test_runs_round_trip_as_recordings(tmp_path: Path, name: str) -> None:
    problem = mmstab.load_problem(ROOT / "problems" / "kerb.yaml")
    robot = problem.robot
    rng = np.random.default_rng(3)
    q = robot.stowed + rng.uniform(-0.2, 0.2, (5, 4))
    poses = np.column_stack([np.linspace(-0.5, 0.5, 5), np.zeros(5), np.linspace(0, 0.4, 5)])
    G_T_B = problem.terrain.G_T_B(poses)
    polys = [problem.terrain.support(robot, p).polygon_G for p in poses]
    frames = RunFrames(np.arange(5) * 0.1, G_T_B, q, np.array([300.0, 200, 100, 0, -5]), polys)
    write_run(tmp_path / name, robot, frames, 400.0)
    got = {t: [] for t in TOPICS}  # type: ignore[var-annotated]
    for m in messages(tmp_path / name, TOPICS):
        got[m.topic].append(m)
    assert [m.message.data for m in got["/mu"]] == [300.0, 200, 100, 0, -5]
    names = joint_names(robot)
    assert all(f'name="{n}"' in robot_to_urdf(robot) for n in names)  # the URDF's joints
    for k, m in enumerate(got["/joint_states"]):
        assert list(m.message.name) == names and np.allclose(m.message.position, q[k])
    base = got["/tf"][2].message.transforms[0]
    assert (base.header.frame_id, base.child_frame_id) == ("odom", "base_link")
    assert np.allclose(
        [base.transform.translation.x, base.transform.translation.z], G_T_B[2, [0, 2], 3]
    )
    link = got["/tf"][2].message.transforms[4]
    B_T_R = robot.kinematics.link_frames(q[2])
    assert link.child_frame_id == "arm_frame_3" and np.isclose(
        link.transform.translation.z, B_T_R[3][2, 3]
    )
    colours = [(m.message.color.r, m.message.color.g) for m in got["/support_polygon"]]
    assert colours[0] == (0.5, 1.0) and colours[3] == (1.0, 0.0)  # 300/400: yellow-green; 0: red
    assert len(got["/arm_trajectory"]) == 1 and len(got["/arm_trajectory"][0].message.points) == 5


def test_a_sample_without_a_pose_writes_no_transform(tmp_path: Path) -> None:
    """A map that left the robot's ground unknown: its sample has no pose (NaN); the run's
    recording skips its /tf and keeps its joints and its μ (NaN)."""
    problem = mmstab.load_problem(ROOT / "problems" / "kerb.yaml")
    robot = problem.robot
    poses = np.column_stack([np.linspace(-0.5, 0.5, 3), np.zeros(3), np.zeros(3)])
    G_T_B = problem.terrain.G_T_B(poses)
    G_T_B[1] = np.nan
    q = np.tile(robot.stowed, (3, 1))
    polys = [problem.terrain.support(robot, p).polygon_G for p in poses]
    polys[1] = np.zeros((0, 3))
    frames = RunFrames(np.arange(3) * 0.1, G_T_B, q, np.array([300.0, np.nan, 200.0]), polys)
    write_run(tmp_path / "run.mcap", robot, frames, 400.0)
    got = {t: [] for t in TOPICS}  # type: ignore[var-annotated]
    for m in messages(tmp_path / "run.mcap", TOPICS):
        got[m.topic].append(m)
    assert len(got["/joint_states"]) == 3 and len(got["/tf"]) == 2
    mu = [m.message.data for m in got["/mu"]]
    assert mu[0] == 300.0 and np.isnan(mu[1]) and mu[2] == 200.0
    assert len(got["/support_polygon"]) == 2


@pytest.mark.slow
def test_follow_where_occluded_ground_is_under_the_robot(tmp_path: Path) -> None:
    """Route 18 of make validate-routes, recorded with its seeded occluded patches: the robot
    stands on unknown cells at some maps (once under its own arm's CoM where the batch's
    stowed CoM was covered). follow answers through them: exit 0, those maps not covered.
    The arm is led along its planned moves from the stowed posture: straight at the first
    planned posture it swung its turret with the arm low, 10.8 cm into the ground (exit 5)."""
    sys.path.insert(0, str(ROOT))
    from experiments.validate_routes import load_settings, route_problem

    data = route_problem(load_settings(ROOT / "problems" / "validate_routes.yaml"), 18)
    p = tmp_path / "route18.yaml"
    p.write_text(yaml.safe_dump(data))
    env = {**os.environ, "MPLBACKEND": "Agg"}
    bag, out = str(tmp_path / "r.mcap"), str(tmp_path / "f")
    for args in (("record", str(p), "-o", bag), ("follow", str(p), "--bag", bag, "-o", out)):
        r = subprocess.run([sys.executable, "-m", "mmstab", *args], capture_output=True,
                           text=True, env=env, cwd=ROOT, timeout=300)  # fmt: skip
        assert r.returncode == 0, r.stderr
    summary = json.loads((tmp_path / "f" / "summary.json").read_text())
    assert 0 < summary["robot_not_covered_updates"] < summary["updates"]
    assert summary["tipped"] is None and summary["qp_failures"] == 0
    ground = summary["arm_in_ground"]
    assert ground["contact"] is False and ground["height_min_m"] > 0.05


@pytest.mark.slow
def test_cli_record_then_follow(tmp_path: Path) -> None:
    from mcap.reader import make_reader

    p = problem_file(tmp_path, range=3.0)
    env = {**os.environ, "MPLBACKEND": "Agg"}
    run = lambda *a: subprocess.run(  # noqa: E731
        [sys.executable, "-m", "mmstab", *a], capture_output=True, text=True, env=env, cwd=ROOT,
        timeout=300,
    )  # fmt: skip
    bag = tmp_path / "run.mcap"
    r = run("record", str(p), "-o", str(bag), "--duration", "3")
    assert r.returncode == 0, r.stderr
    assert "31 maps and 151 odometry messages over 3.0 s" in r.stdout
    out = tmp_path / "out"
    r = run("follow", str(p), "--bag", str(bag), "-o", str(out), "--limit", "20")
    # the route starts on the 31.5 deg side slope, its first poses tilted beyond atan(0.7)
    assert r.returncode == 4 and "mmstab: slides: the tracks would slide" in r.stderr
    s = json.loads((out / "summary.json").read_text())
    assert (
        s["slides"]["tilt_rad"] > s["slides"]["critical_tilt_rad"] == pytest.approx(np.arctan(0.7))
    )
    r = run("follow", str(p), "--bag", str(bag), "-o", str(out), "--limit", "20", "--allow-sliding")
    assert r.returncode == 0, r.stderr
    assert s["updates"] == 20 and "map to answer p50" in r.stdout
    with (out / "online.mcap").open("rb") as fh:
        channels = {c.topic for c in make_reader(fh).get_summary().channels.values()}
    assert channels == set(TOPICS)
    mus = [m.message.data for m in messages(out / "online.mcap", {"/mu": TOPICS["/mu"]})]
    assert len(mus) == s["updates"] - s["robot_not_covered_updates"] and min(mus) == pytest.approx(
        s["mu_min"]
    )
    r = run("follow", str(p), "--bag", str(tmp_path / "none.mcap"), "-o", str(tmp_path / "o2"))
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "no such recording" in r.stderr
    assert not (tmp_path / "o2").exists()


def test_follow_needs_a_route(tmp_path: Path) -> None:
    with pytest.raises(mmstab.MmstabError, match="not a route"):
        build_follower(mmstab.load_problem(ROOT / "problems" / "ramp.yaml"))


@pytest.mark.slow
def test_a_start_on_no_map_is_no_nan_in_the_summary(tmp_path: Path) -> None:
    """rough.yaml's first maps do not cover the robot: ``follow --limit 5`` wrote NaN into
    summary.json (a ValueError traceback); μ min and tilt max are null, the line says n/a."""
    env = {**os.environ, "MPLBACKEND": "Agg"}
    run = lambda *a: subprocess.run(  # noqa: E731
        [sys.executable, "-m", "mmstab", *a], capture_output=True, text=True, env=env, cwd=ROOT,
        timeout=300,
    )  # fmt: skip
    rough, bag, out = ROOT / "problems" / "rough.yaml", tmp_path / "r.mcap", tmp_path / "out"
    assert run("record", str(rough), "-o", str(bag), "--duration", "1").returncode == 0
    r = run("follow", str(rough), "--bag", str(bag), "-o", str(out), "--limit", "5")
    assert r.returncode == 0, r.stderr
    assert "not on its map at 5 maps" in r.stdout and "mu min n/a" in r.stdout
    s = json.loads((out / "summary.json").read_text())
    assert s["updates"] == 5 and s["mu_min"] is None and s["tilt_max_rad"] is None
    assert s["mu_min_at"] is None and s["along_route"] is None
