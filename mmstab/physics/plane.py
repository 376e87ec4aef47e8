"""The resting pose on a PLANE by hand geometry: the analytic predictor of the validation.

On a plane ``z = c + a x + b y`` (G) the tracks' flat bottoms lie on the plane, so B's
z axis is the plane's normal ``n ~ (-a, -b, 1)``, B's origin (the centre of the track
contact rectangle) is ON the plane, and B's x axis is the plane direction whose vertical
projection has the commanded heading ``yaw`` about G's z:
``x_B ~ (cos yaw, sin yaw, a cos yaw + b sin yaw)``. This is independent of MuJoCo and of
any contact model; it holds while the base stands on its tracks (flippers raised).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from mmstab.core.files import MmstabError
from mmstab.model.robot import FloatArray

#: predict(poses (N, 3) of (x, y, yaw) in G) -> (roll (N,) [rad], pitch (N,) [rad], z (N,) [m]).
Predictor = Callable[[FloatArray], tuple[FloatArray, FloatArray, FloatArray]]


class Prediction(NamedTuple):
    """Predicted resting roll, pitch [rad] and height of B's origin [m], each (N,)."""

    roll: FloatArray
    pitch: FloatArray
    z: FloatArray


def fit_plane(xy: ArrayLike, z: ArrayLike) -> tuple[float, float, float]:
    """Least-squares plane ``z = c + a x + b y`` through points: returns (a, b, c).

    Args:
        xy: (n, 2) G positions [m].
        z: (n,) heights [m].
    """
    p = np.asarray(xy, dtype=float).reshape(-1, 2)
    A = np.column_stack([p, np.ones(len(p))])
    (a, b, c), *_ = np.linalg.lstsq(A, np.asarray(z, dtype=float).ravel(), rcond=None)
    return float(a), float(b), float(c)


def tilted_frame(a: float, b: float, yaw: float) -> FloatArray:
    """G_R_B (3, 3) on the plane of gradient (a, b) [-] with heading ``yaw`` [rad] about G's z."""
    z = np.array([-a, -b, 1.0])
    z /= np.linalg.norm(z)
    x = np.array([np.cos(yaw), np.sin(yaw), a * np.cos(yaw) + b * np.sin(yaw)])
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def attitude(yaw: float, roll: float, pitch: float) -> FloatArray:
    """G_R_B = Rz(yaw) Ry(-pitch) Rx(roll) (3, 3): the inverse of :func:`roll_pitch` [rad]."""
    cy, sy, cr, sr = np.cos(yaw), np.sin(yaw), np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    Rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    Ry = np.array([[cp, 0.0, -sp], [0.0, 1.0, 0.0], [sp, 0.0, cp]])
    Rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return Rz @ Ry @ Rx


def roll_pitch(G_R_B: ArrayLike) -> tuple[float, float]:
    """Roll and pitch [rad] of a body attitude, as ``Ramp.roll_pitch``: from gravity in B.

    Positive roll lifts the left side (+y_B), positive pitch lifts the nose (+x_B).
    """
    R = np.asarray(G_R_B, dtype=float)
    up = R[2]  # G's z in B = -gravity direction in B
    return float(np.arctan2(up[1], up[2])), float(np.arctan2(up[0], np.hypot(up[1], up[2])))


def plane_predictor(
    elevation: ArrayLike, resolution: float, origin: ArrayLike, tol: float = 1e-6
) -> Predictor:
    """The analytic resting pose on a plane heightmap (grid_map convention).

    Args:
        elevation: heights ``[iy, ix]`` [m], samples of one plane.
        resolution: cell size [m/cell].
        origin: G (x, y) of the centre of cell [0, 0] [m].
        tol: largest residual of the plane fit accepted [m].

    Raises:
        MmstabError: the heightmap is not a plane.
    """
    e = np.asarray(elevation, dtype=float)
    ny, nx = e.shape
    ix, iy = np.meshgrid(np.arange(nx), np.arange(ny))
    xy = np.stack([ix, iy], -1).reshape(-1, 2) * float(resolution) + np.asarray(origin, float)
    a, b, c = fit_plane(xy, e.ravel())
    residual = float(np.max(np.abs(c + xy @ [a, b] - e.ravel())))
    if residual > tol:
        raise MmstabError(
            f"plane predictor: the heightmap is not a plane (residual {residual:.3g} m)"
        )

    def predict(poses: FloatArray) -> Prediction:
        P = np.atleast_2d(np.asarray(poses, dtype=float))
        rp = np.array([roll_pitch(tilted_frame(a, b, yaw)) for yaw in P[:, 2]]).reshape(-1, 2)
        return Prediction(rp[:, 0], rp[:, 1], c + a * P[:, 0] + b * P[:, 1])

    return predict
