"""The ground under the tracked base: one interface (:class:`Terrain`), several grounds.

Every stage above this package asks a :class:`Terrain` for the body pose, gravity in the
body and the support contacts of a base pose; none of them knows which ground it is.
The planar ramp (:mod:`mmstab.terrain.ramp`) is the first implementation.
"""

from mmstab.terrain.base import GRAVITY_G, Support, Terrain
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
    "Ramp",
    "Support",
    "Terrain",
    "global_com_functions",
    "rot_x",
    "rot_z",
    "wrap_angle",
]
