"""Contact candidates of the tracked base, in the body frame B (``docs/terrain.md``).

B has its origin at the centre of the track-ground contact rectangle, x forward, y left,
z up. The candidates are the points of the base that can touch the ground:

* **tracks**: each track is a stadium in the x-z plane, ``tracks.width`` wide, centred at
  y = +-separation/2: a flat bottom from x = -L/2 to +L/2 at z = 0 (L = ``tracks.length``)
  and end arcs (sprocket, idler) of radius r_t = ``tracks.height``/2 centred at
  (+-L/2, r_t). Points along the bottom and along the lower half of each end arc (from
  straight down to straight ahead/behind), on rows across the belt at most ``spacing``
  apart, both track edges (y = centre +- width/2) included.
* **flippers**: the box of :meth:`mmstab.model.robot.Flippers.box` at the flipper angle; points
  along its two lower long edges (the rear pair's at its own angle).
* **chassis**: the bottom face of ``base.body`` (z = centre_z - size_z/2): its corners,
  points along its edges and a grid inside it, all at most ``spacing`` apart.

Every sample of a belt or the underside is at most ``spacing`` from the next one along x
and y, so the ground can reach into either between samples only by what it rises over
half a spacing (``docs/terrain.md``: a bound measured on rough ground).
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from mmstab.core.files import MmstabError
from mmstab.model.robot import Base, Flippers, rpy_matrix

FloatArray = NDArray[np.float64]

TRACK, FLIPPER, CHASSIS = 0, 1, 2
PART_NAMES = ("track", "flipper", "chassis")

#: Default spacing of the candidates along straight edges [m].
SPACING = 0.05
#: Default angular step along the track end arcs [rad]: the chords sag r_t (1 - cos(step/2))
#: = 0.24 mm below the arc for r_t = 0.11 m.
ARC_STEP = np.radians(7.5)


class ContactCandidates(NamedTuple):
    """Points of the base that may touch the ground.

    Attributes:
        points: (K, 3) in the body frame B [m].
        part: (K,) part code per point: ``TRACK``, ``FLIPPER`` or ``CHASSIS``.
    """

    points: FloatArray
    part: NDArray[np.int_]

    @property
    def compliant(self) -> NDArray[np.bool_]:
        """(K,) the candidates on the tracks' flat bottom runs (z = 0 in B).

        The tracks' suspension lets that part yield, so it carries load a little above the
        ground too (:attr:`mmstab.terrain.rest.RestSettings.compliance`).
        """
        return (self.part == TRACK) & (np.abs(self.points[:, 2]) < 1e-12)


def _segment(a: FloatArray, b: FloatArray, spacing: float) -> FloatArray:
    """Points from ``a`` to ``b`` (both included), at most ``spacing`` [m] apart."""
    n = max(int(np.ceil(np.linalg.norm(b - a) / spacing - 1e-9)), 1) + 1
    s = np.linspace(0.0, 1.0, n)[:, None]
    return a + s * (b - a)


def track_profile(length: float, height: float, spacing: float, arc_step: float) -> FloatArray:
    """The (x, z) profile of one track bottom: flat part then both lower quarter arcs.

    Args:
        length: flat ground-contact length L [m].
        height: track height 2 r_t [m].
        spacing: point spacing along the flat bottom [m].
        arc_step: angular step along the arcs [rad].

    Returns:
        (n, 2) points (x, z) [m].
    """
    r = height / 2
    flat = _segment(np.array([-length / 2, 0.0]), np.array([length / 2, 0.0]), spacing)
    n_arc = max(int(np.ceil(np.pi / 2 / arc_step - 1e-9)), 1)
    phi = np.linspace(0.0, np.pi / 2, n_arc + 1)[1:]  # phi = 0 is the bottom end, already in
    front = np.stack([length / 2 + r * np.sin(phi), r - r * np.cos(phi)], axis=1)
    rear = front * np.array([-1.0, 1.0])
    return np.concatenate([flat, front, rear])


def flipper_edges(flippers: Flippers, side: str, spacing: float) -> FloatArray:
    """Points along the two lower long edges of one flipper box, body frame (n, 3) [m]."""
    box = flippers.box(side)  # type: ignore[arg-type]
    R = rpy_matrix(box.rpy)
    half = box.size / 2
    edges = []
    for sy in (-1.0, 1.0):
        for sz in (-1.0, 1.0):
            a = box.center + R @ (half * np.array([-1.0, sy, sz]))
            b = box.center + R @ (half * np.array([1.0, sy, sz]))
            edges.append((a, b))
    edges.sort(key=lambda ab: float(ab[0][2] + ab[1][2]))  # the two lowest long edges
    return np.concatenate([_segment(a, b, spacing) for a, b in edges[:2]])


def chassis_outline(base: Base, spacing: float) -> FloatArray:
    """Corners and edge points of the chassis bottom face, body frame (n, 3) [m]."""
    body = base.body
    z = body.center[2] - body.size[2] / 2
    hx, hy = body.size[0] / 2, body.size[1] / 2
    cx, cy = body.center[0], body.center[1]
    corners = np.array(
        [[cx - hx, cy - hy, z], [cx + hx, cy - hy, z], [cx + hx, cy + hy, z], [cx - hx, cy + hy, z]]
    )
    pts = [_segment(corners[i], corners[(i + 1) % 4], spacing)[:-1] for i in range(4)]
    return np.concatenate(pts)


def chassis_inside(base: Base, spacing: float) -> FloatArray:
    """Grid points strictly inside the chassis bottom face, at most ``spacing`` apart (n, 3)."""
    body = base.body
    z = body.center[2] - body.size[2] / 2
    xs = _across(body.center[0], body.size[0], spacing)[1:-1]
    ys = _across(body.center[1], body.size[1], spacing)[1:-1]
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    return np.stack([X.ravel(), Y.ravel(), np.full(X.size, z)], axis=1)


def _across(centre: float, width: float, spacing: float) -> FloatArray:
    """Values from centre - width/2 to centre + width/2 (both included), <= spacing apart."""
    n = max(int(np.ceil(width / spacing - 1e-9)), 1) + 1
    return np.linspace(centre - width / 2, centre + width / 2, n)


def contact_candidates(
    base: Base,
    flipper_angle: float | None = None,
    spacing: float = SPACING,
    arc_step: float = ARC_STEP,
) -> ContactCandidates:
    """All contact candidates of the base in B.

    Args:
        base: the tracked base.
        flipper_angle: flipper angle [rad] (0 = straight forward, positive raises the tip);
            ``None`` = the robot description's.
        spacing: candidate spacing along straight edges [m].
        arc_step: angular step along the track end arcs [rad].
    """
    flippers = base.flippers
    if flipper_angle is not None:
        if flippers is None:
            raise MmstabError(f"flipper angle {flipper_angle} rad: the base has no flippers")
        flippers = dataclasses.replace(flippers, angle=float(flipper_angle))
    t = base.tracks
    prof = track_profile(t.length, t.height, spacing, arc_step)
    parts: list[FloatArray] = []
    codes: list[int] = []
    for yc in (t.separation / 2, -t.separation / 2):
        for y in _across(yc, t.width, spacing)[::-1]:  # the left edge first, as before
            parts.append(np.stack([prof[:, 0], np.full(len(prof), y), prof[:, 1]], axis=1))
            codes += [TRACK] * len(prof)
    # the front pair at the angle asked, then the rear pair
    for pair in dataclasses.replace(base, flippers=flippers).flipper_pairs().values():
        for side in ("left", "right"):
            pts = flipper_edges(pair, side, spacing)
            parts.append(pts)
            codes += [FLIPPER] * len(pts)
    chassis = np.concatenate([chassis_outline(base, spacing), chassis_inside(base, spacing)])
    parts.append(chassis)
    codes += [CHASSIS] * len(chassis)
    return ContactCandidates(points=np.concatenate(parts), part=np.array(codes, dtype=np.int_))
