"""The arm-CoM workspace V (paper Section II-B, Fig. 3; ``docs/design.md``, "Workspace").

Brute force over a grid of the four joint angles: forward kinematics and self-collision
(:mod:`mmstab.model.collision`) label every posture's arm CoM (body frame B) valid or invalid,
then ``V = hull(all CoMs) minus hull(invalid CoMs)``, tested with the hulls' half-spaces.

Membership follows ``docs/design.md`` ("Workspace"): ``A_all p <= b_all and not
(A_bad p <= b_bad)``, both with a slack of ``HULL_TOL``, so the boundary of hull(invalid)
is not in V. Building is ``build_workspace`` (no files, :mod:`.build`);
``load_or_build_workspace`` adds the cache as ``<key>.npz`` in mmstab's cache folder
(``$MMSTAB_CACHE``, else ``~/.cache/mmstab``)
(:mod:`.cache`), keyed by the robot description, the grid and ``WORKSPACE_VERSION``.
Modules: :mod:`.grid`, :mod:`.hulls`, :mod:`.region`, :mod:`.build`, :mod:`.cache`.
"""

from mmstab.workspace.build import (
    DEFAULT_CHUNK,
    PARALLEL_MIN_POSTURES,
    PARALLEL_WORKERS,
    arm_com_from_frames,
    build_workspace,
    label_chunk,
)
from mmstab.workspace.cache import (
    WORKSPACE_VERSION,
    default_cache_dir,
    load_or_build_workspace,
    load_workspace,
    robot_cache_path,
    robot_workspace,
    save_workspace,
    workspace_cache_path,
    workspace_key,
)
from mmstab.workspace.grid import FULL_TURN_TOL, JointGrid, grid_postures, joint_grid
from mmstab.workspace.hulls import (
    FLAT_TOL,
    HULL_BLOCK,
    HULL_TOL,
    HalfSpaces,
    convex_hull,
    halfspaces,
    hull_candidates,
    hull_diameter,
)
from mmstab.workspace.region import Workspace, workspace_from_clouds
from mmstab.workspace.settings import WorkspaceSettings

__all__ = [
    "DEFAULT_CHUNK",
    "FLAT_TOL",
    "FULL_TURN_TOL",
    "HULL_BLOCK",
    "HULL_TOL",
    "PARALLEL_MIN_POSTURES",
    "PARALLEL_WORKERS",
    "WORKSPACE_VERSION",
    "HalfSpaces",
    "JointGrid",
    "Workspace",
    "WorkspaceSettings",
    "arm_com_from_frames",
    "build_workspace",
    "convex_hull",
    "grid_postures",
    "halfspaces",
    "hull_candidates",
    "hull_diameter",
    "joint_grid",
    "label_chunk",
    "load_or_build_workspace",
    "load_workspace",
    "robot_cache_path",
    "robot_workspace",
    "save_workspace",
    "default_cache_dir",
    "workspace_cache_path",
    "workspace_from_clouds",
    "workspace_key",
]
