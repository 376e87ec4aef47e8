"""The atlas's axes read from its section: values, robot variants, payloads, terrain cells.

Each reader checks its axis beyond the schema and raises :class:`ConfigError` naming the
problem file and the field; :func:`experiments.atlas.spec.atlas_spec` puts them
together. Units: slopes, headings and flipper angles [rad], payloads [kg], their CoM [m].
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from mmstab.core.files import ConfigError, MmstabError
from mmstab.core.problem import Problem
from mmstab.model.payload import Payload, attach_payload, check_payload
from mmstab.model.robot import (
    FLIPPER_CONTACT_TOL,
    FloatArray,
    Robot,
    load_robot,
    with_flipper_angle,
)
from mmstab.model.robot import flipper_ground_angle as _ground_angle

#: Slopes the ramp accepts [rad] (as ``terrain.slope`` in the problem schema).
MAX_SLOPE = 1.2
#: Generator kinds the terrain axis sweeps (they have a ``slope`` and an uphill ``azimuth``).
TERRAIN_KINDS = ("plane", "rough")


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


def increasing(path: Path, field: str, values: FloatArray) -> None:
    """Refuse an axis whose ``values`` are not strictly increasing."""
    if np.any(np.diff(values) <= 0):
        raise ConfigError(path, field, "values must be strictly increasing")


def flipper_ground_angle(robot: Robot) -> float:
    """:func:`mmstab.model.robot.flipper_ground_angle`, refused as an ``MmstabError`` [rad]."""
    try:
        return _ground_angle(robot)
    except ValueError as e:
        raise MmstabError(str(e)) from None


def robot_axis(problem: Problem, axes: dict[str, Any]) -> list[tuple[str, Robot]]:
    """The robot axis: (label, robot) per listed robot file (default the problem's robot)."""
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


def variant_axis(
    problem: Problem,
    robots: list[tuple[str, Robot]],
    entries: list[Any],
    payloads: FloatArray,
    payload_com: FloatArray,
) -> tuple[tuple[Variant, ...], tuple[str, ...]]:
    """Every robot x flipper angle x payload variant (robot slowest), and the flipper labels."""
    labels = []
    for e in entries:
        label = e if isinstance(e, str) else f"{float(e):g}"
        if label in labels:
            raise ConfigError(problem.path, "atlas.axes.flipper_angle", f"{label} is listed twice")
        labels.append(label)
    variants = []
    for (ri, (rlabel, robot)), (fi, e) in itertools.product(enumerate(robots), enumerate(entries)):
        field = f"atlas.axes.flipper_angle[{fi}]"
        if robot.base.flippers is None:  # a base without flippers: only its own angle
            if e != "robot":
                raise ConfigError(problem.path, field, f"robot {rlabel} has no flippers")
            variants += [
                Variant((ri, fi, pi), rlabel, labels[fi], math.nan, float(mass),
                        attach_payload(robot, Payload(float(mass), payload_com)))
                for pi, mass in enumerate(payloads)
            ]  # fmt: skip
            continue
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
        flippers = variant.base.flippers
        assert flippers is not None  # the robot's have been set
        low = flippers.lowest()
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


def payload_axis(path: Path, sec: dict[str, Any]) -> tuple[FloatArray, FloatArray]:
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
    increasing(path, "atlas.axes.payload", masses)
    for m in masses:
        check_payload(path, "atlas.axes.payload", float(m), com)
    return masses, com


def terrain_axis(problem: Problem, axes: dict[str, Any]) -> tuple[TerrainCell, ...]:
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


def slope_axis(
    problem: Problem, axes: dict[str, Any], terrains: tuple[TerrainCell, ...]
) -> FloatArray:
    """The slope axis [rad]: the ramp's slope, or the generator's ``slope`` parameter."""
    path = problem.path
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
    increasing(path, "atlas.axes.slope", slopes)
    if slopes.min() < 0 or slopes.max() > MAX_SLOPE:
        raise ConfigError(path, "atlas.axes.slope", f"slopes must lie in [0, {MAX_SLOPE}] rad")
    return slopes


def heading_axis(path: Path, axes: dict[str, Any]) -> FloatArray:
    """The heading axis [rad]: increasing, spanning less than one turn (default ``[0]``)."""
    headings = (
        axis_values(path, "atlas.axes.heading", axes["heading"], periodic=True)
        if "heading" in axes
        else np.zeros(1)
    )
    increasing(path, "atlas.axes.heading", headings)
    if headings[-1] - headings[0] >= 2 * math.pi - 1e-9:
        raise ConfigError(path, "atlas.axes.heading", "headings must span less than one turn")
    return headings
