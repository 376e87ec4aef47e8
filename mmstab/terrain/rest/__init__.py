"""The resting pose of the tracked base on a heightmap: its solver, C kernel and NumPy twin.

- :mod:`~mmstab.terrain.rest.poses`: :func:`rest_poses`, the batched driver (the method);
- :mod:`~mmstab.terrain.rest.types`: its settings (:class:`RestSettings`) and results
  (:class:`RestPoses`);
- :mod:`~mmstab.terrain.rest.kernel` (``kernel.c``): the C kernel, called through ctypes
  (the default backend);
- :mod:`~mmstab.terrain.rest.numpy_path` on :mod:`~mmstab.terrain.rest.geometry`: the
  NumPy path, the kernel's independent twin;
- :mod:`~mmstab.terrain.rest.polish`: the poses the rounds did not settle, taken to the
  minimum of the CoM's height;
- :mod:`~mmstab.terrain.rest.result`: attitudes into :class:`RestPoses`, off-map errors.
"""

from __future__ import annotations

from mmstab.terrain.rest.geometry import BLOCK, coarse_subset, rotations
from mmstab.terrain.rest.numpy_path import CHUNK
from mmstab.terrain.rest.poses import rest_poses
from mmstab.terrain.rest.types import BoolArray, RestPoses, RestSettings

__all__ = [
    "BLOCK",
    "CHUNK",
    "BoolArray",
    "RestPoses",
    "RestSettings",
    "coarse_subset",
    "rest_poses",
    "rotations",
]
