"""A tracking run's headline numbers (``results/tracking/summary.json``)."""

from __future__ import annotations

from typing import Any

import numpy as np

from mmstab.control.approach import ArmReferences
from mmstab.model.robot import FloatArray
from mmstab.runs.tracking.run import TRANSIENT_FRACTION, TrackingRun, joint_names


def transient_end(run: TrackingRun) -> int:
    """The sample where the initial transient ends (0 when the arm starts on its reference).

    With a start-up approach, the first sample at or after its end. Without one, the first
    index from which the arm-CoM error stays within :data:`TRANSIENT_FRACTION` of its initial
    value.
    """
    if run.approach is not None:
        return int(np.searchsorted(run.t, run.approach.duration - 0.5 * run.dt))
    e = run.arm_com_error
    above = np.flatnonzero(e > TRANSIENT_FRACTION * e[0])
    return int(above[-1] + 1) if above.size and e[0] > 0 else 0


def summarize(run: TrackingRun) -> dict[str, Any]:
    """The run's headline numbers (the keys of ``results/tracking/summary.json``).

    Besides the whole-run numbers, ``after_transient`` repeats errors, mean joint speeds and
    μ from :func:`transient_end` on: the initial reconfiguration (from the stowed arm)
    dominates the whole-run maxima and minima (with an approach: the approach is the transient).
    ``posture_reference`` is the posture
    reference's collision check and via postures (:meth:`PostureReference.summary`).
    """
    names = joint_names(run.qdot.shape[1] - 2)

    def arm_dict(values: FloatArray) -> dict[str, float]:
        return dict(zip(names[2:], np.asarray(values, dtype=float).tolist(), strict=True))

    limit = run.qdot_limit
    saturated = np.isclose(np.abs(run.qdot), limit, rtol=0, atol=1e-9)
    cases = run.mu._asdict()
    k = min(transient_end(run), run.steps - 1)
    after = {
        "start_s": float(run.t[k]),
        "base_error_max_m": float(run.base_error[k:].max()),
        "arm_com_error_max_m": float(run.arm_com_error[k:].max()),
        "posture_error_max_abs_rad": arm_dict(np.abs(run.posture_error[k:]).max(axis=0)),
        "qdot_mean_abs": dict(zip(names, np.abs(run.qdot[k:]).mean(axis=0).tolist(), strict=True)),
        "mu_min": {name: float(v[k:].min()) for name, v in cases.items()},
        "mu_mean": {name: float(v[k:].mean()) for name, v in cases.items()},
    }
    return {
        "base_error_max_m": float(run.base_error.max()),
        "base_error_final_m": float(run.base_error[-1]),
        "arm_com_error_max_m": float(run.arm_com_error.max()),
        "arm_com_error_final_m": float(run.arm_com_error[-1]),
        "heading_error_max_abs_rad": float(np.abs(run.heading_error).max()),
        "posture_error_max_abs_rad": arm_dict(np.abs(run.posture_error).max(axis=0)),
        "posture_error_final_abs_rad": arm_dict(np.abs(run.posture_error[-1])),
        "qdot_max_abs": dict(zip(names, np.abs(run.qdot).max(axis=0).tolist(), strict=True)),
        "qdot_mean_abs": dict(zip(names, np.abs(run.qdot).mean(axis=0).tolist(), strict=True)),
        "qdot_limit": dict(zip(names, limit.tolist(), strict=True)),
        "saturated_steps": dict(zip(names, saturated.sum(axis=0).tolist(), strict=True)),
        "last_saturated_time_s": float(run.t[np.flatnonzero(saturated.any(axis=1))[-1]])
        if saturated.any()
        else None,
        "mean_track_speed_left": float(run.qdot[:, 0].mean()),
        "mean_track_speed_right": float(run.qdot[:, 1].mean()),
        "right_track_faster_share": float(np.mean(run.qdot[:, 1] > run.qdot[:, 0])),
        "mu_min": {name: float(v.min()) for name, v in cases.items()},
        "mu_mean": {name: float(v.mean()) for name, v in cases.items()},
        "after_transient": after,
        "qp_failures": len(run.failures),
        "qp_failure_events": [
            {"step": f.step, "time_s": f.time, "status": f.status.name} for f in run.failures
        ],
        "steps": run.steps,
        "dt_s": run.dt,
        "duration_s": float(run.t[-1]),
        "wall_seconds": run.wall_seconds,
        "build_seconds": run.build_seconds,
        "us_per_step": run.us_per_step,
        "plugin": run.plugin,
        "backend": run.backend,
        "initial_arm": run.initial_arm,
        "posture_reference": run.posture.summary(run.lap_time),
        "approach": None if run.approach is None else run.approach.summary(),
        "arm_timing": ArmReferences(run.posture, run.approach, run.timing).timing_summary(
            float(run.t[-1])
        ),
        "tipped": None if run.tipped is None else run.tipped.summary(),
    }
