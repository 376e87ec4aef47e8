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
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from mmstab.core.clib import BYTES, DOUBLE, DOUBLES, LONG, LONGS, compiled_library
from mmstab.core.files import MmstabError
from mmstab.model.robot import FloatArray

SOURCE = Path(__file__).with_name("collision_distance.c")  #: the kernel's C source
#: Taken off every bound [m]: FCL's distances (GJK) are exact to about 1e-6 m.
SLACK = 1e-5


@lru_cache(maxsize=1)
def _kernels() -> tuple[Any, Any, Any] | None:
    try:
        lib = ctypes.CDLL(str(compiled_library(SOURCE, "mmstab_collision_distance")))
    except MmstabError:
        return None
    box, seg, near = lib.mmstab_segment_box, lib.mmstab_segment_segment, lib.mmstab_pairs_near
    box.argtypes = [DOUBLES, DOUBLES, LONG, DOUBLES, DOUBLES, LONG, DOUBLES, DOUBLE, DOUBLES]
    seg.argtypes = [DOUBLES, DOUBLES, DOUBLES, DOUBLES, LONG, DOUBLES]
    # R p n L kind hl rad hb ball bc br bh P pa pb skip need slack_sphere slack | near
    # (the table's arrays by address: converted once per table, _table_addresses)
    near.argtypes = [DOUBLES, DOUBLES, LONG, LONG, *[ctypes.c_void_p] * 8, LONG]
    near.argtypes += [ctypes.c_void_p, ctypes.c_void_p, LONGS, DOUBLE, DOUBLE, DOUBLE, BYTES]
    for f in (box, seg, near):
        f.restype = ctypes.c_int
    return box, seg, near


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


class PairTable(NamedTuple):
    """A checker's shapes and pairs as the kernel reads them (:func:`pairs_near`).

    Attributes:
        kind: per link, 1 a capsule, 0 a box (L,).
        half_length: a capsule's half length [m] (L,).
        radius: a capsule's radius [m] (L,).
        box_half: a box link's half extents [m] (L, 3).
        ball: each link shape's bounding radius about its centre [m] (L,).
        base_centre: the base boxes' centres in B (B, 3) [m].
        base_R: their rotations, box frame to B (B, 3, 3).
        base_half: their half extents (B, 3) [m].
        link: each pair's link (P,).
        other: its other link, or -1 - b for base box b (P,).
    """

    kind: NDArray[np.int64]
    half_length: FloatArray
    radius: FloatArray
    box_half: FloatArray
    ball: FloatArray
    base_centre: FloatArray
    base_R: FloatArray
    base_half: FloatArray
    link: NDArray[np.int64]
    other: NDArray[np.int64]


def pairs_near(
    table: PairTable,
    R: FloatArray,
    p: FloatArray,
    need: float,
    skip: NDArray[np.int64],
    sphere_slack: float,
) -> NDArray[np.bool_]:
    """Per posture and pair, whether its bounds leave it possibly within ``need`` [m] (N, P).

    The bounding spheres' gap (less ``sphere_slack`` [m]) first, then the capsules'
    segments against the boxes and each other (less :data:`SLACK`); a box against a base
    box by its sphere alone. Pairs with ``skip`` 1 are never near.

    Args:
        table: the checker's shapes and pairs.
        R: each link shape's rotation in B per posture (N, L, 3, 3).
        p: its centre in B (N, L, 3) [m].
        need: the clearance asked [m].
        skip: per pair, 1 to leave it out (P,).
        sphere_slack: taken off the spheres' gap [m] (the checker's culling slack).
    """
    kernels = _kernels()
    assert kernels is not None, "collision_distance: no C compiler (check available())"
    n, L = p.shape[:2]
    P = len(table.link)
    out = np.zeros((n, P), dtype=np.uint8)
    a = _table_addresses(table)
    kernels[2](
        _c(R), _c(p), n, L, *a[:8], P, *a[8:],
        np.ascontiguousarray(skip, dtype=np.int64), float(need), float(sphere_slack),
        SLACK, out,
    )  # fmt: skip
    return out.view(bool)


#: Per table (by id, the table kept to check it): its arrays as the kernel reads them, and
#: their addresses (a table's arrays are converted once, not at every call).
_ADDRESSES: dict[int, tuple[PairTable, tuple[np.ndarray, ...], tuple[int, ...]]] = {}


def _table_addresses(table: PairTable) -> tuple[int, ...]:
    """The addresses of ``table``'s arrays in :func:`pairs_near`'s order (kind .. other)."""
    kept = _ADDRESSES.get(id(table))
    if kept is None or kept[0] is not table:
        t = table
        arrays = (
            np.ascontiguousarray(t.kind, dtype=np.int64),
            *(np.ascontiguousarray(x, dtype=np.float64) for x in (
                t.half_length, t.radius, t.box_half, t.ball, t.base_centre, t.base_R,
                t.base_half,
            )),
            np.ascontiguousarray(t.link, dtype=np.int64),
            np.ascontiguousarray(t.other, dtype=np.int64),
        )  # fmt: skip
        kept = (table, arrays, tuple(int(x.ctypes.data) for x in arrays))
        _ADDRESSES[id(table)] = kept
    return kept[2]
