"""The arm-CoM workspace V (paper Section II-B, Fig. 3; ``docs/design.md``, "Workspace").

Brute force over a grid of the four joint angles: forward kinematics and self-collision
(:mod:`mmstab.collision`) label every posture's arm CoM (body frame B) valid or invalid,
then ``V = hull(all CoMs) minus hull(invalid CoMs)``, tested with the hulls' half-spaces.

Membership follows ``docs/design.md`` ("Workspace"): ``A_all p <= b_all and not
(A_bad p <= b_bad)``, both with a slack of ``HULL_TOL``, so the boundary of hull(invalid)
is not in V. Building is ``build_workspace`` (no files); ``load_or_build_workspace`` adds
the cache under ``results/workspace/<key>.npz``, keyed by the robot description, the grid
and ``WORKSPACE_VERSION``.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import hashlib
import os
import sys
import threading
import time
from collections.abc import Iterator, Sequence
from concurrent.futures import Executor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import ConvexHull, QhullError, cKDTree
from scipy.spatial.distance import cdist
from tqdm import tqdm

from mmstab.collision import CollisionChecker
from mmstab.config import MmstabError, write_npz
from mmstab.pool import ChunkPool, run_interruptibly
from mmstab.problem import Problem
from mmstab.robot import FloatArray, Robot
from mmstab.sizes import announce, workspace_estimate

#: Bump when labelling or the cache format changes: old cache files are then ignored.
WORKSPACE_VERSION = 1
#: Where ``load_or_build_workspace`` keeps built workspaces (relative to the working folder).
DEFAULT_CACHE_DIR = Path("results") / "workspace"
#: Postures per chunk handed to a worker.
DEFAULT_CHUNK = 16384
#: From this many postures on, ``build_workspace`` uses a process pool by default.
PARALLEL_MIN_POSTURES = 50_000
#: Processes of that pool (:class:`mmstab.pool.ChunkPool`).
PARALLEL_WORKERS = 2
#: Half-space slack of the membership tests [m].
HULL_TOL = 1e-9
#: A joint whose range is a full turn within this [rad] does not sample its upper end.
FULL_TURN_TOL = 1e-6
#: Points per block when a cloud is reduced to its hull's candidates (``hull_candidates``).
HULL_BLOCK = 65536
#: A cloud whose smallest principal spread is below this share of the largest is flat.
FLAT_TOL = 1e-9


class JointGrid(NamedTuple):
    """The posture grid: per-joint samples and spacing.

    Attributes:
        axes: sample values of each joint, four arrays [rad].
        step: spacing of each joint's samples (4,) [rad].
    """

    axes: tuple[FloatArray, ...]
    step: FloatArray

    @property
    def shape(self) -> tuple[int, ...]:
        """Samples per joint."""
        return tuple(len(a) for a in self.axes)

    @property
    def size(self) -> int:
        """Number of postures."""
        return int(np.prod(self.shape))


def joint_grid(robot: Robot, counts: Sequence[int]) -> JointGrid:
    """Evenly spaced samples of each joint within its limits.

    A joint spanning a full turn (the turret, [0, 2 pi]) omits its upper end, which is
    the same posture as its lower end.

    Args:
        robot: the robot (joint limits).
        counts: samples per joint, four integers >= 2.
    """
    axes, step = [], []
    for n, lo, hi in zip(counts, robot.joint_lower, robot.joint_upper, strict=True):
        full_turn = abs((hi - lo) - 2 * np.pi) <= FULL_TURN_TOL
        axes.append(np.linspace(lo, hi, int(n), endpoint=not full_turn))
        step.append((hi - lo) / (n if full_turn else n - 1))
    return JointGrid(tuple(axes), np.array(step))


def grid_postures(grid: JointGrid, start: int = 0, stop: int | None = None) -> FloatArray:
    """Postures ``start:stop`` of the grid (n, 4) [rad].

    Order: joint 1 slowest, then joints 2 and 3, joint 0 (the turret) fastest. A chunk
    then holds few values of the early joints, each at every turret angle, so the
    collision checker reuses most link-vs-base and link-vs-link answers within it.
    """
    stop = grid.size if stop is None else stop
    n0, n1, n2, n3 = grid.shape
    i1, i2, i3, i0 = np.unravel_index(np.arange(start, stop), (n1, n2, n3, n0))
    return np.column_stack([grid.axes[0][i0], grid.axes[1][i1], grid.axes[2][i2], grid.axes[3][i3]])


# ----------------------------------------------------------------------------------- hulls
class HalfSpaces(NamedTuple):
    """A convex polytope ``{p : A p <= b}``.

    Attributes:
        A: outward facet normals (F, 3).
        b: offsets (F,) [m].
    """

    A: FloatArray
    b: FloatArray


def hull_candidates(points: FloatArray, block: int = HULL_BLOCK) -> FloatArray:
    """The points of a cloud that may be vertices of its convex hull (M, 3) [m].

    Each block's own hull vertices: a vertex of the whole hull is a vertex of the hull of
    any block holding it, so ``hull(candidates) = hull(points)`` (on the default grid the
    half-spaces come out identical). Qhull cannot be interrupted; one block takes tens of
    milliseconds, so a Ctrl-C is handled between blocks instead of after one long call on
    millions of points. A block without a hull (flat, too small) is kept whole.
    """
    if len(points) <= block:
        return points
    keep = []
    for s in range(0, len(points), block):
        b = points[s : s + block]
        try:
            keep.append(b[ConvexHull(b).vertices])
        except QhullError:
            keep.append(b)
    return np.vstack(keep)


def convex_hull(points: ArrayLike, what: str) -> ConvexHull:
    """Convex hull of a 3-D cloud, or a clear error when the cloud is degenerate.

    Args:
        points: the cloud (N, 3) [m].
        what: what the cloud is, for the error message.

    Raises:
        MmstabError: fewer than 4 points, or all on a plane or line.
    """
    pts = np.asarray(points, dtype=float)
    n = len(pts)
    if n < 4:
        raise MmstabError(
            f"{what}: {n} points cannot span a 3-D convex hull (need 4 not on a "
            "plane); refine the workspace grid"
        )
    pts = hull_candidates(pts)
    spread = np.linalg.svd(pts - pts.mean(axis=0), compute_uv=False)
    if spread[-1] <= FLAT_TOL * spread[0]:
        raise MmstabError(
            f"{what}: the {n} points lie on a plane or a line, so their convex hull "
            "has no volume; refine the workspace grid"
        )
    try:
        return ConvexHull(pts)
    except QhullError as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else "Qhull failed"
        raise MmstabError(f"{what}: convex hull failed ({first})") from None


def halfspaces(hull: ConvexHull) -> HalfSpaces:
    """Half-space form of a hull; coplanar triangles' duplicate facets are merged."""
    eq = np.unique(np.round(hull.equations, 10), axis=0)
    return HalfSpaces(A=eq[:, :3], b=-eq[:, 3])


def hull_diameter(points: FloatArray, block: int = 2048) -> float:
    """Largest distance between two points of a cloud (N, 3) [m]."""
    best = 0.0
    for s in range(0, len(points), block):
        best = max(best, float(cdist(points[s : s + block], points).max()))
    return best


def _inside(points: FloatArray, hs: HalfSpaces, slack: float) -> NDArray[np.bool_]:
    """``all(A p <= b + slack)`` per point, in cache-sized blocks (no N x F temporary)."""
    block = min(max(2**17 // max(len(hs.b), 1), 16), 4096)
    if len(points) <= block:  # small batches (the planner's populations): one product
        return (points @ hs.A.T - hs.b).max(axis=1, initial=-np.inf) <= slack
    out = np.empty(len(points), dtype=bool)
    AT = np.ascontiguousarray(hs.A.T)
    buf = np.empty((block, len(hs.b)))
    for s in range(0, len(points), block):
        p = points[s : s + block]
        excess = buf[: len(p)]
        np.matmul(p, AT, out=excess)
        excess -= hs.b
        out[s : s + block] = excess.max(axis=1, initial=-np.inf) <= slack
    return out


# ------------------------------------------------------------------------------- workspace
@dataclass(frozen=True, eq=False)
class Workspace:
    """The arm-CoM workspace V and the clouds it was built from (body frame B).

    Attributes:
        grid: samples per joint.
        valid_q: collision-free postures (Nv, 4) [rad].
        valid_com: their arm CoMs (Nv, 3) [m].
        invalid_q: colliding postures (Ni, 4) [rad].
        invalid_com: their arm CoMs (Ni, 3) [m].
        A_all: facet normals of hull(all CoMs) (F, 3); ``A_all p <= b_all`` inside.
        b_all: offsets (F,) [m].
        A_bad: facet normals of hull(invalid CoMs) (G, 3); G = 0 when no posture collides.
        b_bad: offsets (G,) [m].
        diameter: d_workspace, the diameter of hull(all CoMs) (Eq. 6) [m].
        build_seconds: wall time of the build (0 if unknown) [s].
    """

    grid: tuple[int, int, int, int]
    valid_q: FloatArray
    valid_com: FloatArray
    invalid_q: FloatArray
    invalid_com: FloatArray
    A_all: FloatArray
    b_all: FloatArray
    A_bad: FloatArray
    b_bad: FloatArray
    diameter: float
    build_seconds: float = 0.0

    def contains(self, points: ArrayLike) -> NDArray[np.bool_]:
        """Whether body-frame points lie in V: in hull(all) and not in hull(invalid).

        Args:
            points: (N, 3) or (3,) arm-CoM positions in the body frame [m].

        Returns:
            (N,) bool ((1,) for a single point).
        """
        pts = np.atleast_2d(np.asarray(points, dtype=float))
        inside = _inside(pts, HalfSpaces(self.A_all, self.b_all), HULL_TOL)
        if len(self.b_bad) and inside.any():
            inside[inside] = ~_inside(pts[inside], HalfSpaces(self.A_bad, self.b_bad), HULL_TOL)
        return inside

    @functools.cached_property
    def valid_com_in_V(self) -> FloatArray:
        """The valid CoMs that V contains (M, 3) [m] (V drops some: see ``recall``)."""
        return self.valid_com[self.contains(self.valid_com)]

    def violation(self, points: ArrayLike) -> FloatArray:
        """How far body-frame points (N, 3) lie outside V, 0 inside [m].

        Outside hull(all): the largest facet violation; inside hull(invalid): the depth
        to its nearest facet. Facet normals are unit (Qhull), so both are distances to a
        facet plane (a lower bound on the distance to V). Ranks infeasible CMA samples.
        Zero exactly where :meth:`contains` is true (same products, same ``HULL_TOL``).
        """
        pts = np.atleast_2d(np.asarray(points, dtype=float))
        excess = (pts @ self.A_all.T - self.b_all).max(axis=1, initial=-np.inf)
        out = np.maximum(excess, 0.0)
        inside = excess <= HULL_TOL
        if len(self.b_bad):
            depth = (self.b_bad - pts @ self.A_bad.T).min(axis=1)
            in_bad = depth >= -HULL_TOL
            inside &= ~in_bad
            out = np.where(excess > HULL_TOL, out, np.maximum(depth, 0.0))
        return np.where(inside, 0.0, np.maximum(out, HULL_TOL))

    @functools.cached_property
    def _valid_tree(self) -> cKDTree:
        return run_interruptibly(cKDTree, self.valid_com)  # seconds for millions: Ctrl-C

    def nearest_valid_posture(self, point: ArrayLike) -> FloatArray:
        """The collision-free grid posture whose arm CoM is nearest to a point.

        Args:
            point: arm-CoM target (3,) or (N, 3) in the body frame [m].

        Returns:
            posture (4,) or (N, 4) [rad].
        """
        _, idx = self._valid_tree.query(np.asarray(point, dtype=float))
        return self.valid_q[idx].copy()

    @property
    def postures(self) -> int:
        """Number of grid postures."""
        return len(self.valid_q) + len(self.invalid_q)

    @functools.cached_property
    def volume_all(self) -> float:
        """Volume of hull(all CoMs) [m^3]."""
        return float(convex_hull(np.vstack([self.valid_com, self.invalid_com]), "all CoMs").volume)

    @functools.cached_property
    def volume_invalid(self) -> float:
        """Volume of hull(invalid CoMs) [m^3]; 0 when no posture collides."""
        if not len(self.b_bad):
            return 0.0
        return float(convex_hull(self.invalid_com, "invalid CoMs").volume)

    @property
    def volume_V(self) -> float:
        """Volume of V [m^3]: exact, since hull(invalid) lies inside hull(all)."""
        return self.volume_all - self.volume_invalid


def workspace_from_clouds(
    grid: Sequence[int],
    valid_q: ArrayLike,
    valid_com: ArrayLike,
    invalid_q: ArrayLike,
    invalid_com: ArrayLike,
    build_seconds: float = 0.0,
) -> Workspace:
    """Hulls, half-spaces and diameter of labelled CoM clouds.

    Args:
        grid: samples per joint.
        valid_q: collision-free postures (Nv, 4) [rad].
        valid_com: their arm CoMs (Nv, 3), body frame [m].
        invalid_q: colliding postures (Ni, 4) [rad]; may be empty (then V = hull(all)).
        invalid_com: their arm CoMs (Ni, 3) [m].
        build_seconds: wall time of the labelling, recorded in the result [s].

    Raises:
        MmstabError: no valid posture, or a degenerate (flat, too small) cloud.
    """
    vq, vc = np.asarray(valid_q, float).reshape(-1, 4), np.asarray(valid_com, float).reshape(-1, 3)
    iq, ic = (
        np.asarray(invalid_q, float).reshape(-1, 4),
        np.asarray(invalid_com, float).reshape(-1, 3),
    )
    if len(vc) == 0:
        raise MmstabError("no collision-free posture on the workspace grid: check the geometry")
    hull_all = convex_hull(np.vstack([vc, ic]), "all arm CoMs")
    hs_all = halfspaces(hull_all)
    if len(ic):
        hs_bad = halfspaces(convex_hull(ic, "invalid (colliding) arm CoMs"))
    else:
        hs_bad = HalfSpaces(np.zeros((0, 3)), np.zeros(0))
    return Workspace(
        grid=tuple(int(n) for n in grid),  # type: ignore[arg-type]
        valid_q=vq,
        valid_com=vc,
        invalid_q=iq,
        invalid_com=ic,
        A_all=hs_all.A,
        b_all=hs_all.b,
        A_bad=hs_bad.A,
        b_bad=hs_bad.b,
        diameter=hull_diameter(hull_all.points[hull_all.vertices]),
        build_seconds=float(build_seconds),
    )


# ---------------------------------------------------------------------------------- build
_CHECKERS: dict[tuple[str, int], CollisionChecker] = {}  # per robot, process and thread


def _checker(robot: Robot) -> CollisionChecker:
    key = (robot.source_hash, threading.get_ident())
    if key not in _CHECKERS or not robot.source_hash:
        _CHECKERS[key] = CollisionChecker(robot)
    return _CHECKERS[key]


def label_chunk(
    robot: Robot, grid: JointGrid, start: int, stop: int
) -> tuple[int, NDArray[np.bool_], FloatArray]:
    """Label grid postures ``start:stop`` (runs in a worker).

    Returns:
        ``start``, collision-free flags (n,), arm CoMs (n, 3) in the body frame [m].
    """
    checker = _checker(robot)
    q = grid_postures(grid, start, stop)
    frames = checker.kinematics.link_frames(q)
    free = ~np.asarray(checker.collides(q, frames=frames), dtype=bool)
    return start, free, arm_com_from_frames(robot, frames)


def arm_com_from_frames(robot: Robot, frames: FloatArray) -> FloatArray:
    """Arm CoM g_a (N, 3) in the body frame [m] from link frames B_T_R_i (N, 4, 4, 4).

    The same quantity as ``robot.arm_com(q)`` (Eq. 1), without repeating the kinematics.
    """
    masses = np.array([link.mass for link in robot.links])
    com_link = np.array([link.com for link in robot.links])[:, :, None]  # (4, 3, 1) in R_i
    coms = (frames[..., :3, :3] @ com_link)[..., 0] + frames[..., :3, 3]  # (N, 4, 3) in B
    return (coms * masses[:, None]).sum(axis=1) / masses.sum()


def build_workspace(
    robot: Robot,
    grid: Sequence[int],
    executor: Executor | None = None,
    chunk: int = DEFAULT_CHUNK,
    progress: bool = True,
) -> Workspace:
    """Label every grid posture and build V (no cache; see ``load_or_build_workspace``).

    Args:
        robot: the robot.
        grid: samples per joint, four integers >= 2.
        executor: runs the chunks (any ``concurrent.futures.Executor``); default: a
            :class:`~mmstab.pool.ChunkPool` of ``PARALLEL_WORKERS`` processes from
            ``PARALLEL_MIN_POSTURES`` postures on (stopped at once by Ctrl-C), else this
            process.
        chunk: postures per chunk.
        progress: show a tqdm progress bar.
    """
    t0 = time.perf_counter()
    jg = joint_grid(robot, grid)
    n = jg.size
    bounds = [(s, min(s + chunk, n)) for s in range(0, n, chunk)]
    free = np.empty(n, dtype=bool)
    com = np.empty((n, 3))
    with contextlib.ExitStack() as stack:
        results: Iterator[tuple[int, NDArray[np.bool_], FloatArray]]
        light = dataclasses.replace(robot)  # without the cached CasADi kinematics
        if executor is not None:
            futures = [executor.submit(label_chunk, light, jg, a, b) for a, b in bounds]
            results = (f.result() for f in as_completed(futures))
        elif n >= PARALLEL_MIN_POSTURES and (os.cpu_count() or 1) > 1:
            # killable on Ctrl-C, workers included (mmstab.pool)
            pool = stack.enter_context(ChunkPool(label_chunk, (light, jg), PARALLEL_WORKERS))
            results = pool.run(bounds)
        else:
            results = (label_chunk(robot, jg, a, b) for a, b in bounds)
        with tqdm(total=n, unit="posture", desc="workspace", disable=not progress) as bar:
            for start, f, c in results:
                free[start : start + len(f)] = f
                com[start : start + len(f)] = c
                bar.update(len(f))
    q = grid_postures(jg)
    return workspace_from_clouds(
        grid, q[free], com[free], q[~free], com[~free], time.perf_counter() - t0
    )


# ---------------------------------------------------------------------------------- cache
def workspace_key(robot: Robot, grid: Sequence[int]) -> str:
    """Cache key of a robot description, a grid and the code version."""
    text = f"v{WORKSPACE_VERSION}|{robot.source_hash}|{[int(n) for n in grid]}"
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def save_workspace(path: str | os.PathLike[str], ws: Workspace) -> Path:
    """Write a workspace to ``.npz`` atomically."""
    arrays = {f.name: getattr(ws, f.name) for f in dataclasses.fields(ws)}
    return write_npz(path, version=WORKSPACE_VERSION, **arrays)


def load_workspace(path: str | os.PathLike[str]) -> Workspace:
    """Read a workspace written by :func:`save_workspace`.

    Raises:
        ValueError: the file is from another ``WORKSPACE_VERSION``.
    """
    with np.load(path) as z:
        if int(z["version"]) != WORKSPACE_VERSION:
            raise ValueError(f"{path}: workspace cache version {int(z['version'])}")
        kw = {f.name: z[f.name] for f in dataclasses.fields(Workspace)}
    kw["grid"] = tuple(int(n) for n in kw["grid"])
    kw["diameter"] = float(kw["diameter"])
    kw["build_seconds"] = float(kw["build_seconds"])
    return Workspace(**kw)


def _short(exc: BaseException, width: int = 60) -> str:
    """``Type: first line of the message`` within about ``width`` characters."""
    text = (str(exc).splitlines() or [""])[0]
    text = text if len(text) <= width else text[: width - 3] + "..."
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def load_or_build_workspace(
    problem: Problem,
    force: bool = False,
    progress: bool = True,
    cache_dir: str | os.PathLike[str] | None = None,
    executor: Executor | None = None,
) -> Workspace:
    """The problem's workspace: from the cache when robot and grid are unchanged, else built.

    Args:
        problem: the problem (robot and ``workspace.grid``).
        force: rebuild (and overwrite the cache) even when a cached copy matches.
        progress: show a progress bar while building.
        cache_dir: cache folder (default ``results/workspace``).
        executor: passed to :func:`build_workspace`.
    """
    grid = tuple(problem.section("workspace")["grid"])
    path = Path(cache_dir if cache_dir is not None else DEFAULT_CACHE_DIR)
    path = path / f"{workspace_key(problem.robot, grid)}.npz"
    if not force and path.is_file():
        try:
            return load_workspace(path)
        except Exception as exc:  # noqa: BLE001 - any unreadable cache (0-byte, cut, garbage)
            why = _short(exc)
            print(
                f"mmstab: notice: workspace cache {path} unreadable ({why}); rebuilding",
                file=sys.stderr,
            )
    if progress:
        announce(workspace_estimate(grid))
    ws = build_workspace(problem.robot, grid, executor=executor, progress=progress)
    save_workspace(path, ws)
    return ws


def workspace_cache_path(problem: Problem, cache_dir: str | os.PathLike[str] | None = None) -> Path:
    """Where ``load_or_build_workspace`` keeps the problem's workspace."""
    base = Path(cache_dir if cache_dir is not None else DEFAULT_CACHE_DIR)
    return base / f"{workspace_key(problem.robot, problem.section('workspace')['grid'])}.npz"
