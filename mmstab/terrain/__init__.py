"""The ground under the tracked base: one interface (:class:`Terrain`), several grounds.

Every stage above this package asks a :class:`Terrain` for the body pose, gravity in the
body, the placement of body points and the support contacts of a base pose; none of them
knows which ground it is. The planar ramp (:mod:`mmstab.terrain.ramp`) is the first
implementation, heightmaps (:mod:`mmstab.terrain.heightmap_terrain`) the second;
:func:`from_section` builds the problem's terrain from its ``terrain:`` section.
"""

from __future__ import annotations

from mmstab.terrain.base import (
    GRAVITY_G,
    GROUND_SIZE,
    Placement,
    Support,
    Terrain,
    as_poses,
    local_transforms,
    place_local,
    place_local_sx,
    placement_function,
    roll_pitch,
    rot_x,
    rot_z,
    wrap_angle,
)
from mmstab.terrain.com import GlobalCoM, global_com_functions
from mmstab.terrain.factory import from_section
from mmstab.terrain.heightmap import Heightmap, OffMapError
from mmstab.terrain.heightmap_terrain import HeightmapTerrain
from mmstab.terrain.ramp import BasePose, Ramp

__all__ = [
    "GRAVITY_G",
    "GROUND_SIZE",
    "BasePose",
    "GlobalCoM",
    "Heightmap",
    "HeightmapTerrain",
    "OffMapError",
    "Placement",
    "Ramp",
    "Support",
    "Terrain",
    "as_poses",
    "from_section",
    "global_com_functions",
    "local_transforms",
    "place_local",
    "place_local_sx",
    "placement_function",
    "roll_pitch",
    "rot_x",
    "rot_z",
    "wrap_angle",
]
