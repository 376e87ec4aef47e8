"""Where a path high-centres the robot: its chassis on the ground, its tracks unloaded.

The resting pose on a heightmap (:mod:`mmstab.terrain.rest`) flags ``high_centred`` when a
chassis point is among the touching contacts: the body sits on a ridge, a ditch's edge or a
bump, and the tracks carry little or none of the weight, so they cannot drive it off (in
MuJoCo, ``dem.yaml``'s lap stops dead on its ditch's far edge with both tracks at full
speed). The planned poses are too sparse to see a ditch (0.5 m apart), so the path is rested
every ``spacing`` of arc length. A planar terrain never high-centres the robot.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mmstab.core.masks import true_runs

#: Arc length between the rested samples of a path [m] (the heightmaps' cells are 2-5 cm).
SPACING = 0.05


def high_centred_verdict(terrain: Any, poses: Any, s: Any) -> dict[str, Any]:
    """Stretches of a path where the rested robot's chassis touches the ground.

    Args:
        terrain: the ground (a heightmap terrain rests poses; any other never high-centres).
        poses: the path's poses (x [m], y [m], heading [rad]) (N, 3) in the terrain's map
            frame, in driving order, about :data:`SPACING` apart.
        s: their arc length along the path (N,) [m].

    Returns:
        ``high_centred`` (any sample is), ``samples``, ``spacing_m`` and ``stretches``
        (arc lengths [m] where it is).
    """
    P = np.atleast_2d(np.asarray(poses, dtype=float))
    s_m = np.asarray(s, dtype=float)
    rest = getattr(terrain, "rest", None)
    flags = (
        np.zeros(len(P), bool) if rest is None else np.asarray(rest(P, strict=False).high_centred)
    )
    stretches = [
        {"start_s": float(s_m[a]), "end_s": float(s_m[b - 1])} for a, b in true_runs(flags)
    ]
    return {
        "high_centred": bool(flags.any()),
        "samples": len(P),
        "spacing_m": float(np.median(np.diff(s_m))) if len(s_m) > 1 else 0.0,
        "criterion": "the rested chassis does not touch the ground along the path",
        "stretches": stretches,
    }


def path_samples(base_path: Any, spacing: float = SPACING) -> tuple[Any, Any]:
    """(poses (N, 3), arc lengths (N,) [m]) of a path about ``spacing`` [m] apart.

    Args:
        base_path: a route (``n`` poses from start to goal) or a closed lap (``n`` poses
            over one lap, the start once) (:mod:`mmstab.paths`).
        spacing: [m].
    """
    n = max(int(np.ceil(base_path.length / spacing)) + 1, 2)
    closed = bool(base_path.closed)
    s = base_path.length * np.arange(n) / n if closed else np.linspace(0.0, base_path.length, n)
    return base_path.poses(n), s
