"""The ground under the arm's one C kernel (``kernel.c``), called through ctypes.

Four functions of the check, each its NumPy twin operation for operation:

- :func:`pieces_kernel`: the arm's pieces in B for a batch of postures
  (:func:`mmstab.planner.ground.under_arm.pieces_in_body`, the lowest point over the body's
  tilts up to the attitude margin);
- :func:`heights_kernel`: one pose's least heights above the ground under the arm
  (:meth:`mmstab.planner.ground.under_arm.PoseGround.heights`, on the pose's peak map),
  the offline planner's;
- :func:`peak_map_kernel`: one pose's peak map on a terrain's lattice
  (:meth:`mmstab.planner.ground.under_arm.PoseGround._build`: the rise above the support
  plane, its max over blocks, then over the squares of blocks), the offline planner's;
- :func:`lattice_peak_kernel`: on a live map, the peaks of the ground's rise computed only
  where a piece asks and kept for the pose
  (:class:`~mmstab.planner.ground.map_lattice.LatticePeaks`), the online loop's.

Compiled on first use into one library (:mod:`mmstab.core.clib`); the NumPy functions stay
as the independent twin (``GroundUnderArm(backend="numpy")``; online without a C compiler),
equal bit for bit (tests/planner/test_under_arm_kernel.py,
tests/online/test_online_lattice.py).
"""

from __future__ import annotations

import ctypes
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mmstab.core.clib import DOUBLE, DOUBLES, LONG, LONGS, array_pointer, compiled_library
from mmstab.core.files import MmstabError

KERNEL_NAME = "mmstab_ground"  #: the library's name
KERNEL_SOURCE = Path(__file__).with_name("kernel.c")  #: its C source

_D, _L, _long, _double = DOUBLES, LONGS, LONG, DOUBLE


@lru_cache(maxsize=1)
def _kernels() -> tuple[Any, Any, Any, Any]:
    lib = ctypes.CDLL(str(compiled_library(KERNEL_SOURCE, KERNEL_NAME)))
    pieces, heights = lib.mmstab_arm_pieces, lib.mmstab_arm_heights
    peak, peak_map = lib.mmstab_lattice_peak, lib.mmstab_peak_map
    # frames n L link points radius mid P margin cm sm | low centre
    pieces.argtypes = [_D, _long, _long, _L, _D, _D, _D, _long, _long, _double, _double, _D, _D]
    # low centre at n P T cos top above plane peak rows cols i0 j0 block reach lattice slack | h
    heights.argtypes = [_D, _D, ctypes.c_void_p, _long, _long, _D, _double, _double, _double]
    heights.argtypes += [_long, _D]
    heights.argtypes += [_long, _long, _long, _long, _long, _long, _double, _double, _D]
    # elev ny nx origin res | plane steps sizes | blocks rows peaks | i j m out
    peak.argtypes = [_D, _long, _long, _D, _double, _D, _D, _L, _D, _D, _D, _L, _L, _long, _D]
    for f in (pieces, heights, peak):
        f.restype = ctypes.c_int
    # tiles ntx nty tile i0 j0 lattice T block half | rise blocks rows peak
    _P = array_pointer(np.uintp)
    peak_map.argtypes = [_P, _long, _long, _long, _long, _long, _double, _D, _long, _long]
    peak_map.argtypes += [_D, _D, _D, _D]
    peak_map.restype = ctypes.c_double
    return pieces, heights, peak, peak_map


def load_kernels() -> None:
    """Compile (first use) and load the kernels now, not within a plan's first pose."""
    _kernels()


def kernel_available() -> bool:
    """Whether the kernel compiles and loads here (else the online loop takes NumPy's path)."""
    try:
        _kernels()
    except (MmstabError, OSError):
        return False
    return True


def pieces_kernel(
    frames: NDArray[np.float64],
    link: NDArray[np.intp],
    points: NDArray[np.float64],
    radius: NDArray[np.float64],
    margin: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Each piece's lowest z_B and centre in B, from the postures' link frames.

    Args:
        frames: the links' frames in B per posture (n, L, 4, 4).
        link: each piece's link (P,).
        points: each piece's corners or segment ends in its link's frame (P, 8, 3) [m].
        radius: each piece's capsule radius, 0 for a box (P,) [m].
        margin: the body's tilt the lowest point is taken over [rad]; 0: none.

    Returns:
        low (n, P) [m] and centre (n, P, 3) [m].
    """
    F = np.ascontiguousarray(frames, dtype=np.float64)
    n, L = F.shape[:2]
    pts = np.ascontiguousarray(points, dtype=np.float64)
    P = len(pts)
    low, centre = np.empty((n, P)), np.empty((n, P, 3))
    _kernels()[0](
        F, n, L, np.ascontiguousarray(link, dtype=np.int64), pts,
        np.ascontiguousarray(radius, dtype=np.float64),
        np.ascontiguousarray(pts.mean(axis=1)), P, int(margin != 0.0),
        float(np.cos(margin)), float(np.sin(margin)), low, centre,
    )  # fmt: skip
    return low, centre


def heights_kernel(
    low: NDArray[np.float64],
    centre: NDArray[np.float64],
    M_T_B: NDArray[np.float64],
    top: float,
    above: float,
    plane: bool,
    peak: NDArray[np.float64],
    origin: tuple[int, int],
    block: int,
    reach: int,
    lattice: float,
    slack: float,
    rows: NDArray[np.intp] | None = None,
) -> NDArray[np.float64] | None:
    """One pose's least height of each posture above the ground under the arm (n,) [m].

    Args:
        low: the pieces' lowest z_B (m, P) [m].
        centre: their centres in B (m, P, 3) [m].
        M_T_B: the pose's resting body pose in M (4, 4).
        top: the peak map's max [m].
        above: pieces this far over the highest ground are not looked at closer [m].
        plane: pieces over ground not above the support plane: +inf.
        peak: the rise's max over squares about each block (rows, cols) [m].
        origin: lattice sample (i, j) of block (0, 0).
        block: lattice samples along a block's edge.
        reach: a piece's square must lie this many samples inside the map.
        lattice: the lattice step [m].
        slack: round-off allowance [m].
        rows: the postures' rows of ``low`` and ``centre`` (n,); None: all m, in order
            (the rows read where they are: no copy of the pieces).

    Returns:
        None when some piece's square leaves the map (the caller widens it).
    """
    lo = np.ascontiguousarray(low, dtype=np.float64)
    m, P = lo.shape
    at = None if rows is None else np.ascontiguousarray(rows, dtype=np.int64)
    if at is not None and len(at) and not (0 <= int(at.min()) and int(at.max()) < m):
        raise IndexError(f"heights_kernel: rows outside the {m} rows of the pieces")
    n = m if at is None else len(at)
    T = np.ascontiguousarray(M_T_B, dtype=np.float64)
    pk = np.ascontiguousarray(peak, dtype=np.float64)
    h = np.empty(n)
    code = _kernels()[1](
        lo, np.ascontiguousarray(centre, dtype=np.float64),
        None if at is None else at.ctypes.data, n, P, T, float(T[2, 2]),
        float(top), float(above), int(plane), pk, pk.shape[0], pk.shape[1],
        int(origin[0]), int(origin[1]), int(block), int(reach), float(lattice), float(slack), h,
    )  # fmt: skip
    return None if code else h


def lattice_peak_kernel(
    elev: NDArray[np.float64],
    origin: NDArray[np.float64],
    res: float,
    plane: NDArray[np.float64],
    steps: NDArray[np.float64],
    sizes: NDArray[np.int64],
    cache: NDArray[np.float64],
    i: NDArray[np.intp],
    j: NDArray[np.intp],
) -> NDArray[np.float64] | None:
    """A live map's peaks of the rise at lattice samples (i, j) (m,) [m], kept in ``cache``.

    Args:
        elev: the map's elevation (ny, nx) [m], NaN: unknown.
        origin: M (x, y) of the centre of cell [0, 0] [m].
        res: the map's resolution [m/cell].
        plane: the support plane: B's z axis and origin in M (6,) [-, m].
        steps: the lattice's step [m] and the unknown's fill above the plane [m].
        sizes: block, half (the peak's half-width [blocks]), the cached blocks' first (x, y)
            and counts.
        cache: blocks', rows' and peaks' maxima (3, rows, cols) [m], NaN: not yet (filled).
        i: the samples' lattice index along x (m,).
        j: along y (m,).

    Returns:
        None when a sample's square leaves the cached blocks (the caller takes NumPy's path).
    """
    out = np.empty(len(i))
    ny, nx = elev.shape
    code = _kernels()[2](
        elev, ny, nx, origin, res, plane, steps, sizes, cache[0], cache[1], cache[2],
        np.ascontiguousarray(i, dtype=np.int64), np.ascontiguousarray(j, dtype=np.int64),
        len(i), out,
    )  # fmt: skip
    return out if code == 0 else None


def peak_map_kernel(
    tiles: list[list[NDArray[np.float64]]],
    origin: tuple[int, int],
    lattice: float,
    M_T_B: NDArray[np.float64],
    block: int,
    half: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """One pose's peak map: the ground's rise above the support plane, max over squares.

    Args:
        tiles: the ground's z_M on the lattice by tiles (square, C-contiguous float64),
            ``tiles[tj][ti]`` along y then x (the mosaic ``GroundTiles.z_M`` would stack) [m].
        origin: lattice sample (i, j) of ``tiles[0][0][0, 0]``.
        lattice: the lattice step [m].
        M_T_B: the pose's resting body pose in M (4, 4) (its z_B = 0 is the plane).
        block: lattice samples along a block's edge.
        half: the squares' half-width [blocks].

    Returns:
        The blocks' maxima and their max over (2 half + 1)^2 blocks about each block (the
        edge's block beyond the edge), both (rows / block, cols / block) [m], and the
        blocks' max [m]. The samples must not be NaN (SciPy's filter's NaN rules are not
        followed): the caller checks.
    """
    tile, nty, ntx = len(tiles[0][0]), len(tiles), len(tiles[0])
    flat = [t for row in tiles for t in row]
    if not all(t.flags.c_contiguous and t.dtype == np.float64 for t in flat):
        raise ValueError("peak_map_kernel: the tiles must be C-contiguous float64")
    ptrs = np.array([t.ctypes.data for t in flat], dtype=np.uintp)
    shape = (nty * tile // block, ntx * tile // block)
    blocks, rows, peak = np.empty(shape), np.empty(shape), np.empty(shape)
    top = _kernels()[3](
        ptrs, ntx, nty, tile, int(origin[0]), int(origin[1]), float(lattice),
        np.ascontiguousarray(M_T_B, dtype=np.float64), int(block), int(half),
        np.empty(2 * ntx * tile), blocks, rows, peak,
    )  # fmt: skip
    return blocks, peak, float(top)
