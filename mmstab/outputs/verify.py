"""A plan checked in physics: ``mmstab plan --verify`` runs the route in MuJoCo after planning.

mmstab's verdict on the plan (accepted, or refused: it tips below the margin, or it slides)
is set beside MuJoCo's outcome of the same plan run with the controller in the loop (it
holds, tips, leaves the map, slides, touches the ground with the arm or stalls:
:mod:`mmstab.physics.closed_loop`), and the two agree when an accepted plan holds and a
refused one fails. An arm link on the ground is an outcome as ``mmstab simulate``'s exit 5
is: an accepted route whose arm touches the ground in physics is not safe. The run's summary and its
figure go to ``verify/`` beside the plan's.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from mmstab.core.files import write_json
from mmstab.core.problem import Problem

#: mmstab plan's verdicts and their exit statuses.
PLAN_VERDICTS = {"accepted": 0, "tips": 3, "slides": 4, "no plan": 6}
#: MuJoCo's outcomes, the first event of a run that counts, in this order.
OUTCOMES = ("tips", "leaves the map", "slides", "touches the ground", "stalls", "holds")
#: The run summary's event of each outcome but ``holds`` (:data:`OUTCOMES`' order).
EVENTS = ("tipped", "left_map", "slid", "arm_ground_contact", "stalled")


def plan_verdict_of(summary: dict[str, Any]) -> str:
    """``mmstab plan``'s verdict of a route plan's summary: its stability, then its slip."""
    if not summary["stability"]["stable"]:
        return "tips"
    if summary["slip"]["slides"]:
        return "slides"
    return "accepted"


def outcome_of(s: dict[str, Any]) -> str:
    """MuJoCo's outcome of a ``mmstab simulate`` summary (:data:`OUTCOMES`' order)."""
    for name, key in zip(OUTCOMES, EVENTS, strict=False):
        if s[key] is not None:
            return name
    return "holds"


def verify_plan(problem: Problem, plan: Any, summary: dict[str, Any], out: Path) -> dict[str, Any]:
    """Run ``plan`` in MuJoCo and set its outcome beside the plan's verdict.

    Args:
        problem: the problem (its ``physics:`` section).
        plan: the route plan (:func:`mmstab.app.plan`).
        summary: the plan's ``summary.json`` (its verdicts).
        out: the folder for the run's ``summary.json`` and ``physics.png``.

    Returns:
        ``plan`` (verdict), ``mujoco`` (outcome), ``agree``, the run's events, μ predicted
        against simulated (median relative difference), and the base's largest errors at
        the control point and the body origin [m].
    """
    from mmstab.outputs.simulate import loop_settings, place_events, simulate_run, summarize
    from mmstab.outputs.simulate_figure import write_run_figure

    problem = problem.following(plan)  # MuJoCo's reference on the plan's (slowed) time law
    loop = loop_settings(problem)
    run = simulate_run(problem, loop, plan)
    sim = summarize(run, loop)
    place_events(sim, run, problem.base_path)
    out.mkdir(parents=True, exist_ok=True)
    write_run_figure(out / "physics.png", problem, run, loop)
    write_json(out / "summary.json", sim)
    verdict, outcome = plan_verdict_of(summary), outcome_of(sim)
    ok = np.isfinite(run.mu_simulated) & np.isfinite(run.mu_predicted)
    rel = np.abs(run.mu_simulated[ok] - run.mu_predicted[ok]) / np.abs(run.mu_predicted[ok])
    return {
        "plan": verdict,
        "mujoco": outcome,
        "agree": (verdict == "accepted") == (outcome == "holds"),
        "events": {k: sim[k] for k in EVENTS},
        "disagreement": sim["disagreement"],
        "mu_relative_difference_median": float(np.median(rel)) if ok.any() else None,
        "base_error_max_m": sim["base_error_max_m"],
        "base_origin_error_max_m": sim["base_origin_error_max_m"],
        "simulated_s": sim["duration_s"],
        "run": str(out),
    }
