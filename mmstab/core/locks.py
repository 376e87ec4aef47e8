"""One builder per cache file: processes that want the same file take turns.

Cache files are written atomically (:func:`mmstab.core.files.write_npz`), so two processes
building the same one never leave it corrupt; without a lock they would both build it (a
workspace V takes about a minute). :func:`build_lock` makes the second wait for the first and
then read its file. The lock is an advisory ``flock`` on ``<file>.lock`` beside the cache file
(released by the system when its holder exits, however it ends); where ``fcntl`` is missing
(Windows) the lock is a no-op and each process builds its own copy, as before.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX
    fcntl = None  # type: ignore[assignment]


@contextlib.contextmanager
def build_lock(path: str | os.PathLike[str]) -> Iterator[None]:
    """Hold the exclusive lock of the cache file ``path`` (waits while another process holds it).

    Args:
        path: the cache file to be read or built; its lock is ``<path>.lock`` (its folder is
            created if missing).
    """
    target = Path(path)
    if fcntl is None:
        yield
        return
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        fh = open(target.with_name(target.name + ".lock"), "a")  # noqa: SIM115
    except OSError:  # a read-only cache folder: no lock, each process builds its own copy
        yield
        return
    with fh:
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh.fileno(), fcntl.LOCK_UN)


def file_stamp(path: str | os.PathLike[str]) -> tuple[int, int] | None:
    """``(inode, mtime [ns])`` of a file (None: missing): has another process replaced it?

    Args:
        path: the file.
    """
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_ino, st.st_mtime_ns
