"""Compare a resting-pose predictor with MuJoCo drops: error distributions and outliers.

A predictor is ``predict(poses (N, 3) of (x, y, yaw) in G) -> (roll (N,), pitch (N,), z
(N,))`` [rad, rad, m] (:data:`mmstab.physics.plane.Predictor`). By default it is
evaluated where MuJoCo's robot actually came to rest (settled x, y, yaw), so a few mm of
slip or a small yaw drift of the simulated drop do not count as prediction errors;
``at="commanded"`` evaluates it at the commanded poses instead.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from mmstab.model.robot import FloatArray
from mmstab.physics.mujoco_drop import DropModel, DropResult
from mmstab.physics.plane import Predictor, attitude

#: explain(index, drops, prediction errors row) -> a sentence, or "" when it has nothing to say.
Explainer = Callable[[int, DropResult, dict[str, float]], str]


class Comparison(NamedTuple):
    """Prediction minus MuJoCo, per drop, and its distribution.

    Attributes:
        roll_deg: |Δroll| (N,) [deg].
        pitch_deg: |Δpitch| (N,) [deg].
        z_m: |Δz| of B's origin (N,) [m].
        settled: which drops settled (N,) bool; statistics use only those.
        stats: ``{"roll_deg"|"pitch_deg"|"z_m": {"median", "p95", "max"}}`` and counts.
        outliers: one dict per drop over a threshold or unsettled (index, pose, errors, why).
    """

    roll_deg: FloatArray
    pitch_deg: FloatArray
    z_m: FloatArray
    settled: np.ndarray
    stats: dict[str, Any]
    outliers: list[dict[str, Any]]


def distribution(values: FloatArray) -> dict[str, float]:
    """Median, 95th percentile and maximum of non-negative errors (NaN when empty)."""
    v = np.asarray(values, dtype=float)
    if v.size == 0:
        return {"median": float("nan"), "p95": float("nan"), "max": float("nan")}
    return {
        "median": float(np.median(v)),
        "p95": float(np.percentile(v, 95)),
        "max": float(np.max(v)),
    }


def default_explanation(index: int, drops: DropResult, errors: dict[str, float]) -> str:
    """Facts of the drop that usually explain a large error (the first hook)."""
    reasons = []
    if not drops.settled[index]:
        reasons.append(f"did not settle within {drops.time[index]:.1f} s (fell off or rocking)")
    if abs(drops.roll[index]) > np.pi / 2 or abs(drops.pitch[index]) > np.pi / 2:
        reasons.append("turned over while settling (a tumble of the release, not a rest)")
    touching = drops.touching[index]
    if "chassis" in touching:
        reasons.append("chassis on the ground (high-centred)")
    if any(t.startswith("flipper") for t in touching):
        reasons.append("resting on a flipper")
    sides = {t.split("_")[1] for t in touching if t.startswith(("track_", "wheel_"))}
    if len(sides) < 2:
        reasons.append(f"tracks touching: {sorted(sides) or 'none'} (tipped or balanced)")
    if drops.slip[index] > 0.02:
        reasons.append(f"slid {1000 * drops.slip[index]:.0f} mm while settling")
    if abs(drops.yaw_drift[index]) > np.radians(2):
        reasons.append(f"turned {np.degrees(drops.yaw_drift[index]):.1f} deg while settling")
    return "; ".join(reasons)


def rest_state_check(
    model: DropModel, predict: Predictor, lift: float = 1e-3, tol_deg: float = 0.5
) -> Explainer:
    """A hook that releases MuJoCo's robot AT the predicted rest and watches what it does.

    If it stays (within ``tol_deg``), the prediction is a MuJoCo rest state too: the drop
    found another one (two rest states, e.g. tipping either way over a crest). If it
    moves away, the prediction is not a MuJoCo rest: a predictor error, or a rest so
    marginal that the surfaces' small differences (MuJoCo's triangles vs bilinear cells,
    about a millimetre on curved ground) tip it.

    Args:
        model: the drop model the drops were made with.
        predict: the predictor being compared.
        lift: release the prediction this much higher, so no contact starts penetrating [m].
        tol_deg: largest roll/pitch change that counts as staying [deg].
    """

    def hook(index: int, drops: DropResult, errors: dict[str, float]) -> str:
        if not drops.settled[index]:
            return ""
        pose = drops.settled_poses[index]
        roll, pitch, z = (float(np.asarray(v).ravel()[0]) for v in predict(pose[None]))
        T = np.eye(4)
        T[:3, :3] = attitude(pose[2], roll, pitch)
        T[:3, 3] = [pose[0], pose[1], z + lift]
        again = model.drop_one(pose, start=T)
        moved = np.degrees(max(abs(again["roll"] - roll), abs(again["pitch"] - pitch)))
        if again["settled"] and moved <= tol_deg:
            return (
                f"two rest states: released at the prediction MuJoCo stays there "
                f"(within {moved:.2f} deg)"
            )
        return (
            f"MuJoCo does not stay at the prediction: released there it moves {moved:.1f} deg "
            f"(to roll {np.degrees(again['roll']):.2f}, pitch {np.degrees(again['pitch']):.2f} "
            "deg): a predictor error, or a rest too marginal for the surfaces' differences"
        )

    return hook


def compare(
    predict: Predictor,
    drops: DropResult,
    at: str = "settled",
    outlier_deg: float = 2.0,
    outlier_z: float = 0.01,
    explain: tuple[Explainer, ...] = (default_explanation,),
) -> Comparison:
    """Errors of ``predict`` against the MuJoCo drops.

    Args:
        predict: the predictor (poses (N, 3) -> roll, pitch [rad], z [m]).
        drops: the MuJoCo drops (:func:`mmstab.physics.mujoco_drop.drop`).
        at: ``"settled"`` (predict where the robot came to rest) or ``"commanded"``.
        outlier_deg: a drop whose |Δroll| or |Δpitch| exceeds this is an outlier [deg].
        outlier_z: ... or whose |Δz| exceeds this [m].
        explain: hooks that each add a sentence about an outlier (empty string = nothing).
    """
    if at not in ("settled", "commanded"):
        raise ValueError(f"compare: at must be 'settled' or 'commanded', got {at!r}")
    poses = drops.settled_poses if at == "settled" else drops.poses
    roll, pitch, z = (np.asarray(v, dtype=float) for v in predict(poses))
    d_roll = np.degrees(np.abs(_wrap(roll - drops.roll)))
    d_pitch = np.degrees(np.abs(_wrap(pitch - drops.pitch)))
    d_z = np.abs(z - drops.z)
    ok = np.asarray(drops.settled, dtype=bool)
    stats: dict[str, Any] = {
        "roll_deg": distribution(d_roll[ok]),
        "pitch_deg": distribution(d_pitch[ok]),
        "z_m": distribution(d_z[ok]),
        "drops": int(len(ok)),
        "settled": int(ok.sum()),
        "slip_m": distribution(drops.slip[ok]),
        "penetration_m": distribution(drops.penetration[ok]),
    }
    outliers = []
    bad = (~ok) | (d_roll > outlier_deg) | (d_pitch > outlier_deg) | (d_z > outlier_z)
    for i in np.flatnonzero(bad):
        errors = {
            "roll_deg": float(d_roll[i]),
            "pitch_deg": float(d_pitch[i]),
            "z_m": float(d_z[i]),
        }
        why = [s for s in (hook(int(i), drops, errors) for hook in explain) if s]
        outliers.append(
            {
                "index": int(i),
                "pose": [float(v) for v in drops.poses[i]],
                **errors,
                "settled": bool(ok[i]),
                "touching": list(drops.touching[i]),
                "explanation": "; ".join(why) or "unexplained",
            }
        )
    return Comparison(d_roll, d_pitch, d_z, ok, stats, outliers)


def _wrap(a: FloatArray) -> FloatArray:
    return np.pi - np.mod(np.pi - a, 2 * np.pi)
