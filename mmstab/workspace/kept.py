"""Arrays derived from a cached roadmap, kept beside its file so a new process reads them.

A one-off plan needs more than the roadmap's file: the graph of the nodes above the
ground clearance and its components (:func:`mmstab.planner.grounded.ground_graph`), the
start node (``Roadmap.connect``: a k-d tree over every node), its shortest-path tree and
the component's clusters. Each is the same in every process, so the first process writes
it into ``roadmap-<key>/<name>/`` beside ``roadmap-<key>.npz`` (one uncompressed ``.npy``
per array, each written atomically, then ``_stamp.npy``: the roadmap file's modification
time) and every later one reads it there, memory-mapped copy-on-write (only the pages a
plan touches are read). A rebuilt roadmap's old files are not used (computed and written
again). Without a cache file (a roadmap built in memory) nothing is kept.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from mmstab.core.files import write_npy

#: The attribute of a loaded roadmap naming its file (set by ``load_or_build_roadmap``).
SOURCE_ATTR = "_source_file"


def kept_arrays(
    roadmap: Any, name: str, compute: Callable[[], dict[str, np.ndarray]]
) -> dict[str, np.ndarray]:
    """The arrays ``compute()`` gives for ``roadmap``, read from beside its file if kept there.

    Args:
        roadmap: a roadmap (any object; its file from the ``_source_file`` attribute).
        name: the arrays' name, unique per roadmap (a file name's part).
        compute: computes them (called when not kept, or kept for another build).
    """
    source: Path | None = getattr(roadmap, SOURCE_ATTR, None)
    if source is None:
        return compute()
    return kept_beside(source, name, compute)


def kept_beside(
    source: Path, name: str, compute: Callable[[], dict[str, np.ndarray]]
) -> dict[str, np.ndarray]:
    """:func:`kept_arrays` by the cache file ``source`` itself (module text)."""
    try:
        stamp = source.stat().st_mtime_ns
    except OSError:
        return compute()
    folder = source.with_suffix("") / name
    try:
        if int(np.load(folder / "_stamp.npy")) == stamp:
            return {f.stem: _mapped(f) for f in sorted(folder.glob("*.npy")) if f.stem != "_stamp"}
    except (OSError, ValueError):
        pass
    arrays = compute()
    try:  # the stamp last: a folder cut short is never read
        (folder / "_stamp.npy").unlink(missing_ok=True)
        for old in folder.glob("*.npy"):
            old.unlink()
        for key, value in arrays.items():
            write_npy(folder / f"{key}.npy", value)
        write_npy(folder / "_stamp.npy", np.int64(stamp))
    except OSError:  # a read-only cache folder: computed in every process
        pass
    return arrays


def _mapped(path: Path) -> np.ndarray:
    """The array of a ``.npy`` file, memory-mapped copy-on-write (read where touched)."""
    try:
        return np.asarray(np.load(path, mmap_mode="c"))
    except ValueError:  # an empty array cannot be mapped
        return np.load(path)
