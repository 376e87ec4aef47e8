"""A plan checked in physics: ``mmstab plan --verify`` runs the route in MuJoCo after planning.

mmstab's verdict on the plan (accepted, or refused: it tips below the margin, it slides, or
the arm touches the robot or the ground)
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
PLAN_VERDICTS = {"accepted": 0, "tips": 3, "slides": 4, "arm contact": 5, "no plan": 6}
#: MuJoCo's outcomes, the first event of a run that counts, in this order.
OUTCOMES = ("tips", "leaves the map", "slides", "touches the ground", "stalls", "holds")
#: The run summary's event of each outcome but ``holds`` (:data:`OUTCOMES`' order).
EVENTS = ("tipped", "left_map", "slid", "arm_ground_contact", "stalled")
#: The plan's limits (its summary's ``verdicts``) that name the place of each outcome.
OUTCOME_LIMITS = {"tips": ("tip",), "slides": ("slide",), "stalls": ("step", "high_centred"),
                  "touches the ground": ("arm_contact",)}  # fmt: skip
#: An event this close to a stretch the plan flags for its limit is at the plan's place [m]
#: (about the robot's length: the plan's stretches are where the body origin is).
SAME_PLACE_M = 0.5


def plan_verdict_of(summary: dict[str, Any]) -> str:
    """``mmstab plan``'s verdict of a route plan's summary: its stability, its slip, its arm.

    In the order of the exit statuses (:func:`mmstab.runs.plan_verdicts.exit_status`).
    """
    if not summary["stability"]["stable"]:
        return "tips"
    if summary["slip"]["slides"]:
        return "slides"
    if summary["verdicts"]["arm_contact"]["unsafe"]:
        return "arm contact"
    return "accepted"


def outcome_of(s: dict[str, Any]) -> str:
    """MuJoCo's outcome of a ``mmstab simulate`` summary (:data:`OUTCOMES`' order)."""
    for name, key in zip(OUTCOMES, EVENTS, strict=False):
        if s[key] is not None:
            return name
    return "holds"


def event_place(
    verdicts: dict[str, Any], outcome: str, events: dict[str, Any]
) -> dict[str, Any] | None:
    """Where MuJoCo's event lies against the stretches the plan flags for the same limit.

    Args:
        verdicts: the plan summary's ``verdicts`` (each limit's ``where``: [start, end] [m]).
        outcome: MuJoCo's outcome (:data:`OUTCOMES`).
        events: the run's events (:data:`EVENTS`), placed (``s_m`` [m] along the route).

    Returns:
        None where the outcome has no limit or its event no place; else the event's
        ``s_m``, the ``limits``, the plan's ``flagged`` stretches for them, ``distance_m`` from the
        nearest (None: none flagged) and ``same_place`` (within :data:`SAME_PLACE_M`).
    """
    limits = OUTCOME_LIMITS.get(outcome)
    event = events.get(EVENTS[OUTCOMES.index(outcome)]) if limits else None
    if limits is None or event is None or "s_m" not in event:
        return None
    s = float(event["s_m"])
    stretches = [w for k in limits for w in verdicts.get(k, {}).get("where", [])]
    flagged = [[float(a), float(b)] for a, b in stretches]
    d = min((max(a - s, s - b, 0.0) for a, b in flagged), default=None)
    return {"s_m": s, "limits": list(limits), "flagged": flagged, "distance_m": d,
            "same_place": d is not None and d <= SAME_PLACE_M}  # fmt: skip


def verify_plan(problem: Problem, plan: Any, summary: dict[str, Any], out: Path) -> dict[str, Any]:
    """Run ``plan`` in MuJoCo and set its outcome beside the plan's verdict.

    Args:
        problem: the problem (its ``physics:`` section).
        plan: the route plan (:func:`mmstab.app.plan`).
        summary: the plan's ``summary.json`` (its verdicts).
        out: the folder for the run's ``summary.json`` and ``physics.png``.

    Returns:
        ``plan`` (verdict), ``mujoco`` (outcome), ``agree``, the run's events, ``place``
        (:func:`event_place`: MuJoCo's event against where the plan flags its limit), μ
        predicted against simulated (median relative difference), and the base's largest
        errors at the control point and the body origin [m].
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
        "place": event_place(summary["verdicts"], outcome, sim),
        "disagreement": sim["disagreement"],
        "mu_relative_difference_median": float(np.median(rel)) if ok.any() else None,
        "base_error_max_m": sim["base_error_max_m"],
        "base_origin_error_max_m": sim["base_origin_error_max_m"],
        "simulated_s": sim["duration_s"],
        "run": str(out),
    }
