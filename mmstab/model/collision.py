"""Self-collision of the arm with the base and with itself (python-fcl, GJK).

The checker holds one FCL object per arm link and per base part (main body, two tracks,
two flippers), built once per robot. ``collides(q)`` labels many postures at once:

1. batched forward kinematics gives every link shape's pose in the body frame B;
2. pairs whose answer was already computed for the same relevant joints are reused: a
   link-vs-base pair depends only on the joints up to that link, a link-vs-link pair only
   on the joints between the two links (it is invariant under the joints before them);
3. pairs whose bounding sphere cannot reach the other body are culled in NumPy (sphere vs
   sphere, and sphere vs the base box for link-vs-base pairs);
4. FCL decides the surviving pairs, one ``fcl.collide`` each, reusing the objects.

Steps 2-3 only skip work: the answer is what FCL gives on every pair (tests check it).
"""

from __future__ import annotations

from typing import NamedTuple

import fcl
import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.model import collision_distance
from mmstab.model import frames as frames_c
from mmstab.model.collision_bounds import FLOOR_STEPS, turn_floor
from mmstab.model.parts import BASE_PARTS as PARTS_OF_BASE
from mmstab.model.robot import Box, FloatArray, Geometry, Robot

#: The base parts an arm link is checked against, in checking order.
BASE_PARTS = PARTS_OF_BASE


def arm_pairs(n: int) -> tuple[tuple[int, int], ...]:
    """The non-adjacent arm link pairs (i, j), i < j − 1, checked against each other."""
    return tuple((i, j) for i in range(n) for j in range(i + 2, n))


#: Non-adjacent arm link pairs of the 4-DoF arm.
ARM_PAIRS = arm_pairs(4)

#: Slack added to a culling distance so that round-off never culls a touching pair [m].
CULL_SLACK = 1e-9
#: Each robot's turn floors (:func:`mmstab.model.collision_bounds.turn_floor`), by its id.
_FLOORS: dict[int, tuple[Robot, dict[str, float]]] = {}


class Pair(NamedTuple):
    """One pair of bodies to check.

    Attributes:
        name: ``"<link>-<base part>"`` or ``"<link>-<link>"``.
        link: index of the first arm link.
        other: base part name, or the index of the second arm link.
        columns: the joints the pair's answer depends on (for reuse across postures).
    """

    name: str
    link: int
    other: str | int
    columns: tuple[int, ...]


def geometry_pose(geometry: Geometry) -> FloatArray:
    """Pose of the FCL shape's centre (capsule axis along its local z) in the owning frame.

    Args:
        geometry: a :class:`Box` or :class:`Capsule` expressed in its owning frame.

    Returns:
        4x4 homogeneous transform [m].
    """
    if isinstance(geometry, Box):
        return geometry.frame_T_shape
    T = np.eye(4)
    T[:3, 3] = geometry.center
    axis = geometry.p1 - geometry.p0
    length = np.linalg.norm(axis)
    if length > 0:
        z = axis / length
        helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        x = np.cross(helper, z)
        x /= np.linalg.norm(x)
        T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    return T


def fcl_geometry(geometry: Geometry) -> fcl.CollisionGeometry:
    """The FCL shape of a box or capsule (a zero-length capsule is a sphere)."""
    if isinstance(geometry, Box):
        return fcl.Box(*geometry.size)
    if geometry.length == 0:
        return fcl.Sphere(geometry.radius)
    return fcl.Capsule(geometry.radius, geometry.length)


def value_codes(q: FloatArray) -> NDArray[np.int64]:
    """Per joint, the rank of each posture's value among the distinct values (N, 4)."""
    codes = np.empty(q.shape, dtype=np.int64)
    for j in range(q.shape[1]):
        codes[:, j] = np.unique(q[:, j], return_inverse=True)[1].reshape(-1)
    return codes


def row_keys(codes: NDArray[np.int64], columns: tuple[int, ...]) -> NDArray[np.int64]:
    """One integer per row, equal exactly when the rows agree on ``columns``."""
    key = np.zeros(len(codes), dtype=np.int64)
    for j in columns:
        radix = int(codes[:, j].max(initial=0)) + 1
        if int(key.max(initial=0)) >= np.iinfo(np.int64).max // radix - radix:
            key = np.unique(key, return_inverse=True)[1].reshape(-1)  # renumber: no overflow
        key = key * radix + codes[:, j]
    return key


class CollisionChecker:
    """Arm self-collision checker (links vs base parts, non-adjacent links vs each other).

    Built once per robot; not thread-safe (it moves its FCL objects). For a process pool,
    build one per worker process.

    Pairs of bodies allowed to touch (``Robot.collision_allow``: the file's ``collision.allow``,
    as MoveIt's ``disable_collisions``, and, for a problem's robot, the pairs that touch at
    every posture: :mod:`mmstab.model.touching`) are never checked.

    Args:
        robot: the robot; its arm link geometry and base collision boxes are used.
    """

    def __init__(self, robot: Robot):
        self.robot = robot
        self.kinematics = robot.kinematics
        self.base_boxes: dict[str, Box] = robot.base.collision_boxes()
        # link shape pose in its link frame R_i, and the bounding radius about its centre
        shape_T = np.stack([geometry_pose(link.geometry) for link in robot.links])
        self._link_R_shape = shape_T[:, :3, :3]  # (4, 3, 3)
        self._link_p_shape = shape_T[:, :3, 3]  # (4, 3)
        self._c_R_shape = np.ascontiguousarray(self._link_R_shape, dtype=np.float64)
        self._c_p_shape = np.ascontiguousarray(self._link_p_shape, dtype=np.float64)
        self._fast: bool | None = None  # shape_poses in C: not yet checked
        self._link_radius = np.array([link.geometry.bounding_radius for link in robot.links])
        self._link_objs = [
            fcl.CollisionObject(fcl_geometry(link.geometry), fcl.Transform())
            for link in robot.links
        ]
        self._base_objs: dict[str, fcl.CollisionObject] = {}
        for name, box in self.base_boxes.items():
            T = box.frame_T_shape
            self._base_objs[name] = fcl.CollisionObject(
                fcl_geometry(box), fcl.Transform(T[:3, :3], T[:3, 3])
            )
        self._request = fcl.CollisionRequest()
        names = [link.name for link in robot.links]
        # link-vs-body first: it is the pair most often in contact, so later pairs skip more
        every = [
            Pair(f"{names[i]}-{part}", i, part, tuple(range(i + 1)))
            for part in BASE_PARTS
            if part in self.base_boxes  # a base without flippers has three parts
            for i in range(len(names))
        ] + [
            Pair(f"{names[i]}-{names[j]}", i, j, tuple(range(i + 1, j + 1)))
            for i, j in arm_pairs(len(names))
        ]

        def body(other: str | int) -> str:
            return other if isinstance(other, str) else names[other]

        #: the pairs allowed to touch (``Robot.collision_allow``): never checked
        self.allowed: tuple[str, ...] = tuple(
            pr.name
            for pr in every
            if frozenset((names[pr.link], body(pr.other))) in robot.collision_allow
        )
        self.pairs: tuple[Pair, ...] = tuple(pr for pr in every if pr.name not in self.allowed)
        # the base boxes' frames, kept for the pairs' gaps (:meth:`_gaps`)
        parts = list(self.base_boxes)
        geometries = [link.geometry for link in robot.links]
        self._table = collision_distance.PairTable(
            kind=np.array([0 if isinstance(g, Box) else 1 for g in geometries], dtype=np.int64),
            half_length=np.array([0.0 if isinstance(g, Box) else g.length / 2 for g in geometries]),
            radius=np.array([0.0 if isinstance(g, Box) else float(g.radius) for g in geometries]),
            box_half=np.array(
                [np.asarray(g.size) / 2 if isinstance(g, Box) else np.zeros(3) for g in geometries]
            ),
            ball=np.ascontiguousarray(self._link_radius, dtype=float),
            base_centre=np.stack([self.base_boxes[b].frame_T_shape[:3, 3] for b in parts]),
            base_R=np.ascontiguousarray(
                np.stack([self.base_boxes[b].frame_T_shape[:3, :3] for b in parts])
            ),
            base_half=np.stack([np.asarray(self.base_boxes[b].size) / 2 for b in parts]),
            link=np.array([pr.link for pr in self.pairs], dtype=np.int64),
            other=np.array(
                [-1 - parts.index(pr.other) if isinstance(pr.other, str) else pr.other
                 for pr in self.pairs], dtype=np.int64,
            ),
        )  # fmt: skip
        self._box_R, self._box_c = self._table.base_R, self._table.base_centre
        self._box_half, self._part = self._table.base_half, {b: k for k, b in enumerate(parts)}
        self._gap_column = {
            pr.name: (pr.link * len(parts) + parts.index(pr.other))
            if isinstance(pr.other, str)
            else len(robot.links) * len(parts) + k
            for k, pr in enumerate(self.pairs)
        }

    # ---------------------------------------------------------------------------- geometry
    def shape_poses(
        self, q: FloatArray, frames: FloatArray | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """Poses of the four link shapes in the body frame.

        Args:
            q: joint angles (N, 4) [rad].
            frames: ``kinematics.link_frames(q)`` (N, 4, 4, 4) if already computed.

        Returns:
            R (N, 4, 3, 3) rotations and p (N, 4, 3) shape centres [m], body frame.
        """
        frames = self.kinematics.link_frames(q) if frames is None else frames
        if self._fast is None:  # C where it gives NumPy's bits on this machine (frames.py)
            sample = self.kinematics.link_frames(frames_c.sample_postures(len(self.robot.links)))
            key = b"shapes" + self._c_R_shape.tobytes() + self._c_p_shape.tobytes()
            self._fast = frames_c.agrees(
                key, lambda: self._shape_poses_c(sample), lambda: self._shape_poses_np(sample)
            )
        out = self._shape_poses_c(frames) if self._fast else None
        return self._shape_poses_np(frames) if out is None else out

    def _shape_poses_c(self, frames: FloatArray) -> tuple[FloatArray, FloatArray] | None:
        F = np.ascontiguousarray(frames, dtype=np.float64)
        return frames_c.shape_poses(F, self._c_R_shape, self._c_p_shape)

    def _shape_poses_np(self, frames: FloatArray) -> tuple[FloatArray, FloatArray]:
        R_link, p_link = frames[..., :3, :3], frames[..., :3, 3]
        R = R_link @ self._link_R_shape
        p = (R_link @ self._link_p_shape[:, :, None])[..., 0] + p_link
        return R, p

    def _may_touch(self, pair: Pair, p: FloatArray, rows: NDArray[np.intp]) -> NDArray[np.bool_]:
        """Conservative test: False only where the pair certainly does not touch."""
        centre = p[rows, pair.link]
        radius = self._link_radius[pair.link]
        if isinstance(pair.other, str):  # bounding sphere vs the base box itself
            b = self._part[pair.other]
            local = (centre - self._box_c[b]) @ self._box_R[b]
            outside = np.maximum(np.abs(local) - self._box_half[b], 0.0)
            return np.einsum("ij,ij->i", outside, outside) <= (radius + CULL_SLACK) ** 2
        reach = radius + self._link_radius[pair.other] + CULL_SLACK
        d = centre - p[rows, pair.other]
        return np.einsum("ij,ij->i", d, d) <= reach**2

    def _fcl(
        self, pair: Pair, R: FloatArray, p: FloatArray, rows: NDArray[np.intp]
    ) -> NDArray[np.bool_]:
        """FCL answer of one pair at the given postures (row indices into R, p)."""
        a = self._link_objs[pair.link]
        if isinstance(pair.other, str):
            b, j = self._base_objs[pair.other], -1
        else:
            b, j = self._link_objs[pair.other], pair.other
        out = np.zeros(len(rows), dtype=bool)
        i, request, collide = pair.link, self._request, fcl.collide
        for k, n in enumerate(rows):
            a.setTransform(fcl.Transform(R[n, i], p[n, i]))
            if j >= 0:
                b.setTransform(fcl.Transform(R[n, j], p[n, j]))
            out[k] = collide(a, b, request, fcl.CollisionResult()) > 0
        return out

    # ------------------------------------------------------------------------------ public
    def collides(
        self,
        q: ArrayLike,
        cull: bool = True,
        frames: FloatArray | None = None,
        moving: int | None = None,
        groups: dict[tuple[int, ...], tuple[NDArray[np.intp], NDArray[np.intp]]] | None = None,
    ) -> NDArray[np.bool_] | bool:
        """Whether any checked pair of bodies intersects, for each posture.

        Args:
            q: joint angles (N, 4) or (4,) [rad].
            cull: skip pairs proven apart and reuse answers of identical relevant joints
                (False: FCL on every pair of every posture, the reference for tests).
            frames: ``kinematics.link_frames(q)`` (N, 4, 4, 4) if already computed.
            moving: the postures are this checker's free ones moved in this joint only: the
                pairs it does not move keep their free answer (a roadmap edge's interior).
            groups: per pair's ``columns``, the rows' groups of equal values there, as
                ``(first row, group of each row)`` (the caller knows them; else computed).

        Returns:
            (N,) bool, or a bool for one posture; True = some pair collides.
        """
        qa = np.asarray(q, dtype=float)
        single = qa.ndim == 1
        qa = np.atleast_2d(qa)
        R, p = self.shape_poses(qa, frames)
        codes = None
        groups = {} if groups is None else dict(groups)  # the caller's stays as given
        hit = np.zeros(len(qa), dtype=bool)
        pairs = [pr for pr in self.pairs if moving is None or moving in pr.columns]
        for pair in pairs:
            todo = np.flatnonzero(~hit)
            if todo.size == 0:
                break
            if cull:
                # rows that agree on the pair's joints share its answer: grouped once per set
                if pair.columns not in groups:
                    codes = value_codes(qa) if codes is None else codes
                    key = row_keys(codes, pair.columns)
                    _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
                    groups[pair.columns] = first, inverse.reshape(-1)
                first, inverse = groups[pair.columns]
                wanted = np.bincount(inverse[todo], minlength=len(first)) > 0
                reps = first[wanted]
                near = self._may_touch(pair, p, reps)
                group_hit = np.zeros(len(first), dtype=bool)
                group_hit[np.flatnonzero(wanted)[near]] = self._fcl(pair, R, p, reps[near])
                hit[todo] = group_hit[inverse[todo]]
            else:
                hit[todo] = self._fcl(pair, R, p, todo)
        return bool(hit[0]) if single else hit

    def _gap(self, pair: Pair, p: FloatArray) -> FloatArray:
        """Lower bound on the pair's distance per posture (N,) [m].

        Bounding spheres (the base box itself for link-vs-base pairs); negative where
        they overlap.
        """
        centre = p[:, pair.link]
        radius = self._link_radius[pair.link]
        if isinstance(pair.other, str):
            box = self.base_boxes[pair.other]
            local = (centre - box.center) @ box.frame_T_shape[:3, :3]
            outside = local - np.clip(local, -box.size / 2, box.size / 2)
            return np.linalg.norm(outside, axis=1) - radius - CULL_SLACK
        d = np.linalg.norm(centre - p[:, pair.other], axis=1)
        return d - radius - self._link_radius[pair.other] - CULL_SLACK

    def _segment_gap(
        self, pair: Pair, R: FloatArray, p: FloatArray, rows: NDArray[np.intp], need: float
    ) -> FloatArray | None:
        """Lower bound on the pair's distance at postures ``rows`` (m,) [m]: its segments'.

        From the capsules' segments (:mod:`mmstab.model.collision_distance`), decided
        against ``need`` [m] (exact enough to tell which postures keep it); None: a box
        against a base box, or no C compiler.
        """
        if not collision_distance.available():
            return None
        ends = [self._ends(i, R, p, rows) for i in (pair.link, pair.other) if isinstance(i, int)]
        if isinstance(pair.other, str):
            if ends[0] is None:
                return None
            box = self.base_boxes[pair.other]
            T = box.frame_T_shape
            a0, a1, r = ends[0]
            d = collision_distance.segment_box(a0, a1, T[:3, 3], T[:3, :3], box.size / 2, need + r)
            return d - r
        if ends[0] is not None and ends[1] is not None:
            (a0, a1, ra), (b0, b1, rb) = ends[0], ends[1]
            return collision_distance.segment_segment(a0, a1, b0, b1) - ra - rb
        box_link, seg = (pair.link, ends[1]) if ends[0] is None else (pair.other, ends[0])
        if seg is None:
            return None
        link_box = self.robot.links[box_link].geometry
        assert isinstance(link_box, Box)  # the pair's other shape has no segment: a box
        size = np.asarray(link_box.size, dtype=float)
        a0, a1, r = seg
        return (
            collision_distance.segment_box(
                a0, a1, p[rows, box_link], R[rows, box_link], size / 2, need + r
            )
            - r
        )

    def _ends(
        self, link: int, R: FloatArray, p: FloatArray, rows: NDArray[np.intp]
    ) -> tuple[FloatArray, FloatArray, float] | None:
        """A capsule link's segment ends in B at postures ``rows`` (m, 3) each, its radius [m]."""
        g = self.robot.links[link].geometry
        if isinstance(g, Box):
            return None
        axis = R[rows, link, :, 2] * (g.length / 2)  # the FCL capsule's axis: its z
        return p[rows, link] - axis, p[rows, link] + axis, float(g.radius)

    def turn_floors(self) -> dict[str, float]:
        """Least distance [m] over a full turn of the pairs one joint alone moves, by name.

        The first link against each base part (:func:`mmstab.model.collision_bounds.turn_floor`),
        computed once per robot.
        """
        kept = _FLOORS.get(id(self.robot))
        if kept is not None and kept[0] is self.robot:
            return kept[1]
        q = np.tile(np.asarray(self.robot.stowed, dtype=float), (FLOOR_STEPS + 1, 1))
        q[:, 0] = np.linspace(-np.pi, np.pi, FLOOR_STEPS + 1)
        R, p = self.shape_poses(q)
        floors: dict[str, float] = {}
        for pair in self.pairs:
            if pair.columns != (0,) or not isinstance(pair.other, str):
                continue
            geometry = self.robot.links[pair.link].geometry
            if isinstance(geometry, Box):
                signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
                corners, inflate = signs * np.asarray(geometry.size) / 2, 0.0  # shape frame
            else:
                half = geometry.length / 2
                corners, inflate = np.array([[0, 0, -half], [0, 0, half]]), geometry.radius
            floors[pair.name] = turn_floor(
                self._link_objs[pair.link], self._base_objs[pair.other],
                R[:, pair.link], p[:, pair.link], corners, inflate,
            )  # fmt: skip
        _FLOORS[id(self.robot)] = (self.robot, floors)
        return floors

    def _gaps(self, p: FloatArray) -> FloatArray:
        """:meth:`_gap` of every pair at once: (N, columns) [m], a pair's in ``_gap_column``.

        The link-vs-base columns first (link-major), then the pairs of links.
        """
        n, links = p.shape[0], p.shape[1]
        local = np.einsum("nlj,bji->nlbi", p, self._box_R)
        local -= np.einsum("bi,bij->bj", self._box_c, self._box_R)
        outside = local - np.clip(local, -self._box_half, self._box_half)
        d = np.sqrt(np.einsum("nlbi,nlbi->nlb", outside, outside))
        d -= (self._link_radius + CULL_SLACK)[None, :, None]
        out = np.full((n, links * len(self._box_R) + len(self.pairs)), np.inf)
        out[:, : links * len(self._box_R)] = d.reshape(n, -1)
        for pr in self.pairs:
            if isinstance(pr.other, int):
                i, j = pr.link, pr.other
                reach = self._link_radius[i] + self._link_radius[j] + CULL_SLACK
                out[:, self._gap_column[pr.name]] = (
                    np.linalg.norm(p[:, i] - p[:, j], axis=1) - reach
                )
        return out

    def clearance(self, q: ArrayLike, cull_above: float | None = None) -> FloatArray:
        """Smallest distance between the bodies of any checked pair, per posture (N,) [m].

        FCL's distance (GJK); 0 where a pair touches or intersects.

        Args:
            q: joint angles (N, 4) or (4,) [rad].
            cull_above: skip the pairs whose bounding spheres, turn floor
                (:meth:`turn_floors`) or capsules' segments
                (:mod:`mmstab.model.collision_distance`) keep them at least this far [m]
                apart (None: every pair): the answer is then exact where it is below
                ``cull_above`` and a lower bound, at least ``cull_above``, elsewhere.
        """
        qa = np.atleast_2d(np.asarray(q, dtype=float))
        R, p = self.shape_poses(qa)
        out = np.full(len(qa), np.inf)
        request = fcl.DistanceRequest()
        floors = {} if cull_above is None else self.turn_floors()
        for pair in self.pairs:
            a = self._link_objs[pair.link]
            j = -1 if isinstance(pair.other, str) else pair.other
            b = self._base_objs[pair.other] if isinstance(pair.other, str) else self._link_objs[j]
            rows = np.arange(len(qa))
            if cull_above is not None:
                gap = self._gap(pair, p)
                floor = floors.get(pair.name, -np.inf)
                if floor >= cull_above:  # at every angle
                    gap = np.maximum(gap, floor)
                far = gap >= cull_above
                out[far] = np.minimum(out[far], gap[far])
                rows = np.flatnonzero(~far)
                near = self._segment_gap(pair, R, p, rows, cull_above) if rows.size else None
                if near is not None:
                    far_too = near >= cull_above
                    out[rows[far_too]] = np.minimum(out[rows[far_too]], near[far_too])
                    rows = rows[~far_too]
            for n in rows:
                a.setTransform(fcl.Transform(R[n, pair.link], p[n, pair.link]))
                if j >= 0:
                    b.setTransform(fcl.Transform(R[n, j], p[n, j]))
                d = fcl.distance(a, b, request, fcl.DistanceResult())
                out[n] = min(out[n], max(float(d), 0.0))
        return out

    def keeps_clearance(self, q: ArrayLike, need: float, step: float) -> bool:
        """Whether every posture of a sequence keeps ``need`` [m] between every checked pair.

        Exact at each posture, with fewer FCL calls than :meth:`clearance`: consecutive
        postures of ``q`` (N, 4) [rad] must move no point of the arm more than ``step`` [m],
        so a pair measured ``d`` apart cannot come within ``need`` for the next
        ``(d − need) / step`` postures (half that for a pair of two moving links), which are
        skipped; pairs whose bounding spheres stay ``need`` apart are not measured, nor the
        pairs one joint alone moves that keep ``need`` at every angle (:meth:`turn_floors`);
        the first posture found closer ends the check.
        """
        qa = np.atleast_2d(np.asarray(q, dtype=float))
        R, p = self.shape_poses(qa)
        request = fcl.DistanceRequest()
        skip, order = self._skipped(need)
        if collision_distance.available():  # every pair's bounds at once, in C
            near = collision_distance.pairs_near(self._table, R, p, need, skip, CULL_SLACK)
        else:
            gaps = self._gaps(p)
            near = np.stack([gaps[:, self._gap_column[pr.name]] < need for pr in self.pairs], 1)
        some: NDArray[np.bool_] = np.asarray(near.any(axis=0))  # some posture near (unbounded)
        for index in order:
            pair = self.pairs[index]
            if skip[index] or not some[index]:  # that far apart at every angle, or bounded
                continue
            a = self._link_objs[pair.link]
            j = -1 if isinstance(pair.other, str) else pair.other
            b = self._base_objs[pair.other] if isinstance(pair.other, str) else self._link_objs[j]
            rate = step * (2.0 if j >= 0 else 1.0)  # how fast the pair's distance can shrink
            safe_until = 0
            for n in np.flatnonzero(near[:, index]):
                if n < safe_until:
                    continue
                a.setTransform(fcl.Transform(R[n, pair.link], p[n, pair.link]))
                if j >= 0:
                    b.setTransform(fcl.Transform(R[n, j], p[n, j]))
                d = float(fcl.distance(a, b, request, fcl.DistanceResult()))
                if d < need:
                    return False
                safe_until = int(n) + 1 + int((d - need) / rate)
        return True

    def _skipped(self, need: float) -> tuple[NDArray[np.int64], list[int]]:
        """Pairs left out at ``need`` [m] (1: kept at every turn angle), the order (arm first).

        Kept per ``need`` (the moves' checks ask one or two).
        """
        kept = self.__dict__.setdefault("_skip_by_need", {})
        if need not in kept:
            floors, pairs = self.turn_floors(), self.pairs
            skip = np.array([floors.get(pr.name, -np.inf) >= need for pr in pairs], np.int64)
            kept[need] = (
                skip,
                sorted(range(len(pairs)), key=lambda i: isinstance(pairs[i].other, str)),
            )
        return kept[need]

    def colliding_pairs(self, q: ArrayLike) -> list[str]:
        """Names of all pairs that intersect at one posture (FCL on every pair).

        Args:
            q: joint angles (4,) [rad].
        """
        qa = np.asarray(q, dtype=float).reshape(1, len(self.robot.links))
        R, p = self.shape_poses(qa)
        rows = np.zeros(1, dtype=np.intp)
        return [pair.name for pair in self.pairs if self._fcl(pair, R, p, rows)[0]]
