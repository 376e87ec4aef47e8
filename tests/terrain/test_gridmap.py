"""grid_map's GridMap in and out: storage order, circular buffer, recordings.

The storage order is checked against messages built here by hand from grid_map's own
definition (index (0, 0) at the map's +x/+y corner, column-major data, the buffer's start
index), not with :func:`mmstab.terrain.gridmap.to_message`; the writer is then checked
against the reader, and the files against a second reader (the ``mcap`` library).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import ROOT

from mmstab.core.bags import BagWriter
from mmstab.core.files import ConfigError
from mmstab.terrain.gridmap import GRIDMAP, GridMapFrame, from_message, to_message, typestore
from mmstab.terrain.heightmap import Heightmap
from mmstab.terrain.recording import load_grid_map, messages


def hand_message(
    values: np.ndarray, res: float, centre: tuple[float, float], start: tuple[int, int]
) -> Any:
    """A ROS 2 GridMap whose unwrapped matrix is ``values`` (rows along -x, cols along -y)."""
    t = typestore(False).types
    rows, cols = values.shape
    buffer = np.empty_like(values)
    for i in range(rows):  # grid_map: index (i, j) lives at ((i + s0) % rows, (j + s1) % cols)
        for j in range(cols):
            buffer[(i + start[0]) % rows, (j + start[1]) % cols] = values[i, j]
    data = [buffer[r, c] for c in range(cols) for r in range(rows)]  # column-major
    dim = t["std_msgs/msg/MultiArrayDimension"]
    layout = t["std_msgs/msg/MultiArrayLayout"](
        dim=[dim(label="column_index", size=cols, stride=rows * cols),
             dim(label="row_index", size=rows, stride=rows)],
        data_offset=0,
    )  # fmt: skip
    arr = t["std_msgs/msg/Float32MultiArray"](layout=layout, data=np.array(data, np.float32))
    pose = t["geometry_msgs/msg/Pose"](
        position=t["geometry_msgs/msg/Point"](x=centre[0], y=centre[1], z=0.0),
        orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
    )
    info = t["grid_map_msgs/msg/GridMapInfo"](
        resolution=res, length_x=rows * res, length_y=cols * res, pose=pose
    )
    stamp = t["builtin_interfaces/msg/Time"](sec=3, nanosec=500_000_000)
    header = t["std_msgs/msg/Header"](stamp=stamp, frame_id="odom")
    return t[GRIDMAP](
        header=header, info=info, layers=["elevation"], basic_layers=[], data=[arr],
        outer_start_index=start[0], inner_start_index=start[1],
    )  # fmt: skip


@pytest.mark.parametrize("start", [(0, 0), (2, 3), (6, 1)])
def test_storage_order_against_a_plane_tilted_one_way(start: tuple[int, int]) -> None:
    # z = 0.3 x + 0.1 (rises toward +x only): grid_map's cell (i, j) centre is at
    # x = cx + L_x/2 - (i + 1/2) res, so row i = 0 is the highest
    res, rows, cols, centre = 0.1, 7, 5, (2.0, -1.0)
    i = np.arange(rows)[:, None] * np.ones((1, cols))
    x = centre[0] + rows * res / 2 - (i + 0.5) * res
    frame = from_message(hand_message(0.3 * x + 0.1, res, centre, start))
    hm = frame.heightmap
    assert hm.elevation.shape == (cols, rows)  # mmstab: row = +y, column = +x
    xs = hm.origin[0] + res * np.arange(rows)
    assert np.allclose(hm.elevation, 0.3 * xs[None, :] + 0.1, atol=1e-6)
    assert np.allclose(hm.origin, [centre[0] - 0.3, centre[1] - 0.2])
    # the heights seen through the terrain interface: the plane's, at any point inside
    pts = np.array([[1.8, -1.1], [2.1, -0.9], [1.75, -1.15]])
    assert np.allclose(hm.height(pts), 0.3 * pts[:, 0] + 0.1, atol=1e-6)
    assert frame.frame_id == "odom" and frame.stamp == 3.5


def test_storage_order_along_y() -> None:
    # z = -0.2 y: column j = 0 (the +y edge) is the lowest
    res, rows, cols, centre = 0.05, 4, 6, (0.0, 0.0)
    j = np.ones((rows, 1)) * np.arange(cols)[None, :]
    y = centre[1] + cols * res / 2 - (j + 0.5) * res
    hm = from_message(hand_message(-0.2 * y, res, centre, (1, 4))).heightmap
    ys = hm.origin[1] + res * np.arange(cols)
    assert np.allclose(hm.elevation, -0.2 * ys[:, None] * np.ones((1, rows)), atol=1e-7)


@pytest.mark.parametrize("ros1", [False, True])
@pytest.mark.parametrize("row_major", [False, True])
def test_round_trip_with_unknown_cells(ros1: bool, row_major: bool) -> None:
    rng = np.random.default_rng(4)
    e = rng.normal(size=(9, 13))
    e[rng.random(e.shape) < 0.1] = np.nan
    hm = Heightmap(e, 0.08, np.array([-1.5, 2.25]))
    frame = GridMapFrame(hm, "map", 12.25, {"variance": np.abs(e)})
    back = from_message(to_message(frame, ros1, (5, 11), row_major))
    e32 = e.astype(np.float32).astype(float)  # the message stores float32
    assert np.array_equal(np.isnan(back.heightmap.elevation), np.isnan(e))
    assert np.allclose(back.heightmap.elevation, e32, equal_nan=True, atol=0)
    assert np.allclose(back.heightmap.origin, hm.origin) and back.heightmap.resolution == 0.08
    assert np.allclose(back.layers["variance"], np.abs(e32), equal_nan=True)
    assert back.stamp == 12.25 and back.frame_id == "map"


def _maps(n: int, rng: np.random.Generator) -> list[GridMapFrame]:
    return [
        GridMapFrame(Heightmap(rng.normal(size=(6, 8)), 0.1, np.array([0.5 * k, 0.0])), "odom", k)
        for k in range(n)
    ]


@pytest.mark.parametrize("name", ["run.mcap", "run.bag", "run2"])
def test_recordings_round_trip(tmp_path: Path, name: str) -> None:
    rng = np.random.default_rng(7)
    frames = _maps(4, rng)
    path = tmp_path / name
    ros1 = name.endswith(".bag")
    with BagWriter(path, typestore(ros1)) as w:
        for k, f in enumerate(frames):
            w.write("/elevation_map", GRIDMAP, 0.25 * k, to_message(f, ros1, (k, 2 * k)))
    if name == "run2":  # a ROS 2 bag directory
        assert (path / "metadata.yaml").is_file()
    for k, f in enumerate(frames):
        got = load_grid_map(path, "/elevation_map", 0.25 * k + 0.1)  # the last map by then
        assert np.allclose(got.heightmap.elevation, f.heightmap.elevation, atol=1e-6)
        assert np.allclose(got.heightmap.origin, f.heightmap.origin)
    first = load_grid_map(path, "/elevation_map")
    assert np.allclose(first.heightmap.origin, frames[0].heightmap.origin)
    assert [p.name for p in tmp_path.iterdir()] == [name]  # nothing else left behind


def test_mcap_is_read_by_the_mcap_library(tmp_path: Path) -> None:
    from mcap.reader import make_reader

    frames = _maps(3, np.random.default_rng(1))
    path = tmp_path / "maps.mcap"
    with BagWriter(path, typestore(False)) as w:
        for k, f in enumerate(frames):
            w.write("/em", GRIDMAP, k, to_message(f))
    with path.open("rb") as fh:
        reader = make_reader(fh)
        schemas = reader.get_summary().schemas.values()
        assert [(s.name, s.encoding) for s in schemas] == [(GRIDMAP, "ros2msg")]
        raw = [(m.log_time, m.data) for _, _, m in reader.iter_messages(topics=["/em"])]
    assert [t for t, _ in raw] == [0, 1_000_000_000, 2_000_000_000]
    store = typestore(False)
    for (_, data), f in zip(raw, frames, strict=True):
        msg = store.deserialize_cdr(data, GRIDMAP)
        assert np.allclose(from_message(msg).heightmap.elevation, f.heightmap.elevation, atol=1e-6)


def test_a_writer_that_fails_leaves_nothing(tmp_path: Path) -> None:
    path = tmp_path / "x.mcap"
    with pytest.raises(RuntimeError), BagWriter(path, typestore(False)) as w:
        w.write("/em", GRIDMAP, 0.0, to_message(_maps(1, np.random.default_rng(0))[0]))
        raise RuntimeError("stop")
    assert list(tmp_path.iterdir()) == []


def _bag(tmp_path: Path) -> Path:
    path = tmp_path / "maps.mcap"
    store = typestore(False)
    odom = store.types["nav_msgs/msg/Odometry"]
    with BagWriter(path, store) as w:  # the recording starts at 0.5 s, its map 0.5 s later
        w.write("/odom", "nav_msgs/msg/Odometry", 0.5, _odometry(odom, store))
        w.write("/em", GRIDMAP, 1.0, to_message(_maps(1, np.random.default_rng(0))[0]))
    return path


def _odometry(cls: Any, store: Any) -> Any:
    t = store.types
    zero = t["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
    pose = t["geometry_msgs/msg/Pose"](
        position=t["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=0.0),
        orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
    )
    return cls(
        header=t["std_msgs/msg/Header"](
            stamp=t["builtin_interfaces/msg/Time"](sec=1, nanosec=0), frame_id="odom"
        ),
        child_frame_id="base_link",
        pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
        twist=t["geometry_msgs/msg/TwistWithCovariance"](
            twist=t["geometry_msgs/msg/Twist"](linear=zero, angular=zero), covariance=np.zeros(36)
        ),
    )


def test_bad_recordings_are_one_clear_error(tmp_path: Path) -> None:
    bag = _bag(tmp_path)
    with pytest.raises(ConfigError, match="no topic '/nope'"):
        load_grid_map(bag, "/nope")
    with pytest.raises(ConfigError, match="'/odom' carries nav_msgs/msg/Odometry, not grid_map"):
        load_grid_map(bag, "/odom")
    with pytest.raises(ConfigError, match="no map on '/em' by time 0.4 s"):
        load_grid_map(bag, "/em", 0.4)
    assert load_grid_map(bag, "/em", 0.5).stamp == 0.0  # from the start: the map's own stamp 0
    truncated = tmp_path / "cut.mcap"
    truncated.write_bytes(bag.read_bytes()[: bag.stat().st_size // 2])
    with pytest.raises(ConfigError, match="not a readable recording"):
        load_grid_map(truncated, "/em")
    garbage = tmp_path / "junk.bag"
    garbage.write_bytes(b"#ROSBAG V2.0\n" + b"\x00" * 40)
    with pytest.raises(ConfigError, match="not a readable recording"):
        list(messages(garbage, {"/em": GRIDMAP}))


def test_a_map_without_elevation_is_refused() -> None:
    msg = to_message(_maps(1, np.random.default_rng(2))[0])
    msg.layers = ["height"]
    with pytest.raises(ConfigError, match="no 'elevation' layer"):
        from_message(msg, "x.mcap [/em]")
    msg.layers = ["elevation"]
    msg.info.length_x = msg.info.length_x * 2
    with pytest.raises(
        ConfigError, match=r"data\[elevation\]: has 48 values, the map's size is 16x6"
    ):
        from_message(msg, "x.mcap [/em]")


def _problem(tmp_path: Path, terrain: str) -> Path:
    robot = ROOT / "problems" / "robots" / "cameleon.yaml"
    route = "{waypoints: [[0.0, 0.0], [0.6, 0.0]], speed: 0.2, turn_radius: 0.5}"
    text = f"robot: {robot}\nterrain: {terrain}\npath: {route}\n"
    path = tmp_path / "p.yaml"
    path.write_text(text)
    return path


def test_a_recorded_plane_gives_the_ramps_answer(tmp_path: Path) -> None:
    import mmstab

    slope, res = 0.2, 0.05
    n = 80  # 4 m square around the origin
    xy = (np.arange(n) - (n - 1) / 2) * res
    plane = np.tan(slope) * np.repeat(xy[:, None], n, axis=1)  # z = y tan(slope): the ramp
    hm = Heightmap(plane, res, np.array([xy[0], xy[0]]))
    with BagWriter(tmp_path / "plane.mcap", typestore(False)) as w:
        w.write("/em", GRIDMAP, 0.0, to_message(GridMapFrame(hm, "odom", 0.0), start_index=(7, 30)))
    problem = mmstab.load_problem(_problem(tmp_path, "{file: plane.mcap, topic: /em, time: 0.0}"))
    ramp = mmstab.Ramp(slope)
    # headings along and across the slope: the ramp's heading (in its slope plane) and the
    # heightmap's yaw (in G) name the same direction there
    poses = np.array(
        [[0.0, 0.0, 0.0], [0.3, -0.2, np.pi / 2], [-0.2, 0.1, np.pi], [0.1, 0.3, -np.pi / 2]]
    )
    g_map = problem.terrain.gravity_body(poses)
    g_ramp = ramp.gravity_body(poses)
    assert np.allclose(g_map, g_ramp, atol=1e-4)  # float32 heights: ~1e-7 m


def test_cli_refuses_a_missing_topic_in_one_line(tmp_path: Path) -> None:
    _bag(tmp_path)
    p = _problem(tmp_path, "{file: maps.mcap, topic: /nope}")
    env = {**os.environ, "MPLBACKEND": "Agg"}
    r = subprocess.run(
        [sys.executable, "-m", "mmstab", "plan", str(p), "-o", str(tmp_path / "out")],
        capture_output=True, text=True, env=env, cwd=ROOT, timeout=120,
    )  # fmt: skip
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "maps.mcap: topic: no topic '/nope'" in lines[0]
    assert not (tmp_path / "out").exists()
