"""The ground under the tracked base: one interface (:class:`Terrain`), several grounds.

Every stage above this package asks a :class:`Terrain` for the body pose, gravity in the
body and the support contacts of a base pose; none of them knows which ground it is.
The planar ramp (:mod:`mmstab.terrain.ramp`) is the first implementation; heightmaps
(:mod:`mmstab.terrain.heightmap_terrain`) the second. :func:`from_section` builds the
ground of a problem file's ``terrain:`` section.
"""

from mmstab.terrain.base import GRAVITY_G, Support, Terrain
from mmstab.terrain.factory import from_section
from mmstab.terrain.heightmap import Heightmap, OffMapError
from mmstab.terrain.heightmap_terrain import HeightmapTerrain
from mmstab.terrain.ramp import (
    BasePose,
    CirclePath,
    GlobalCoM,
    Ramp,
    global_com_functions,
    rot_x,
    rot_z,
    wrap_angle,
)

__all__ = [
    "GRAVITY_G",
    "BasePose",
    "CirclePath",
    "GlobalCoM",
    "Heightmap",
    "HeightmapTerrain",
    "OffMapError",
    "Ramp",
    "Support",
    "Terrain",
    "from_section",
    "global_com_functions",
    "rot_x",
    "rot_z",
    "wrap_angle",
]
