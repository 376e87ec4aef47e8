"""``grid_map_msgs/GridMap`` <-> :class:`~mmstab.terrain.heightmap.Heightmap` (ANYbotics grid_map).

What a robot's elevation mapping (grid_map / elevation_mapping) publishes, in its own
storage convention, converted to mmstab's heightmap layout (``docs/terrain.md``):

* grid_map's index (i, j) runs along **-x** and **-y** of the map frame: cell (0, 0) sits at
  the map's +x/+y corner. The centre of cell (i, j) is
  ``position + length / 2 - (i + 1/2, j + 1/2) * resolution`` (``info.pose.position`` is
  the map's centre; grid_map maps are axis-aligned, so ``info.pose``'s rotation must be
  the identity);
* each layer is a ``std_msgs/Float32MultiArray``, stored column-major
  (``layout.dim[0].label == "column_index"``, the Eigen default; ``"row_index"`` first is
  row-major and is read too), ``size(0)`` rows along x and ``size(1)`` columns along y;
* the data is a circular buffer: the cell at index (i, j) is stored at
  ``((i + outer_start_index) % rows, (j + inner_start_index) % cols)``;
* NaN marks unknown cells, as in mmstab.

mmstab's heightmap has row = +y, column = +x and its origin at the centre of the -x/-y
corner cell, so ``elevation = M[::-1, ::-1].T`` of the unwrapped grid_map matrix ``M``.
The message definitions (ROS 1: the info carries the header; ROS 2: the map does) are
registered into a ``rosbags`` typestore here, so no ROS install is needed.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mmstab.core.files import ConfigError
from mmstab.terrain.heightmap import FloatArray, Heightmap, check_layout

GRIDMAP = "grid_map_msgs/msg/GridMap"
GRIDMAP_INFO = "grid_map_msgs/msg/GridMapInfo"
#: Layers a GridMap from an elevation mapping carries; only ``elevation`` is required.
ELEVATION, OPTIONAL_LAYERS = "elevation", ("variance", "traversability")

_MAP_BODY = """string[] layers
string[] basic_layers
std_msgs/Float32MultiArray[] data
uint16 outer_start_index
uint16 inner_start_index
"""
_INFO_BODY = """float64 resolution
float64 length_x
float64 length_y
geometry_msgs/Pose pose
"""
#: The message definitions, as grid_map_msgs ships them (comments left out).
MSG_ROS1 = {
    GRIDMAP_INFO: "std_msgs/Header header\n" + _INFO_BODY,
    GRIDMAP: "grid_map_msgs/GridMapInfo info\n" + _MAP_BODY,
    # not in rosbags' Noetic store; ROS 1's /tf carries it
    "tf2_msgs/msg/TFMessage": "geometry_msgs/TransformStamped[] transforms\n",
}
MSG_ROS2 = {
    GRIDMAP_INFO: _INFO_BODY,
    GRIDMAP: "std_msgs/Header header\ngrid_map_msgs/GridMapInfo info\n" + _MAP_BODY,
}
#: Largest rotation of ``info.pose`` from the identity read as axis-aligned [rad].
ROTATION_TOL = 1e-6


@functools.cache
def typestore(ros1: bool = False) -> Any:
    """A ``rosbags`` typestore (ROS 1 Noetic or ROS 2 Humble) that knows grid_map_msgs.

    Args:
        ros1: the ROS 1 definitions (a ``.bag``) rather than ROS 2's (MCAP, ROS 2 bags).
    """
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    types: dict[str, Any] = {}
    for name, text in (MSG_ROS1 if ros1 else MSG_ROS2).items():
        types.update(get_types_from_msg(text, name))
    store.register(types)
    return store


def ros_time(store: Any, t: float, kind: str = "Time") -> Any:
    """A ``builtin_interfaces`` ``Time`` (or ``Duration``) of ``t`` [s] in ``store``."""
    sec = int(np.floor(t))
    return store.types[f"builtin_interfaces/msg/{kind}"](
        sec=sec, nanosec=int(round((t - sec) * 1e9))
    )


def ros_header(store: Any, ros1: bool, t: float, frame_id: str) -> Any:
    """A ``std_msgs/Header`` at ``t`` [s] in ``frame_id`` (ROS 1's carries ``seq``)."""
    extra = {"seq": 0} if ros1 else {}
    return store.types["std_msgs/msg/Header"](stamp=ros_time(store, t), frame_id=frame_id, **extra)


@dataclass(frozen=True)
class GridMapFrame:
    """One elevation map, in mmstab's layout.

    Attributes:
        heightmap: the ``elevation`` layer (row = +y, column = +x, NaN unknown) [m].
        frame_id: the frame the map is given in (its poses are in this frame).
        stamp: the map's header time [s].
        layers: the optional layers present (``variance`` [m^2], ``traversability`` [-]),
            in the heightmap's layout.
    """

    heightmap: Heightmap
    frame_id: str
    stamp: float
    layers: dict[str, FloatArray] = field(default_factory=dict)


def _header(msg: Any) -> Any:
    """ROS 2 carries the header on the map, ROS 1 on its info."""
    return msg.header if hasattr(msg, "header") else msg.info.header


def _layer_matrix(source: str, array: Any, rows: int, cols: int, name: str) -> FloatArray:
    """A Float32MultiArray as the (rows, cols) buffer matrix (column-major by default)."""
    data = np.asarray(array.data, dtype=np.float64)
    if data.size != rows * cols:
        raise ConfigError(
            source, f"data[{name}]", f"has {data.size} values, the map's size is {rows}x{cols}"
        )
    dims = [d.label for d in array.layout.dim]
    row_major = bool(dims) and dims[0] == "row_index"
    return data.reshape(rows, cols) if row_major else data.reshape(cols, rows).T


def _check_pose(source: str, info: Any) -> None:
    o = info.pose.orientation
    tilt = np.linalg.norm([o.x, o.y, o.z])
    if not np.isfinite(tilt) or tilt > ROTATION_TOL:
        raise ConfigError(source, "info.pose.orientation", "grid maps must be axis-aligned")


def from_message(msg: Any, source: str = "<GridMap>") -> GridMapFrame:
    """A ``grid_map_msgs/GridMap`` message (ROS 1 or ROS 2 definition) as a heightmap.

    Args:
        msg: the deserialised message (``rosbags`` or anything with the same fields).
        source: where it came from (file and topic), for the error message.

    Raises:
        ConfigError: no ``elevation`` layer, sizes that do not add up, a rotated map.
    """
    info = msg.info
    res = float(info.resolution)
    if not np.isfinite(res) or res <= 0:
        raise ConfigError(source, "info.resolution", f"must be positive, got {res}")
    rows, cols = (round(float(info.length_x) / res), round(float(info.length_y) / res))
    layers = list(msg.layers)
    if ELEVATION not in layers:
        raise ConfigError(source, "layers", f"no {ELEVATION!r} layer (has {layers})")
    if len(msg.data) != len(layers):
        raise ConfigError(source, "data", f"{len(msg.data)} arrays for {len(layers)} layers")
    _check_pose(source, info)
    shift = (int(msg.outer_start_index), int(msg.inner_start_index))

    def unwrapped(name: str) -> FloatArray:
        buffer = _layer_matrix(source, msg.data[layers.index(name)], rows, cols, name)
        grid = np.roll(buffer, (-shift[0], -shift[1]), axis=(0, 1))  # index (0, 0) first
        return np.ascontiguousarray(grid[::-1, ::-1].T)  # row = +y, column = +x

    centre = np.array([info.pose.position.x, info.pose.position.y], dtype=float)
    length = np.array([rows, cols], dtype=float) * res
    origin = centre - length / 2 + res / 2
    elevation, res_, origin_ = check_layout(source, unwrapped(ELEVATION), res, origin)
    header = _header(msg)
    stamp = float(header.stamp.sec) + 1e-9 * float(header.stamp.nanosec)
    extra = {name: unwrapped(name) for name in OPTIONAL_LAYERS if name in layers}
    return GridMapFrame(Heightmap(elevation, res_, origin_, source), header.frame_id, stamp, extra)


def to_message(
    frame: GridMapFrame,
    ros1: bool = False,
    start_index: tuple[int, int] = (0, 0),
    row_major: bool = False,
) -> Any:
    """A heightmap as a ``grid_map_msgs/GridMap`` message (the inverse of :func:`from_message`).

    Args:
        frame: the map, its frame and stamp [s], and any optional layers.
        ros1: the ROS 1 definition (header in the info) rather than ROS 2's.
        start_index: the circular buffer's (outer, inner) start index [cells], as a map that
            has moved with the robot stores it.
        row_major: store the layers row-major (``row_index`` first) instead of grid_map's
            column-major default.
    """
    store = typestore(ros1)
    t = store.types
    hm = frame.heightmap
    ny, nx = hm.elevation.shape
    rows, cols = nx, ny  # grid_map: rows along x, columns along y
    header = ros_header(store, ros1, frame.stamp, frame.frame_id)
    length = np.array([rows, cols], dtype=float) * hm.resolution
    centre = hm.origin - hm.resolution / 2 + length / 2
    pose = t["geometry_msgs/msg/Pose"](
        position=t["geometry_msgs/msg/Point"](x=float(centre[0]), y=float(centre[1]), z=0.0),
        orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
    )
    info_args: dict[str, Any] = {
        "resolution": float(hm.resolution),
        "length_x": float(length[0]),
        "length_y": float(length[1]),
        "pose": pose,
    }
    if ros1:
        info_args["header"] = header
    info = t[GRIDMAP_INFO](**info_args)
    names = [ELEVATION, *frame.layers]
    data = [
        _multi_array(t, grid, start_index, row_major)
        for grid in [hm.elevation, *frame.layers.values()]
    ]
    map_args: dict[str, Any] = {
        "info": info,
        "layers": names,
        "basic_layers": [ELEVATION],
        "data": data,
        "outer_start_index": int(start_index[0]),
        "inner_start_index": int(start_index[1]),
    }
    if not ros1:
        map_args["header"] = header
    return t[GRIDMAP](**map_args)


def _multi_array(t: Any, grid: FloatArray, start: tuple[int, int], row_major: bool) -> Any:
    """One layer (mmstab layout) as grid_map's buffer in a Float32MultiArray."""
    matrix = np.asarray(grid)[::-1, ::-1].T  # index (0, 0) at +x/+y
    buffer = np.roll(matrix, start, axis=(0, 1))
    rows, cols = buffer.shape
    dim = t["std_msgs/msg/MultiArrayDimension"]
    if row_major:
        dims = [dim(label="row_index", size=rows, stride=rows * cols),
                dim(label="column_index", size=cols, stride=cols)]  # fmt: skip
        flat = buffer.ravel(order="C")
    else:
        dims = [dim(label="column_index", size=cols, stride=rows * cols),
                dim(label="row_index", size=rows, stride=rows)]  # fmt: skip
        flat = buffer.ravel(order="F")
    layout = t["std_msgs/msg/MultiArrayLayout"](dim=dims, data_offset=0)
    return t["std_msgs/msg/Float32MultiArray"](layout=layout, data=flat.astype(np.float32))
