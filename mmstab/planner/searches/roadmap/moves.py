"""The arm's moves between the nodes ``method: roadmap`` chose (:mod:`~.searches.roadmap`).

A move is a shortest roadmap path (the start node's shortest-path tree, else A*, else the
whole component), shortcut where the cut is free, on the nodes whose arm stays
``planner.ground_clearance`` above the support plane (:mod:`mmstab.planner.grounded`).

**Ground under the arm.** With the ground under the arm at each pose
(:class:`mmstab.planner.ground.under_arm.GroundUnderArm`) a move into pose k's node is checked
against the ground of both poses it joins (k − 1 and k; the first move of an open path:
pose 0's): the arm moves while the base drives from one to the other, so every posture of
the move must clear the ground at either end. A path whose nodes or sampled postures are too
low is searched again without those nodes (a masked A*), at most :data:`REROUTES` times; a
shortcut that is too low is not taken; the nodes found too low at a pair of poses are kept
(:class:`~mmstab.planner.searches.roadmap.Mover`) and masked at the first search again of
the next move between them: near a ditch with a 12° ``attitude_margin`` a move otherwise
found the same low nodes again, move after move. When no path clears both grounds,
:func:`ground_move` answers None and the caller forbids that pair of nodes and chooses again.
"""

from __future__ import annotations

import ctypes
import heapq
from collections.abc import Generator
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from mmstab.core.clib import compiled_library
from mmstab.core.files import MmstabError
from mmstab.core.steps import drain
from mmstab.model.collision import CollisionChecker
from mmstab.model.robot import FloatArray, Robot
from mmstab.planner.ground.under_arm import GroundUnderArm
from mmstab.planner.grounded import ground_graph, shortcut_above_steps
from mmstab.workspace.kept import kept_arrays
from mmstab.workspace.roadmap import Roadmap

#: Node expansions of an A* query before the whole component is searched instead.
ASTAR_EXPANSIONS = 20000
#: Searches of one move with the nodes found too low masked before the move is given up.
REROUTES = 20


def start_tree(
    roadmap: Roadmap, start: int, ground: float | None = None
) -> tuple[int, NDArray[np.int32]]:
    """Shortest-path tree from node ``start`` (its predecessors), kept with the roadmap.

    Every plan's first move leaves the arm's start node (the stowed arm's): one search
    over the whole component, once (on the nodes ``ground`` [m] above the plane, if set),
    kept in memory and beside the roadmap's cache file (:mod:`mmstab.workspace.kept`).
    """
    trees = getattr(roadmap, "_trees", None)
    if trees is None:
        trees = {}
        object.__setattr__(roadmap, "_trees", trees)
    if (start, ground) not in trees:

        def compute() -> dict[str, np.ndarray]:
            graph = ground_graph(roadmap, ground).graph
            return {"pred": dijkstra(graph, indices=start, return_predecessors=True)[1]}

        name = f"tree-{start}-{None if ground is None else float(ground)!r}"
        trees[start, ground] = kept_arrays(roadmap, name, compute)["pred"]
    return start, trees[start, ground]


#: The A* kernel's C source (:func:`astar`; without a C compiler the same loop in Python).
ASTAR_SOURCE = Path(__file__).with_name("astar.c")


@lru_cache(maxsize=1)
def _astar_kernel() -> Any:
    """The compiled ``mmstab_astar`` (pointers passed as addresses), or None (no compiler)."""
    try:
        lib = ctypes.CDLL(str(compiled_library(ASTAR_SOURCE, "mmstab_astar")))
    except MmstabError:
        return None
    f = lib.mmstab_astar
    ptr, long = ctypes.c_void_p, ctypes.c_long
    # indptr indices weights q N J a b masked expansions best parent | path
    f.argtypes = [ptr, ptr, ptr, ptr, long, long, long, long, ptr, long, ptr, ptr, ptr]
    f.restype = long
    return f


def _astar_arrays(roadmap: Roadmap, ground: float | None) -> dict[str, np.ndarray]:
    """The graph as the kernel reads it and its work arrays, kept per roadmap and ground."""
    kept = getattr(roadmap, "_astar_arrays", None)
    if kept is None:
        kept = {}
        object.__setattr__(roadmap, "_astar_arrays", kept)
    if ground not in kept:
        g, n = ground_graph(roadmap, ground).graph, len(roadmap.nodes_q)
        kept[ground] = {
            "indptr": np.ascontiguousarray(g.indptr, dtype=np.int64),
            "indices": np.ascontiguousarray(g.indices, dtype=np.int64),
            "weights": np.ascontiguousarray(g.data, dtype=np.float64),
            "q": np.ascontiguousarray(roadmap.nodes_q, dtype=np.float64),
            "best": np.full(n, np.inf),  # +inf again after every call (the kernel's text)
            "parent": np.zeros(n, dtype=np.int64),
            "path": np.zeros(n, dtype=np.int64),
            "masked": np.zeros(n, dtype=np.uint8),  # 0 again after every call
        }
    return kept[ground]


def prepare_astar(roadmap: Roadmap, ground: float | None) -> None:
    """Compile (first use) and load A*'s kernel and its arrays of the graph now."""
    if _astar_kernel() is not None:
        _astar_arrays(roadmap, ground)


def astar(
    roadmap: Roadmap,
    a: int,
    b: int,
    ground: float | None = None,
    masked: frozenset[int] = frozenset(),
) -> NDArray[np.intp] | None:
    """A shortest roadmap path a -> b (nodes), by A* with the lattice (L1) distance to b.

    Every edge changes one joint by its length and never wraps the turret, so the L1
    distance is a consistent lower bound and the path is a shortest one; with ties
    broken towards the deepest node, a free staircase costs about its length in node
    expansions where Dijkstra's search bounded at 1.5 times the distance (the previous
    query) explored a 4-D ball of nodes (16 ms a move on a random route). None when
    ``ASTAR_EXPANSIONS`` nodes did not reach b. With ``ground`` [m]: on the nodes whose
    arm stays that far above the support plane; never through the ``masked`` nodes.
    In C (``astar.c``, the same operations in the same order: the same path as
    :func:`astar_python`), 10x faster; in Python without a C compiler.
    """
    return astar_search(roadmap, a, b, ground, masked)[0]


def astar_search(
    roadmap: Roadmap,
    a: int,
    b: int,
    ground: float | None = None,
    masked: frozenset[int] = frozenset(),
) -> tuple[NDArray[np.intp] | None, bool]:
    """:func:`astar`'s path, and whether "no path" is proved (every node a reaches expanded).

    A search that stops at ``ASTAR_EXPANSIONS`` proves nothing (False).
    """
    kernel = _astar_kernel()
    if kernel is None:
        return astar_python_search(roadmap, a, b, ground, masked)
    w = _astar_arrays(roadmap, ground)
    q = w["q"]
    mask = w["masked"]
    held = np.fromiter(masked, dtype=np.int64, count=len(masked))
    mask[held] = 1
    try:
        n = kernel(
            w["indptr"].ctypes.data, w["indices"].ctypes.data, w["weights"].ctypes.data,
            q.ctypes.data, q.shape[0], q.shape[1], int(a), int(b),
            mask.ctypes.data if len(held) else None, ASTAR_EXPANSIONS,
            w["best"].ctypes.data, w["parent"].ctypes.data, w["path"].ctypes.data,
        )  # fmt: skip
    finally:
        mask[held] = 0
    if n == -1:
        raise MemoryError("astar: the kernel ran out of memory")
    return (w["path"][:n].astype(np.intp) if n > 0 else None), n == -2


def astar_python(
    roadmap: Roadmap,
    a: int,
    b: int,
    ground: float | None = None,
    masked: frozenset[int] = frozenset(),
) -> NDArray[np.intp] | None:
    """:func:`astar` in Python (the reference of its C kernel; used without a compiler)."""
    return astar_python_search(roadmap, a, b, ground, masked)[0]


def astar_python_search(
    roadmap: Roadmap,
    a: int,
    b: int,
    ground: float | None = None,
    masked: frozenset[int] = frozenset(),
) -> tuple[NDArray[np.intp] | None, bool]:
    """:func:`astar_search` in Python."""
    # each expanded node's row as Python lists (the loop's cheapest reads), not the whole
    # graph converted at once (0.5-0.8 s, most of a cold plan's search on kerb.yaml)
    g, nodes_q = ground_graph(roadmap, ground).graph, roadmap.nodes_q
    ptr, nbr, w = g.indptr, g.indices, g.data
    goal = nodes_q[b].tolist()
    dist: dict[int, float] = {}  # each node's heuristic, computed once

    def h(n: int) -> float:
        v = dist.get(n)
        if v is None:
            v = dist[n] = sum(abs(x - y) for x, y in zip(nodes_q[n].tolist(), goal, strict=True))
        return v

    best, parent = {a: 0.0}, {a: a}
    heap = [(h(a), 0.0, a)]
    for _ in range(ASTAR_EXPANSIONS):
        if not heap:
            return None, True
        _, neg_g, n = heapq.heappop(heap)
        if n == b:
            out = [b]
            while out[-1] != a:
                out.append(parent[out[-1]])
            return np.array(out[::-1], dtype=np.intp), False
        if -neg_g > best[n]:
            continue  # a stale entry
        lo, hi = ptr[n], ptr[n + 1]
        for m, step in zip(nbr[lo:hi].tolist(), w[lo:hi].tolist(), strict=True):
            cost = best[n] + step
            if cost < best.get(m, np.inf) and m not in masked:
                best[m], parent[m] = cost, n
                heapq.heappush(heap, (cost + h(m), -cost, m))
    return None, not heap


def _path_nodes(
    roadmap: Roadmap,
    a: int,
    b: int,
    tree: tuple[int, NDArray[np.int32]] | None,
    ground: float | None,
    masked: frozenset[int] = frozenset(),
) -> NDArray[np.intp] | None:
    """The nodes of a shortest path a -> b avoiding ``masked`` (None: there is none)."""
    if a == b:
        return np.array([a], dtype=np.intp)
    if tree is not None and tree[0] == a and not masked:
        pred = tree[1]
    else:
        path, none = astar_search(roadmap, a, b, ground, masked)
        if path is not None:
            return path
        # no path when either side's search empties its open list (the graph is
        # undirected): a cornered node is proved so in a few expansions, where the
        # whole component's search takes 40 ms (a move whose ends the low nodes wall in)
        if none or b in masked or astar_search(roadmap, b, a, ground, masked - {a})[1]:
            return None
        graph = ground_graph(roadmap, ground).graph
        if masked:  # the whole component without the masked nodes
            graph = without_nodes(graph, masked)
        pred = dijkstra(graph, indices=a, return_predecessors=True)[1]
    if pred[b] < 0:
        return None
    out = [b]
    while out[-1] != a:
        out.append(int(pred[out[-1]]))
    return np.array(out[::-1], dtype=np.intp)


def without_nodes(graph: csr_matrix, nodes: frozenset[int]) -> csr_matrix:
    """The graph without the edges into or out of ``nodes`` (removed, not set to 0).

    csgraph takes an explicit zero for an edge of no length: through the nodes to avoid.
    """
    keep = np.ones(graph.shape[0], dtype=bool)
    keep[np.fromiter(nodes, dtype=np.intp, count=len(nodes))] = False
    nnz = int(graph.indptr[-1])  # a csr_matrix's arrays may be longer than its entries
    indices, data = graph.indices[:nnz], graph.data[:nnz]
    edge = np.repeat(keep, np.diff(graph.indptr)) & keep[indices]
    # copies: eliminate_zeros compacts indices and indptr in place, and a csr_matrix made
    # from arrays shares them (the kept ground graph would lose edges and misalign weights)
    out = csr_matrix(
        (np.where(edge, data, 0.0), indices.copy(), graph.indptr.copy()), shape=graph.shape
    )
    out.eliminate_zeros()
    return out


def roadmap_move(
    roadmap: Roadmap,
    a: int,
    b: int,
    tree: tuple[int, NDArray[np.int32]] | None = None,
    ground: float | None = None,
) -> FloatArray:
    """The shortest roadmap path a -> b as postures (n, 4) [rad].

    From ``tree``'s root (:func:`start_tree`, built with the same ``ground``) along the
    tree; else A* (:func:`astar`), else the whole component; with ``ground`` [m] on the
    nodes whose arm stays that far above the support plane.
    """
    nodes = _path_nodes(roadmap, a, b, tree, ground)
    assert nodes is not None, "a and b lie in one component"
    return roadmap.nodes_q[nodes].copy()


def ground_move(
    robot: Robot,
    roadmap: Roadmap,
    checker: CollisionChecker,
    a: int,
    b: int,
    ground: float | None,
    under: GroundUnderArm | None = None,
    ks: tuple[int, ...] = (),
    tree: tuple[int, NDArray[np.int32]] | None = None,
    tries: Tries | None = None,
    known: set[int] | None = None,
) -> FloatArray | None:
    """The move a -> b (n, 4) [rad] that keeps the arm ``ground`` [m] up (module text).

    Above the support plane always; with ``under``, above the ground under the arm at
    every pose of ``ks`` too. None: no roadmap path a -> b found that does. ``tries``: the
    paths and cuts of a, b computed before (:func:`ground_move_steps`), if any. ``known``:
    the nodes found too low at the poses ``ks`` by earlier moves (and here: added to).
    """
    steps = ground_move_steps(
        robot, roadmap, checker, a, b, ground, under, ks, tree, tries, known
    )  # fmt: skip
    return drain(steps)


#: A move's tries by the set of nodes masked: the shortest path's nodes (None: no path),
#: then its cut above the support plane. Neither depends on the ground under the arm.
Tries = dict[frozenset[int], list[Any]]


def ground_move_steps(
    robot: Robot,
    roadmap: Roadmap,
    checker: CollisionChecker,
    a: int,
    b: int,
    ground: float | None,
    under: GroundUnderArm | None = None,
    ks: tuple[int, ...] = (),
    tree: tuple[int, NDArray[np.int32]] | None = None,
    tries: Tries | None = None,
    known: set[int] | None = None,
) -> Generator[None, None, FloatArray | None]:
    """:func:`ground_move`, a step at a time (a path, a cut test); its tries kept in ``tries``.

    With the tries of an earlier run (the same a, b, ``ground``, ``tree``), only the checks
    against the ground under the arm run again where the same nodes are masked. ``known``
    (the nodes earlier moves between the same poses found too low): once the first path
    is too low, they are masked with the nodes found here (a move whose first path clears
    the ground is the same with or without them), and the nodes found here are added.
    """
    tries = {} if tries is None else tries

    def path(m: frozenset[int]) -> Generator[None, None, NDArray[np.intp] | None]:
        if m not in tries:
            tries[m] = [_path_nodes(roadmap, a, b, tree, ground, m)]
            yield
        return tries[m][0]

    def cut(m: frozenset[int]) -> Generator[None, None, FloatArray]:
        if len(tries[m]) < 2:
            q = roadmap.nodes_q[tries[m][0]]
            cut_q = yield from shortcut_above_steps(robot, roadmap, checker, q, ground, cuts)
            tries[m].append(cut_q)
        return tries[m][1]

    masked: frozenset[int] = frozenset()
    # this move's segments checked at ks and cuts tested (a reroute's path repeats most)
    swept: dict[Any, Any] = {}
    cuts: dict[Any, bool] = {}
    nodes = yield from path(masked)
    if under is None or ground is None or nodes is None:
        return None if nodes is None else (yield from cut(masked))
    for _ in range(REROUTES):
        q = roadmap.nodes_q[nodes]
        short = yield from cut(masked)
        same = len(short) == len(q) and np.array_equal(short, q)
        if not same and under.sweep_clear(ks, short, roadmap.reach, ground, swept)[1].all():
            return short  # the cut clears the ground: the path it cut is not needed
        node_ok, seg_ok = under.sweep_clear(ks, q, roadmap.reach, ground, swept)
        if seg_ok.all() and node_ok.all():
            return q
        low = {int(n) for n in nodes[~node_ok]}
        if a in low or b in low:
            return None
        if known is not None:  # too low at these poses for any move between them
            known |= low
            low |= known - {a, b}
        for i in np.flatnonzero(~seg_ok):  # an edge between clear nodes dips: mask its inner ends
            ends = {int(n) for n in nodes[i : i + 2]} - {a, b}
            if not ends:
                return None
            low |= ends
        masked = masked | low
        nodes = yield from path(masked)
        if nodes is None:
            return None
    return None
