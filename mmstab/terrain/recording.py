"""Elevation maps from robot recordings: ROS 1 bags, ROS 2 bags and MCAP files (``rosbags``).

A recording is a ``.mcap`` file, a ROS 1 ``.bag`` or a ROS 2 bag directory (``metadata.yaml``
beside its ``.db3``/``.mcap`` files). Its ``grid_map_msgs/GridMap`` messages are read with the
pure-Python ``rosbags`` library (no ROS install): the definitions a recording carries are
used, else :mod:`mmstab.terrain.gridmap`'s. A problem file names one map of a recording as its
terrain: ``terrain: {file: run.mcap, topic: /elevation_map, time: 12.5}``, ``time`` [s] from
the recording's start (the last map received by then; without ``time``, the first map).

Every failure (not a recording, truncated, no such topic, another message type, a map
without an ``elevation`` layer) is one :class:`~mmstab.core.files.ConfigError` naming the
file and the field.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, NamedTuple

from mmstab.core.files import ConfigError
from mmstab.terrain.gridmap import GRIDMAP, GridMapFrame, from_message, typestore

#: What a recording's ``file`` may be (a ROS 2 bag is a directory).
RECORDING_SUFFIXES = (".mcap", ".bag")
#: The topic an elevation mapping publishes by default.
DEFAULT_TOPIC = "/elevation_mapping/elevation_map"


class RecordedMessage(NamedTuple):
    """One message of a recording.

    Attributes:
        topic: its topic.
        msgtype: its type (``pkg/msg/Name``).
        time: receive time from the recording's start [s].
        message: the deserialised message.
    """

    topic: str
    msgtype: str
    time: float
    message: Any


def is_recording(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` names a recording (``.mcap``, ``.bag`` or a ROS 2 bag directory)."""
    p = Path(path)
    return p.suffix.lower() in RECORDING_SUFFIXES or (p / "metadata.yaml").is_file()


@contextmanager
def open_recording(path: str | os.PathLike[str]) -> Iterator[Any]:
    """An open ``rosbags`` AnyReader on the recording; errors as one ConfigError.

    Raises:
        ConfigError: no such file, or not a readable recording (the reader's own words).
    """
    from rosbags.highlevel import AnyReader

    p = Path(path)
    if not p.exists():
        raise ConfigError(p, "", "no such recording")
    ros1 = p.suffix.lower() == ".bag"
    try:
        reader = AnyReader([p], default_typestore=typestore(ros1))
        reader.open()
    except Exception as exc:  # rosbags raises many kinds; all mean "unreadable"
        raise ConfigError(p, "", f"not a readable recording: {_words(exc)}") from None
    try:
        yield reader
    finally:
        reader.close()


def _words(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


def messages(
    path: str | os.PathLike[str], topics: dict[str, str | tuple[str, ...]]
) -> Iterator[RecordedMessage]:
    """The messages of the given topics, in receive order, deserialised.

    Args:
        path: the recording.
        topics: topic -> the message type(s) it must carry (``pkg/msg/Name``).

    Raises:
        ConfigError: a topic missing or carrying another type, a truncated or corrupt
            message (naming the recording and the topic).
    """
    with open_recording(path) as reader:
        start = reader.start_time
        chosen = []
        for topic, wanted in topics.items():
            wanted_types = (wanted,) if isinstance(wanted, str) else wanted
            found = [c for c in reader.connections if c.topic == topic]
            if not found:
                have = sorted({c.topic for c in reader.connections})
                raise ConfigError(path, "topic", f"no topic {topic!r} (recorded: {have})")
            for c in found:
                if c.msgtype not in wanted_types:
                    raise ConfigError(
                        path, "topic", f"{topic!r} carries {c.msgtype}, not {wanted_types[0]}"
                    )
            chosen += found
        try:
            for conn, stamp, raw in reader.messages(connections=chosen):
                msg = reader.deserialize(raw, conn.msgtype)
                yield RecordedMessage(conn.topic, conn.msgtype, (stamp - start) * 1e-9, msg)
        except ConfigError:
            raise
        except Exception as exc:
            raise ConfigError(path, "", f"unreadable message: {_words(exc)}") from None


def grid_maps(
    path: str | os.PathLike[str], topic: str = DEFAULT_TOPIC
) -> Iterator[tuple[float, GridMapFrame]]:
    """Every GridMap on ``topic``: (time from the recording's start [s], the map)."""
    for m in messages(path, {topic: GRIDMAP}):
        yield m.time, from_message(m.message, f"{path} [{topic} at {m.time:.3f} s]")


def load_grid_map(
    path: str | os.PathLike[str], topic: str = DEFAULT_TOPIC, time: float | None = None
) -> GridMapFrame:
    """The map a problem's ``terrain: {file, topic, time}`` names.

    Args:
        path: the recording.
        topic: the GridMap topic.
        time: [s] from the recording's start: the last map received by then; None: the
            first map.

    Raises:
        ConfigError: as :func:`messages`, or no map by ``time``.
    """
    chosen: GridMapFrame | None = None
    for t, frame in grid_maps(path, topic):
        if time is None:
            return frame
        if t > time:
            break
        chosen = frame
    if chosen is None:
        when = "in the recording" if time is None else f"by time {time} s"
        raise ConfigError(path, "time", f"no map on {topic!r} {when}")
    return chosen
