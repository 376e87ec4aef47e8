"""Writing robot recordings: MCAP files, ROS 2 bags and ROS 1 bags, atomically (``rosbags``).

The format follows the output path: ``*.mcap`` a single MCAP file (ROS 2 messages, CDR,
schemas included, so Foxglove and ``ros2 bag`` read it), ``*.bag`` a ROS 1 bag, anything
else a ROS 2 bag directory (MCAP storage). Everything is written beside the target under a
temporary name and moved into place when the writer closes without error, so a failed run
leaves nothing half-written.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path
from types import TracebackType
from typing import Any

#: Output kinds by suffix.
MCAP, ROS1, ROS2_DIR = "mcap", "ros1", "ros2"


def bag_kind(path: str | os.PathLike[str]) -> str:
    """``mcap``, ``ros1`` or ``ros2`` (a directory) by the path's suffix."""
    suffix = Path(path).suffix.lower()
    return MCAP if suffix == ".mcap" else ROS1 if suffix == ".bag" else ROS2_DIR


class BagWriter:
    """A recording being written: ``with BagWriter(path, store) as w: w.write(...)``.

    Args:
        path: the output (its suffix picks the format, :func:`bag_kind`).
        store: the ``rosbags`` typestore that knows every message type written (ROS 1's
            for a ``.bag``, ROS 2's otherwise).
    """

    def __init__(self, path: str | os.PathLike[str], store: Any) -> None:
        self.path, self.store, self.kind = Path(path), store, bag_kind(path)
        self._connections: dict[str, Any] = {}
        self._tmp: Path | None = None
        self._writer: Any = None

    def __enter__(self) -> BagWriter:
        from rosbags.rosbag1 import Writer as Writer1
        from rosbags.rosbag2 import StoragePlugin
        from rosbags.rosbag2 import Writer as Writer2

        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._tmp = Path(tempfile.mkdtemp(prefix=f".{self.path.name}.", dir=self.path.parent))
        if self.kind == ROS1:
            self._writer = Writer1(self._tmp / self.path.name)
        else:  # rosbags writes a ROS 2 bag directory; a bare .mcap is its one storage file
            bag = self._tmp / (self.path.stem if self.kind == MCAP else self.path.name)
            self._writer = Writer2(bag, version=8, storage_plugin=StoragePlugin.MCAP)
        self._writer.open()
        return self

    def write(self, topic: str, msgtype: str, time: float, message: Any) -> None:
        """Add one message.

        Args:
            topic: the topic (its connection is made on first use).
            msgtype: the message type (``pkg/msg/Name``).
            time: receive time [s] (non-negative; nanoseconds in the file).
            message: the message (a class of ``store``).
        """
        conn = self._connections.get(topic)
        if conn is None:
            conn = self._writer.add_connection(topic, msgtype, typestore=self.store)
            self._connections[topic] = conn
        if self.kind == ROS1:
            raw = self.store.serialize_ros1(message, msgtype)
        else:
            raw = self.store.serialize_cdr(message, msgtype)
        self._writer.write(conn, int(round(time * 1e9)), raw)

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        assert self._tmp is not None
        try:
            self._writer.close()
            if exc_type is None:
                self._move_into_place()
        finally:
            shutil.rmtree(self._tmp, ignore_errors=True)

    def _move_into_place(self) -> None:
        assert self._tmp is not None
        if self.kind == ROS1:
            made = self._tmp / self.path.name
        elif self.kind == MCAP:
            bag = self._tmp / self.path.stem
            made = bag / f"{bag.name}.mcap"
        else:
            made = self._tmp / self.path.name
        if self.path.is_dir():
            shutil.rmtree(self.path)
        os.replace(made, self.path)
