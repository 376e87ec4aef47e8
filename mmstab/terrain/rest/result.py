"""The resting pose's result: flags and body poses from the solved attitudes; off-map errors.

Both solvers (the C kernel and the NumPy twin) end in attitudes and lifts; these turn them
into :class:`~mmstab.terrain.rest.types.RestPoses` (height, ``G_T_B``, touching and bearing
contacts, high-centring, line contact) or, for a pose that needs ground off the map, into an
:class:`~mmstab.terrain.heightmap.OffMapError` that names it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mmstab.terrain.contacts import CHASSIS
from mmstab.terrain.heightmap import FloatArray, Heightmap, OffMapError
from mmstab.terrain.rest.geometry import rotations
from mmstab.terrain.rest.types import BoolArray, RestPoses, RestSettings


def raise_off_map(
    hm: Heightmap, c: FloatArray, xy: FloatArray, yaw: FloatArray, att: FloatArray, valid: BoolArray
) -> None:
    """Raise :class:`OffMapError` for the first pose not ``valid`` (the ground it needs)."""
    i = int(np.flatnonzero(~valid)[0])
    R = rotations(yaw[i : i + 1], att[i : i + 1, 0], att[i : i + 1, 1])[0][0]
    pts = xy[i] + (c @ R.T)[:, :2]
    x, y = xy[i]
    try:
        hm.check(hm.sample(pts), pts, what=f"pose ({x:.3f}, {y:.3f}, {yaw[i]:.3f}): contact")
    except OffMapError:
        raise
    raise OffMapError(f"{hm.source}: pose ({x:.3f}, {y:.3f}) m needs ground off the map")


def rest_result(
    c: FloatArray,
    p: FloatArray,
    att: FloatArray,
    f: FloatArray,
    valid: BoolArray,
    converged: BoolArray,
    tips: BoolArray,
    iterations: NDArray[np.int_],
    part: ArrayLike | None,
    settings: RestSettings,
    compliant: ArrayLike | None = None,
) -> RestPoses:
    """:class:`RestPoses` of poses ``p`` (n, 3) from the attitudes (n, 2) [rad], lifts (n, K) [m].

    Poses not ``valid`` come back NaN, with no contacts and no flags.
    """
    n, K = p.shape[0], c.shape[0]
    R = rotations(p[:, 2], att[:, 0], att[:, 1])[0]
    z = np.max(f, axis=1)
    gap = z[:, None] - f
    touching = gap <= settings.contact_tol
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = R
    T[:, :3, 3] = np.concatenate([p[:, :2], z[:, None]], axis=1)
    codes = np.full(K, -1) if part is None else np.asarray(part)
    high = (touching & (codes == CHASSIS)[None, :]).any(axis=1)
    bearing = touching.copy()
    # a damped limit cycle between triangles: the contacts it rocks between carry the load
    cycling = valid & ~converged & ~tips
    bearing |= cycling[:, None] & (gap <= settings.cycle_tol)
    if compliant is not None:
        bearing |= np.asarray(compliant, dtype=bool)[None, :] & (gap <= settings.compliance)
    # line contact: the bearing points' footprint has no width. Its covariance is the
    # bearing candidates' covariance in B turned into G (cheaper than placing them all).
    wgt = bearing / np.maximum(bearing.sum(axis=1), 1)[:, None]
    mean = wgt @ c  # (n, 3)
    second = (wgt @ (c[:, :, None] * c[:, None, :]).reshape(K, 9)).reshape(n, 3, 3)
    cov_B = second - mean[:, :, None] * mean[:, None, :]
    cov = R[:, :2] @ cov_B @ R[:, :2].transpose(0, 2, 1)  # (n, 2, 2) in G's x, y
    sxx, syy, sxy = cov[:, 0, 0], cov[:, 1, 1], cov[:, 0, 1]
    smallest = (sxx + syy) / 2 - np.sqrt(((sxx - syy) / 2) ** 2 + sxy**2)  # 2x2 eigenvalue
    width = 2 * np.sqrt(np.maximum(smallest, 0.0))
    line = width < settings.line_width
    bad = ~valid
    roll, pitch = att[:, 0].copy(), att[:, 1].copy()
    for a in (roll, pitch, z):
        a[bad] = np.nan
    T[bad] = np.nan
    gap[bad] = np.nan
    touching[bad] = False
    bearing[bad] = False
    return RestPoses(
        poses=p,
        roll=roll,
        pitch=pitch,
        z=z,
        G_T_B=T,
        gap=gap,
        touching=touching,
        bearing=bearing,
        high_centred=high & valid,
        line_contact=line & valid,
        tips_over=tips & valid,
        converged=converged & valid,
        iterations=iterations,
    )
