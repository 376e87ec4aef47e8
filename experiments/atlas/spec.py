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
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from experiments.atlas.axes import (
    MAX_SLOPE,
    TERRAIN_KINDS,
    TerrainCell,
    Variant,
    axis_values,
    flipper_ground_angle,
    heading_axis,
    payload_axis,
    robot_axis,
    slope_axis,
    terrain_axis,
    variant_axis,
)
from mmstab.core.files import ConfigError
from mmstab.core.problem import Problem
from mmstab.model.robot import FloatArray, with_flipper_angle
from mmstab.planner import PlannerSettings
from mmstab.terrain.base import DEFAULT_FRICTION

__all__ = [
    "ATLAS_VERSION",
    "MAX_CELLS",
    "MAX_SLOPE",
    "TERRAIN_KINDS",
    "AtlasSpec",
    "Block",
    "FloatArray",
    "TerrainCell",
    "Variant",
    "atlas_spec",
    "axis_values",
    "flipper_ground_angle",
    "with_flipper_angle",
]

#: Largest atlas one section may ask for (cells).
MAX_CELLS = 1_000_000
#: Bump when what a cell computes changes: stores of another version are not resumed.
ATLAS_VERSION = 2


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
    terrains = terrain_axis(problem, axes)
    slopes = slope_axis(problem, axes, terrains)
    headings = heading_axis(path, axes)
    payloads, payload_com = payload_axis(path, sec)
    robots = robot_axis(problem, axes)
    variants, flipper_labels = variant_axis(
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
