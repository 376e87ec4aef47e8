"""The ground a problem file's ``terrain:`` section describes (``docs/terrain.md``).

Three forms, told apart by their key:

* ``{slope: A}``: the planar ramp (:class:`~mmstab.terrain.ramp.Ramp`), A [rad];
* ``{file: PATH, resolution: R}``: a heightmap file (``.npz``, GeoTIFF, STL/PLY/OBJ mesh),
  PATH relative to the problem file, R [m/cell] only to rasterise a mesh;
* ``{file: REC, topic: T, time: S}``: one elevation map of a robot recording (``.mcap``,
  ROS 1 ``.bag``, ROS 2 bag directory; :mod:`mmstab.terrain.recording`);
* ``{generate: {kind: K, seed: S, size: [X, Y], resolution: R, ...}}``: a seeded generator
  (:mod:`mmstab.terrain.generators`; each kind's keys in ``schema_terrain.TERRAIN_KINDS``).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from mmstab.core import schema, schema_terrain
from mmstab.core.files import ConfigError, check_known_keys, validate
from mmstab.model.robot import Robot
from mmstab.terrain.base import DEFAULT_FRICTION, Terrain
from mmstab.terrain.generators import Grid, generate
from mmstab.terrain.heightmap import Heightmap
from mmstab.terrain.heightmap_terrain import HeightmapTerrain
from mmstab.terrain.io import MESH_SUFFIXES, load_heightmap
from mmstab.terrain.ramp import Ramp
from mmstab.terrain.recording import DEFAULT_TOPIC, is_recording, load_grid_map

#: Every top-level key of a ``terrain:`` section, whichever its form.
TERRAIN_KEYS = tuple(
    dict.fromkeys(
        [
            "generate",
            *schema_terrain.TERRAIN_FILE["properties"],
            *schema_terrain.TERRAIN_RAMP["properties"],
        ]
    )
)


def check_section(problem_path: Path, section: Any) -> str:
    """Validate a ``terrain:`` section; return its form (``ramp``, ``file`` or ``generate``).

    Raises:
        ConfigError: naming the problem file and the ``terrain.*`` field at fault.
    """
    if not isinstance(section, dict):
        raise ConfigError(problem_path, "terrain", "must be a mapping")
    # a misspelt ``generate`` or ``file`` would be read as a ramp's: name the key
    check_known_keys(problem_path, "terrain", section, TERRAIN_KEYS)
    if "generate" in section:
        gen = section["generate"]
        top = schema.with_optional(
            schema.obj(generate={}),
            compliance=schema_terrain.COMPLIANCE,
            friction=schema_terrain.FRICTION,
        )
        validate(problem_path, {"terrain": section}, schema.obj(terrain=top))
        if not isinstance(gen, dict):
            raise ConfigError(problem_path, "terrain.generate", "must be a mapping")
        kind = gen.get("kind")
        # (a list or mapping given as the kind cannot be looked up: refused as unknown)
        if not isinstance(kind, str) or kind not in schema_terrain.TERRAIN_KINDS:
            kinds = ", ".join(schema_terrain.TERRAIN_KINDS)
            raise ConfigError(problem_path, "terrain.generate.kind", f"must be one of {kinds}")
        sub = schema_terrain.terrain_generate_schema(kind)
        validate(problem_path, {"terrain": {"generate": gen}}, _wrap(_wrap(sub, "generate")))
        if gen["resolution"] > min(gen["size"]):  # 1e300: a map of one cell
            msg = f"{gen['resolution']} m is coarser than the map's size {gen['size']} m"
            raise ConfigError(problem_path, "terrain.generate.resolution", msg)
        return "generate"
    if "file" in section:
        validate(problem_path, {"terrain": section}, _wrap(schema_terrain.TERRAIN_FILE))
        return "file"
    validate(problem_path, {"terrain": section}, _wrap(schema_terrain.TERRAIN_RAMP))
    return "ramp"


def _wrap(sub: dict[str, Any], key: str = "terrain") -> dict[str, Any]:
    return schema.obj(**{key: sub})


def from_section(
    problem_path: str | os.PathLike[str], section: Any, robot: Robot | None = None
) -> Ramp | HeightmapTerrain:
    """Build the terrain of a problem file's ``terrain:`` section.

    Args:
        problem_path: the problem file (file paths are relative to its folder).
        section: the ``terrain:`` mapping.
        robot: bind a heightmap terrain to this robot (its YAML flipper angle, arm stowed).

    Raises:
        ConfigError: a bad section or a bad heightmap file (naming that file and field).
    """
    p = Path(problem_path)
    form = check_section(p, section)
    friction = float(section.get("friction", DEFAULT_FRICTION))
    if form == "ramp":
        return Ramp(section["slope"], friction)
    if form == "file":
        hm = _file_heightmap(p, section)
    else:
        hm = generate(section["generate"])
    terrain = HeightmapTerrain(hm, friction=friction)
    if "compliance" in section:
        settings = terrain.settings._replace(compliance=float(section["compliance"]))
        terrain = HeightmapTerrain(hm, settings=settings, friction=friction)
    return terrain if robot is None else terrain.with_robot(robot)


def planar_terrain(slope: float, friction: float = DEFAULT_FRICTION) -> Terrain:
    """A planar ramp as a :class:`Terrain`, without a problem file's range checks.

    For checks beyond what a problem may ask (the MuJoCo verdict grid goes to friction 4 and
    slopes near 80 deg); a problem's terrain comes from :func:`from_section`.

    Args:
        slope: the plane's slope about G's x axis [rad].
        friction: Coulomb coefficient of tracks on ground [-].
    """
    return Ramp(float(slope), float(friction))


def _file_heightmap(problem_path: Path, section: dict[str, Any]) -> Heightmap:
    """The heightmap of ``terrain: {file, ...}``: a heightmap file or a recording's map."""
    target = problem_path.parent / section["file"]
    if is_recording(target):
        if not target.exists():
            raise ConfigError(problem_path, "terrain.file", f"no recording at {target}")
        return load_grid_map(
            target, section.get("topic", DEFAULT_TOPIC), section.get("time")
        ).heightmap
    for key in ("topic", "time"):
        if key in section:
            raise ConfigError(problem_path, f"terrain.{key}", "only for a recording (.mcap, .bag)")
    if not target.is_file():
        raise ConfigError(problem_path, "terrain.file", f"no heightmap file at {target}")
    if target.suffix.lower() in MESH_SUFFIXES and section.get("resolution") is None:
        raise ConfigError(  # the key to add is the problem's, not the mesh's
            problem_path, "terrain.resolution",
            f"a mesh ({section['file']}) needs the cell size [m/cell] to rasterise it at",
        )  # fmt: skip
    return load_heightmap(target, section.get("resolution"))


def ramp_heightmap(ramp: Ramp, size: tuple[float, float], resolution: float) -> Heightmap:
    """The ramp sampled as a heightmap centred on G's origin: z = y tan(slope).

    Args:
        ramp: the ramp.
        size: (x, y) extent [m].
        resolution: cell size [m/cell].
    """
    grid = Grid.of_size(size, resolution)
    _, y = grid.xy()
    return grid.heightmap(np.tan(ramp.slope) * y, f"ramp({ramp.slope:g} rad)")


def as_heightmap(terrain: Terrain, size: tuple[float, float], resolution: float) -> Heightmap:
    """Any terrain as a heightmap (a ramp is sampled over ``size`` at ``resolution``)."""
    if isinstance(terrain, Ramp):
        return ramp_heightmap(terrain, size, resolution)
    if isinstance(terrain, HeightmapTerrain):
        return terrain.heightmap
    raise TypeError(f"no heightmap form of {type(terrain).__name__}")
