"""Lower bounds on the distance of the arm's capsules to boxes and to each other (C kernel).

:meth:`mmstab.model.collision.CollisionChecker.keeps_clearance` measures with FCL only the
postures these bounds cannot clear: a capsule is a segment grown by its radius, so its
distance to a box is the segment's less the radius (``collision_distance.c``: golden-section
search of the convex distance along the segment, minus what the bracket leaves open), to
another capsule the segments' distance less both radii (closest points of two segments).
Most pairs whose bounding spheres come near keep the clearance by centimetres: bounded
here for a whole move at once instead of one FCL call per posture. The bounds lose
:data:`SLACK` [m] more, so that FCL's GJK round-off never decides differently where a bound
clears a posture (``tests/model/test_collision_bounds.py`` compares them with FCL).
Compiled on first use (:mod:`mmstab.core.clib`); without a C compiler, None: every
posture goes to FCL as before.
"""

from __future__ import annotations

import ctypes
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from mmstab.core.clib import DOUBLE, DOUBLES, LONG, compiled_library
from mmstab.core.files import MmstabError
from mmstab.model.robot import FloatArray

SOURCE = Path(__file__).with_name("collision_distance.c")  #: the kernel's C source
#: Taken off every bound [m]: FCL's distances (GJK) are exact to about 1e-6 m.
SLACK = 1e-5


@lru_cache(maxsize=1)
def _kernels() -> tuple[Any, Any] | None:
    try:
        lib = ctypes.CDLL(str(compiled_library(SOURCE, "mmstab_collision_distance")))
    except MmstabError:
        return None
    box, seg = lib.mmstab_segment_box, lib.mmstab_segment_segment
    box.argtypes = [DOUBLES, DOUBLES, LONG, DOUBLES, DOUBLES, LONG, DOUBLES, DOUBLE, DOUBLES]
    seg.argtypes = [DOUBLES, DOUBLES, DOUBLES, DOUBLES, LONG, DOUBLES]
    for f in (box, seg):
        f.restype = ctypes.c_int
    return box, seg


def available() -> bool:
    """Whether the kernel compiled (a C compiler was found)."""
    return _kernels() is not None


def _c(x: FloatArray) -> FloatArray:
    return np.ascontiguousarray(x, dtype=np.float64)


def segment_box(
    a0: FloatArray,
    a1: FloatArray,
    centre: FloatArray,
    R: FloatArray,
    half: FloatArray,
    stop: float = np.inf,
) -> FloatArray:
    """Lower bound on each segment's distance to a box (n,) [m].

    Args:
        a0: the segments' first ends in B (n, 3) [m].
        a1: their second ends (n, 3) [m].
        centre: the box's centre in B (3,), or one box per segment (n, 3) [m].
        R: the box's rotation, its frame to B (3, 3), or one per segment (n, 3, 3).
        half: the box's half extents (3,) [m].
        stop: the search for a segment ends once its bound is at least this [m] or a
            distance below it is found (then the bound is below it too); ``inf``: to
            round-off.
    """
    kernels = _kernels()
    assert kernels is not None, "collision_distance: no C compiler (check available())"
    n = len(a0)
    out = np.empty(n)
    per_row = int(np.ndim(centre) == 2)
    kernels[0](_c(a0), _c(a1), n, _c(centre), _c(R), per_row, _c(half), stop + SLACK, out)
    return out - SLACK


def segment_segment(a0: FloatArray, a1: FloatArray, b0: FloatArray, b1: FloatArray) -> FloatArray:
    """Lower bound on the distance of segments a0-a1 and b0-b1 (n, 3 each) in B, (n,) [m]."""
    kernels = _kernels()
    assert kernels is not None, "collision_distance: no C compiler (check available())"
    out = np.empty(len(a0))
    kernels[1](_c(a0), _c(a1), _c(b0), _c(b1), len(a0), out)
    return out - SLACK
