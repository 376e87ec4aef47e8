"""Arrays derived from a cached roadmap, kept beside its file so a new process reads them.

A one-off plan needs more than the roadmap's file: the graph of the nodes above the
ground clearance and its components (:func:`mmstab.planner.grounded.ground_graph`), the
start node (``Roadmap.connect``: a k-d tree over every node), its shortest-path tree and
the component's clusters. Each is the same in every process, so the first process writes
it into ``roadmap-<key>/`` beside ``roadmap-<key>.npz`` (uncompressed ``.npz``, one per
name, written atomically) and every later one reads it there. Each file holds the
roadmap file's modification time: a rebuilt roadmap's old files are not used (computed
and written again). Without a cache file (a roadmap built in memory) nothing is kept.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from mmstab.core.files import write_npz_uncompressed

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
    path = source.with_suffix("") / f"{name}.npz"
    try:
        with np.load(path) as z:
            if int(z["_stamp"]) == stamp:
                return {k: z[k] for k in z.files if k != "_stamp"}
    except (OSError, ValueError, KeyError):
        pass
    arrays = compute()
    try:
        write_npz_uncompressed(path, _stamp=np.int64(stamp), **arrays)
    except OSError:  # a read-only cache folder: computed in every process
        pass
    return arrays
