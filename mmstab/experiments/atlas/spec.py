"""The ``atlas:`` section of a problem, checked once: axes, robot variants, chunks.

The atlas is a grid of independent cells over ``robot x flipper x payload x terrain x
slope x heading``. Axes the section leaves out have one value: the problem's robot, the
robot file's flipper angle, no payload, the problem's terrain, its slope and heading 0.

On the ramp (``terrain: {slope}``) a cell is one base pose on a planar ramp (position
does not matter on a plane); headings are about the slope normal in the slope frame S: 0 =
body x across the slope (+x_S), pi/2 = facing uphill (+y_S). On a generated heightmap
(``terrain: {generate: {kind: plane|rough, ...}}``) the terrain axis holds generator
seeds (``terrain_seeds``; default the section's seed) and the slope axis the generator's
``slope``: a cell is the robot at rest at the map's centre, its heading measured from
across the generator's uphill azimuth the same way (``docs/atlas.md``).

A payload [kg] is a point mass at the wrist (``payload_com`` in the wrist frame [m],
default its origin) folded into the last arm link (:mod:`mmstab.model.payload`): a robot variant
of its own, with its own workspace V. Slopes [rad], headings [rad], flipper angles [rad]
(0 = straight forward, positive raises the tip; ``"ground"``: lowered until the flipper
tips rest on the ground, so they join the support polygon; ``"robot"``: the file's angle).
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from mmstab.core.files import ConfigError, MmstabError
from mmstab.core.problem import Problem
from mmstab.model.payload import Payload, attach_payload, check_payload
from mmstab.model.robot import FLIPPER_CONTACT_TOL, Robot, load_robot, with_flipper_angle
from mmstab.model.robot import FloatArray as FloatArray
from mmstab.model.robot import flipper_ground_angle as _ground_angle
from mmstab.planner import PlannerSettings
from mmstab.terrain.base import DEFAULT_FRICTION

#: Largest atlas one section may ask for (cells).
MAX_CELLS = 1_000_000
#: Slopes the ramp accepts [rad] (as ``terrain.slope`` in the problem schema).
MAX_SLOPE = 1.2
#: Generator kinds the terrain axis sweeps (they have a ``slope`` and an uphill ``azimuth``).
TERRAIN_KINDS = ("plane", "rough")
#: Bump when what a cell computes changes: stores of another version are not resumed.
ATLAS_VERSION = 2


class Variant(NamedTuple):
    """One robot at one flipper angle with one payload: the unit that owns a workspace V.

    Attributes:
        position: (robot index, flipper index, payload index) in the atlas.
        robot_label: the robot coordinate (its name).
        flipper_label: the flipper coordinate (``"robot"``, ``"ground"`` or the angle).
        flipper_angle: the angle [rad].
        payload_kg: the payload mass at the wrist [kg] (0: none).
        robot: the robot with that flipper angle and payload (``source_hash`` changed if
            either is).
    """

    position: tuple[int, int, int]
    robot_label: str
    flipper_label: str
    flipper_angle: float
    payload_kg: float
    robot: Robot


class TerrainCell(NamedTuple):
    """One value of the terrain axis.

    Attributes:
        label: the coordinate (``"ramp"`` or ``"KIND seed N"``).
        generate: the ``terrain.generate`` mapping with this seed (``None``: the ramp);
            its ``slope`` is replaced by each cell's.
    """

    label: str
    generate: dict[str, Any] | None

    @property
    def seed(self) -> int:
        """The generator seed (-1 on the ramp)."""
        return -1 if self.generate is None else int(self.generate["seed"])


class Block(NamedTuple):
    """One stored chunk: a variant and a slope x heading rectangle of cells.

    Attributes:
        variant: (robot index, flipper index, payload index, terrain index).
        slope: slice of slope indices.
        heading: slice of heading indices.
        block: (slope block, heading block) index of the chunk.
    """

    variant: tuple[int, int, int, int]
    slope: slice
    heading: slice
    block: tuple[int, int]

    @property
    def cells(self) -> int:
        """Cells in the chunk."""
        return (self.slope.stop - self.slope.start) * (self.heading.stop - self.heading.start)


@dataclass(frozen=True)
class AtlasSpec:
    """A validated atlas.

    Attributes:
        path: the problem file (for error messages).
        variants: robot x flipper x payload variants, row-major (robot slowest).
        robot_labels: the robot coordinate values.
        flipper_labels: the flipper coordinate values.
        payloads: the payload axis [kg], increasing (``[0.0]`` without the axis).
        payload_com: the payload's CoM in the wrist frame (3,) [m].
        terrains: the terrain axis.
        slopes: slope axis [rad], increasing.
        headings: heading axis [rad], increasing, spanning less than a full turn.
        chunks: cells per chunk along (slope, heading).
        margin: the envelope's threshold on mu [N rad].
        settings: the problem's planner settings (its seed seeds every cell).
        workspace_grid: the problem's workspace grid (joint samples).
        planner_section: the problem's ``planner`` section as validated (for the key).
        friction: the terrain's friction coefficient [-] (the slip limit; not in the key:
            no cell's numbers depend on it).
    """

    path: Path
    variants: tuple[Variant, ...]
    robot_labels: tuple[str, ...]
    flipper_labels: tuple[str, ...]
    payloads: FloatArray
    payload_com: FloatArray
    terrains: tuple[TerrainCell, ...]
    slopes: FloatArray
    headings: FloatArray
    chunks: tuple[int, int]
    margin: float
    settings: PlannerSettings
    workspace_grid: tuple[int, ...]
    planner_section: dict[str, Any]
    friction: float = DEFAULT_FRICTION

    @property
    def shape(self) -> tuple[int, int, int, int, int, int]:
        """(robots, flippers, payloads, terrains, slopes, headings)."""
        return (
            len(self.robot_labels),
            len(self.flipper_labels),
            len(self.payloads),
            len(self.terrains),
            len(self.slopes),
            len(self.headings),
        )

    @property
    def terrain_labels(self) -> tuple[str, ...]:
        """The terrain coordinate values."""
        return tuple(t.label for t in self.terrains)

    @property
    def on_ramp(self) -> bool:
        """The cells stand on the planar ramp (no heightmap terrain)."""
        return self.terrains[0].generate is None

    @property
    def cells(self) -> int:
        """Number of cells."""
        return int(np.prod(self.shape))

    @property
    def block_shape(self) -> tuple[int, int]:
        """Number of chunks along (slope, heading)."""
        return (
            -(-len(self.slopes) // self.chunks[0]),
            -(-len(self.headings) // self.chunks[1]),
        )

    def variant(self, index: tuple[int, ...]) -> Variant:
        """The variant at (robot index, flipper index, payload index[, terrain index])."""
        ri, fi, pi = index[:3]
        return self.variants[(ri * len(self.flipper_labels) + fi) * len(self.payloads) + pi]

    def blocks(self) -> list[Block]:
        """Every chunk: variant by variant, terrain by terrain, slope then heading blocks."""
        out = []
        cs, ch = self.chunks
        nb_s, nb_h = self.block_shape
        for v in self.variants:
            for ti, bs, bh in itertools.product(
                range(len(self.terrains)), range(nb_s), range(nb_h)
            ):
                out.append(
                    Block(
                        variant=(*v.position, ti),
                        slope=slice(bs * cs, min((bs + 1) * cs, len(self.slopes))),
                        heading=slice(bh * ch, min((bh + 1) * ch, len(self.headings))),
                        block=(bs, bh),
                    )
                )
        return out

    def key(self) -> str:
        """Hash of everything a cell's numbers depend on (a store resumes only its own)."""
        data = {
            "version": ATLAS_VERSION,
            "variants": [
                (v.robot_label, v.flipper_label, v.flipper_angle, v.payload_kg, v.robot.source_hash)
                for v in self.variants
            ],
            "payload_com": self.payload_com.tolist(),
            "terrains": [(t.label, t.generate) for t in self.terrains],
            "slopes": self.slopes.tolist(),
            "headings": self.headings.tolist(),
            "chunks": list(self.chunks),
            "planner": self.planner_section,
            "workspace_grid": list(self.workspace_grid),
        }
        return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()[:20]


# ------------------------------------------------------------------------------------- axes
def axis_values(path: Path, field: str, node: Any, periodic: bool = False) -> FloatArray:
    """Values of an axis: a list, or ``{start, stop, num}`` evenly spaced with both ends.

    A periodic axis (heading) whose range spans exactly one turn omits its end, which is
    the same heading as its start.
    """
    if isinstance(node, list):
        return np.array(node, dtype=float)
    start, stop, num = float(node["start"]), float(node["stop"]), int(node["num"])
    if num == 1:
        return np.array([start])
    if stop <= start:
        raise ConfigError(path, f"{field}.stop", f"must be above start ({start})")
    full_turn = periodic and math.isclose(stop - start, 2 * math.pi, abs_tol=1e-9)
    return np.linspace(start, stop, num, endpoint=not full_turn)


def _increasing(path: Path, field: str, values: FloatArray) -> None:
    if np.any(np.diff(values) <= 0):
        raise ConfigError(path, field, "values must be strictly increasing")


def flipper_ground_angle(robot: Robot) -> float:
    """:func:`mmstab.model.robot.flipper_ground_angle`, refused as an ``MmstabError`` [rad]."""
    try:
        return _ground_angle(robot)
    except ValueError as e:
        raise MmstabError(str(e)) from None


def _robots(problem: Problem, axes: dict[str, Any]) -> list[tuple[str, Robot]]:
    if "robots" not in axes:
        return [(problem.robot.name, problem.robot)]
    out: list[tuple[str, Robot]] = []
    for i, rel in enumerate(axes["robots"]):
        p = (problem.path.parent / rel).resolve()
        if not p.is_file():
            raise ConfigError(problem.path, f"atlas.axes.robots[{i}]", f"no robot file at {p}")
        robot = load_robot(p)
        label = robot.name if robot.name not in [n for n, _ in out] else Path(rel).stem
        if label in [n for n, _ in out]:
            raise ConfigError(problem.path, f"atlas.axes.robots[{i}]", f"{rel} is listed twice")
        out.append((label, robot))
    return out


def _variants(
    problem: Problem,
    robots: list[tuple[str, Robot]],
    entries: list[Any],
    payloads: FloatArray,
    payload_com: FloatArray,
) -> tuple[tuple[Variant, ...], tuple[str, ...]]:
    labels = []
    for e in entries:
        label = e if isinstance(e, str) else f"{float(e):g}"
        if label in labels:
            raise ConfigError(problem.path, "atlas.axes.flipper_angle", f"{label} is listed twice")
        labels.append(label)
    variants = []
    for (ri, (rlabel, robot)), (fi, e) in itertools.product(enumerate(robots), enumerate(entries)):
        field = f"atlas.axes.flipper_angle[{fi}]"
        if e == "robot":
            angle = robot.base.flippers.angle
        elif e == "ground":
            try:
                angle = flipper_ground_angle(robot)
            except MmstabError as exc:
                raise ConfigError(problem.path, field, str(exc)) from None
        else:
            angle = float(e)
        variant = with_flipper_angle(robot, angle)
        low = float(variant.base.flippers.box("left").corners()[:, 2].min())
        if low < -FLIPPER_CONTACT_TOL:
            raise ConfigError(
                problem.path,
                field,
                f"{angle} rad puts the flippers of {rlabel} {-low:.3f} m below the ground "
                f"(use 'ground' for the angle at which they touch it)",
            )
        for pi, mass in enumerate(payloads):
            loaded = attach_payload(variant, Payload(float(mass), payload_com))
            variants.append(
                Variant((ri, fi, pi), rlabel, labels[fi], float(angle), float(mass), loaded)
            )
    return tuple(variants), tuple(labels)


def _payloads(path: Path, sec: dict[str, Any]) -> tuple[FloatArray, FloatArray]:
    """The payload axis [kg] and the payload's CoM in the wrist frame [m]."""
    axes = sec["axes"]
    masses = (
        axis_values(path, "atlas.axes.payload", axes["payload"])
        if "payload" in axes
        else np.zeros(1)
    )
    com = np.asarray(sec.get("payload_com", [0.0, 0.0, 0.0]), dtype=float)
    if com.shape != (3,) or not np.isfinite(com).all():
        raise ConfigError(path, "atlas.payload_com", "must be 3 finite numbers [m]")
    _increasing(path, "atlas.axes.payload", masses)
    for m in masses:
        check_payload(path, "atlas.axes.payload", float(m), com)
    return masses, com


def _terrains(problem: Problem, axes: dict[str, Any]) -> tuple[TerrainCell, ...]:
    """The terrain axis: the ramp, or the problem's generator at each seed."""
    path = problem.path
    section = problem.section("terrain")
    gen = section.get("generate")
    if gen is None:
        if "terrain_seeds" in axes:
            why = "seeds need a generated heightmap (terrain: {generate: {kind: rough, ...}})"
            raise ConfigError(path, "atlas.axes.terrain_seeds", why)
        if "slope" not in section:
            raise ConfigError(
                path, "atlas", "the terrain must be the ramp or a generated heightmap"
            )
        return (TerrainCell("ramp", None),)
    if gen["kind"] not in TERRAIN_KINDS:
        raise ConfigError(
            path,
            "terrain.generate.kind",
            f"the atlas sweeps a generator's slope and azimuth: {', '.join(TERRAIN_KINDS)}, "
            f"not {gen['kind']}",
        )
    seeds = [int(x) for x in axes.get("terrain_seeds", [gen["seed"]])]
    if len(set(seeds)) != len(seeds):
        raise ConfigError(path, "atlas.axes.terrain_seeds", "a seed is listed twice")
    return tuple(TerrainCell(f"{gen['kind']} seed {seed}", {**gen, "seed": seed}) for seed in seeds)


def atlas_spec(problem: Problem) -> AtlasSpec:
    """Check the problem's ``atlas`` section beyond its schema and build the atlas.

    Raises:
        ConfigError: naming the problem file and the field (missing section, a terrain
            the atlas cannot sweep, decreasing values, a negative payload, flippers below
            the ground, too many cells).
    """
    path = problem.path
    if "atlas" not in problem.data:
        raise ConfigError(path, "atlas", "missing section (see docs/atlas.md)")
    sec = problem.section("atlas")
    axes = sec["axes"]
    terrains = _terrains(problem, axes)
    # the slope axis: the ramp's slope, or the generator's ``slope`` parameter
    default_slope = (
        problem.section("terrain")["slope"]
        if terrains[0].generate is None
        else terrains[0].generate["slope"]
    )
    slopes = (
        axis_values(path, "atlas.axes.slope", axes["slope"])
        if "slope" in axes
        else np.array([float(default_slope)])
    )
    _increasing(path, "atlas.axes.slope", slopes)
    if slopes.min() < 0 or slopes.max() > MAX_SLOPE:
        raise ConfigError(path, "atlas.axes.slope", f"slopes must lie in [0, {MAX_SLOPE}] rad")
    headings = (
        axis_values(path, "atlas.axes.heading", axes["heading"], periodic=True)
        if "heading" in axes
        else np.zeros(1)
    )
    _increasing(path, "atlas.axes.heading", headings)
    if headings[-1] - headings[0] >= 2 * math.pi - 1e-9:
        raise ConfigError(path, "atlas.axes.heading", "headings must span less than one turn")
    payloads, payload_com = _payloads(path, sec)
    robots = _robots(problem, axes)
    variants, flipper_labels = _variants(
        problem, robots, axes.get("flipper_angle", ["robot"]), payloads, payload_com
    )
    spec = AtlasSpec(
        path=path,
        variants=variants,
        robot_labels=tuple(label for label, _ in robots),
        flipper_labels=flipper_labels,
        payloads=payloads,
        payload_com=payload_com,
        terrains=terrains,
        slopes=slopes,
        headings=headings,
        chunks=(int(sec["chunks"]["slope"]), int(sec["chunks"]["heading"])),
        margin=float(sec["margin"]),
        settings=PlannerSettings.from_section(problem.section("planner")),
        workspace_grid=tuple(int(n) for n in problem.section("workspace")["grid"]),
        planner_section=dict(problem.section("planner")),
        friction=float(problem.section("terrain").get("friction", DEFAULT_FRICTION)),
    )
    if spec.cells > MAX_CELLS:
        raise ConfigError(path, "atlas.axes", f"{spec.cells} cells; at most {MAX_CELLS}")
    return spec
