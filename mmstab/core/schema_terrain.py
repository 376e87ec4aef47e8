"""The ``terrain:`` section's schemas (``docs/terrain.md``): the ramp, files, generators.

Checked by :func:`mmstab.terrain.factory.check_section`, which tells the three forms apart.
"""

from __future__ import annotations

from typing import Any

from mmstab.core.schema import NONNEG, NUM, POS, SEED, obj, obj_optional, vec, with_optional

# --------------------------------------------------------------- terrain (heightmaps)
# The ``terrain:`` section takes one of three forms, told apart by their key and checked by
# ``mmstab.terrain.factory.from_section``: ``{slope}`` (the ramp), ``{file, resolution?}`` (a
# heightmap file, path relative to the problem file; ``resolution`` [m/cell] rasterises a
# mesh) or ``{generate: {kind, seed, size, resolution, ...}}`` (a seeded generator); both
# heightmap forms take an optional ``compliance`` [m] (:data:`COMPLIANCE`).
SLOPE: dict[str, Any] = {"type": "number", "minimum": 0, "maximum": 1.2, "unit": "rad"}
AZIMUTH: dict[str, Any] = {"type": "number", "unit": "rad"}
#: ``terrain.compliance`` [m] of a heightmap: the tracks' bottom runs bear load this far
#: above the ground (``mmstab.terrain.rest.RestSettings.compliance``); at most 0.2 m.
COMPLIANCE: dict[str, Any] = {"type": "number", "minimum": 0, "maximum": 0.2}
#: ``terrain.friction``: Coulomb coefficient of the tracks on the ground [-], any form
#: (default ``mmstab.terrain.base.DEFAULT_FRICTION``, 0.7); the slip limit is atan of it.
FRICTION: dict[str, Any] = {"type": "number", "exclusiveMinimum": 0, "maximum": 2}
TERRAIN_RAMP = with_optional(obj(slope=SLOPE), friction=FRICTION)
TERRAIN_FILE: dict[str, Any] = {
    "type": "object",
    "properties": {
        "file": {"type": "string", "minLength": 1},
        "resolution": POS,
        "compliance": COMPLIANCE,
        "friction": FRICTION,
        # a recording (.mcap, .bag, ROS 2 bag directory): its GridMap topic and the time [s]
        # from its start (the last map by then; default the first)
        "topic": {"type": "string", "minLength": 1},
        "time": NONNEG,
    },
    "required": ["file"],
    "additionalProperties": False,
}
#: Keys of each generator kind beyond kind, seed, size [m, m] and resolution [m/cell].
TERRAIN_KINDS: dict[str, dict[str, Any]] = {
    "plane": {"slope": SLOPE, "azimuth": AZIMUTH},
    "kerb": {"height": NUM, "distance": NUM, "azimuth": AZIMUTH},
    "ditch": {"depth": POS, "width": POS, "distance": NUM, "azimuth": AZIMUTH},
    "bumps": {"amplitude": NONNEG, "wavelength": POS},
    "rough": {
        "amplitude": NONNEG,
        # at most 1000 km: its square scales the spectrum (1e300 m overflowed)
        "correlation_length": {**POS, "maximum": 1e6},
        "hill_height": NUM,
        "hill_radius": POS,
        "slope": SLOPE,
        "azimuth": AZIMUTH,
    },
}


#: Optional features laid onto a generated map (any kind): a band ditch and a kerb across
#: it and egg-box bumps over it, as the ``ditch``, ``kerb`` and ``bumps`` kinds (their keys),
#: added to its elevation.
TERRAIN_FEATURES: dict[str, Any] = {
    "ditch": obj(**TERRAIN_KINDS["ditch"]),
    "kerb": obj(**TERRAIN_KINDS["kerb"]),
    "bumps": obj(**TERRAIN_KINDS["bumps"]),
}


def terrain_generate_schema(kind: str) -> dict[str, Any]:
    """Closed schema of ``terrain.generate`` for one generator kind (features optional)."""
    return with_optional(
        obj(
            kind={"const": kind},
            seed=SEED,
            size=vec(2, POS),
            resolution=POS,
            **TERRAIN_KINDS[kind],
        ),
        features=obj_optional(TERRAIN_FEATURES),
    )
