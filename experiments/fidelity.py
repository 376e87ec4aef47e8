"""How faithful mmstab's figures are to the paper's claims, computed from saved results.

Reads what the other experiments wrote (nothing is recomputed) and writes
``results/fidelity/summary.json``: per paper figure the paper's claim and the numbers that
confirm or contradict it. ``docs/planner.md`` explains the differences.

- Fig. 6 (``results/fig6/summary.json``): how many link0 sweeps have exactly two maxima,
  and whether they lie near 2.0 and 5.0 rad as the paper says.
- Fig. 8 (``results/fig8/summary.json``): the planned arm side per pose against the
  paper's pattern, the planner's gap to the exhaustive Eq. 6 optimum, V's cost.
- Fig. 11 (``results/tracking/summary.json`` and ``problem.yaml``): joint-speed
  saturation at the 4 pi rad/s limit.
- Fig. 12 (``results/tracking/run.npz``): the intervals where the reconfigured arm is less
  stable than the stowed arm (or than the arm removed).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import yaml

from mmstab.core.files import MmstabError, write_json
from mmstab.core.masks import true_runs
from mmstab.core.problem import Problem

#: Paper Fig. 6: the two maxima of the link0 sweep [rad].
PAPER_MAXIMA_RAD = (2.0, 5.0)
#: A maximum is "near" a paper value within this [rad].
NEAR_RAD = 0.5
#: Paper Fig. 8 (ten poses): front right for the first four, front left for the next
#: four, then front right again.
PAPER_FIG8_SIDES = ["right"] * 4 + ["left"] * 4 + ["right"] * 2


def _read_json(path: Path, make: str) -> Any:
    import json

    if not path.is_file():
        raise MmstabError(f"fidelity: {path} is missing; run `make {make}` first")
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise MmstabError(f"fidelity: {path}: unreadable ({exc})") from None


def fig6_fidelity(summary: dict[str, Any]) -> dict[str, Any]:
    """Maxima count and position per pose of the Fig. 6 sweeps."""
    counts = [int(c) for c in summary["maxima_per_pose"]]
    near = []
    for pose in summary["poses"]:
        maxima = np.asarray(pose["local_maxima_rad"], dtype=float)
        hit = [
            bool(np.any(np.abs(np.angle(np.exp(1j * (maxima - m)))) <= NEAR_RAD))
            for m in PAPER_MAXIMA_RAD
        ]
        near.append(all(hit))
    return {
        "paper": "two maxima, near 2.0 and 5.0 rad, at every pose",
        "poses": len(counts),
        "maxima_per_pose": counts,
        "poses_with_two_maxima": sum(c == 2 for c in counts),
        "poses_with_three_maxima": sum(c == 3 for c in counts),
        "poses_with_maxima_near_paper": int(sum(near)),
        "near_rad": NEAR_RAD,
        "maxima_rad_per_pose": [p["local_maxima_rad"] for p in summary["poses"]],
    }


def fig8_fidelity(summary: dict[str, Any]) -> dict[str, Any]:
    """Planned arm side per pose against the paper's pattern; planner and V quality."""
    poses = summary["poses"]
    sides = [p["side"] for p in poses]
    mirror = {"left": "right", "right": "left"}
    out: dict[str, Any] = {
        "paper": "front right for poses 1-4, front left for 5-8, front right for 9-10",
        "sides": sides,
        "front": [bool(p["front"]) for p in poses],
        "poses_in_front": int(sum(bool(p["front"]) for p in poses)),
        "side_switches": int(sum(a != b for a, b in zip(sides, sides[1:], strict=False))),
    }
    if len(sides) == len(PAPER_FIG8_SIDES):
        out["sides_as_paper"] = int(
            sum(a == b for a, b in zip(sides, PAPER_FIG8_SIDES, strict=True))
        )
        out["sides_as_paper_mirrored"] = int(
            sum(mirror[a] == b for a, b in zip(sides, PAPER_FIG8_SIDES, strict=True))
        )
    if "fitness_gap_pct" in poses[0]:
        out["planner_gap_to_exhaustive_pct"] = [p["fitness_gap_pct"] for p in poses]
        out["mu_planned"] = [p["mu_planned"] for p in poses]
        out["mu_best_in_V"] = [p["mu_best_in_V"] for p in poses]
        out["mu_best_valid"] = [p["mu_best_valid"] for p in poses]
        out["mu_stowed"] = [p["mu_stowed"] for p in poses]
        out["lap_quality"] = summary.get("lap_quality")
    return out


def fig11_fidelity(summary: dict[str, Any], approach_time: float | None) -> dict[str, Any]:
    """Joint-speed peaks against their limits in the tracking run."""
    peak, limit = summary["qdot_max_abs"], summary["qdot_limit"]
    return {
        "paper": "the arm joint speeds saturate at 4 pi rad/s early in the run",
        "approach_time_s": approach_time,
        "peak_over_limit": {k: float(peak[k]) / float(limit[k]) for k in peak},
        "saturated_steps": summary["saturated_steps"],
        "saturates": bool(any(int(v) > 0 for v in summary["saturated_steps"].values())),
        "last_saturated_time_s": summary.get("last_saturated_time_s"),
    }


def below_intervals(t: np.ndarray, value: np.ndarray, floor: np.ndarray) -> list[dict[str, float]]:
    """Intervals where ``value < floor``: first and last sample time [s], largest deficit."""
    return [
        {
            "start_s": float(t[k]),
            "end_s": float(t[j - 1]),
            "max_deficit": float(np.max(floor[k:j] - value[k:j])),
        }
        for k, j in true_runs(np.asarray(value) < np.asarray(floor))
    ]


def fig12_fidelity(run: Any) -> dict[str, Any]:
    """Where the tracked, reconfigured arm is below the stowed arm or the arm removed."""
    t = np.asarray(run["t"], dtype=float)
    mu = np.asarray(run["mu_reconfigured"], dtype=float)
    stowed = np.asarray(run["mu_stowed"], dtype=float)
    removed = np.asarray(run["mu_arm_removed"], dtype=float)
    return {
        "paper": "the reconfigured arm is clearly more stable than the arm removed along the run",
        "samples": int(t.size),
        "below_stowed": below_intervals(t, mu, stowed),
        "below_stowed_share": float(np.mean(mu < stowed)),
        "below_arm_removed": below_intervals(t, mu, removed),
        "mean_over_stowed_pct": float(100 * (mu.mean() / stowed.mean() - 1)),
        "mean_over_arm_removed_pct": float(100 * (mu.mean() / removed.mean() - 1)),
    }


def run_fidelity(
    problem: Problem, out: str | Path | None = None, results: str | Path = "results"
) -> dict[str, Any]:
    """Read the saved experiments under ``results`` and write the fidelity summary.

    Args:
        problem: the problem (recorded; the results must be this problem's).
        out: output folder (default ``results/fidelity``).
        results: where the other experiments wrote (``fig6/``, ``fig8/``, ``tracking/``).

    Raises:
        MmstabError: a needed result is missing or unreadable (names the make target).
    """
    from mmstab.outputs.common import output_dir

    root = Path(results)
    fig6 = _read_json(root / "fig6" / "summary.json", "fig6")
    fig8 = _read_json(root / "fig8" / "summary.json", "fig8")
    tracking = _read_json(root / "tracking" / "summary.json", "tracking")
    npz = root / "tracking" / "run.npz"
    if not npz.is_file():
        raise MmstabError(f"fidelity: {npz} is missing; run `make tracking` first")
    approach, tracking_planner = None, None
    settings = root / "tracking" / "problem.yaml"
    if settings.is_file():
        saved = yaml.safe_load(settings.read_text())
        approach = saved["controller"].get("approach_time")
        tracking_planner = saved.get("planner")
    with np.load(npz) as run:
        fig12 = fig12_fidelity(run)
    summary = {
        "problem": str(problem.path),
        "fig6": fig6_fidelity(fig6),
        "fig8": fig8_fidelity(fig8),
        "fig11": fig11_fidelity(tracking, approach),
        "fig12": fig12,
        "sources": {
            "fig6": str(root / "fig6" / "summary.json"),
            "fig8": str(root / "fig8" / "summary.json"),
            "tracking": [str(root / "tracking" / "summary.json"), str(npz)],
            "fig8_planner": fig8.get("settings"),
            "tracking_planner": tracking_planner,
        },
    }
    write_json(output_dir(out, "fidelity") / "summary.json", summary)
    return summary
