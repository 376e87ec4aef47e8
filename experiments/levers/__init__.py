"""make levers: payload, flippers, speed and robot variants as stability levers.

Four experiments on the problem's ramp (``docs/levers.md``), settings in its ``levers:``
section, every number in ``results/levers/summary.json``:

- **dynamic**: static vs dynamic force-angle μ along the lap at several lap speeds, the
  planned arm and the stowed arm; the fastest safe lap (bisection on the lap speed). The
  accelerations are those of the *reference motion*, differentiated numerically: the base
  drives the circle at constant speed, the arm follows a periodic cubic spline through the
  planned postures, every body's CoM is placed in M and differentiated twice in time
  (periodic central differences). Bodies are point masses (the description has no inertia
  tensors), so the inertial moments about their own CoMs are zero. A cross-check runs the
  closed loop (``app.track``) at each speed and measures the simulated states' second
  differences over ``SIM_WINDOW`` (:func:`simulated_check`).
- **payload**: the heaviest payload held at the front, left and right on a side slope,
  arm planned (the best collision-free grid posture of V with the turret pointing there and
  the tool held out ``payload_reach`` beyond the tracks' footprint on that side), stowed
  (links 1-3 folded, turret pointing away: the folded arm holds the load over the base on
  that side, :func:`stowed_holding`) and fixed (the
  arm stretched level, turret pointing there); bisection on the mass.
- **variants**: per robot file, the planned and stowed μ along the lap (CMA-ES, V on
  ``levers.variant_grid``), optionally along the circle of a rough-ground problem
  (``levers.rough_problem``: the planner on the heightmap, μ then measured on the resting
  contacts), and the steepest side slope with μ >= margin, arm planned (the best of V's
  samples, both sides downhill) and stowed; bisection on the slope.
- **flippers**: μ along the lap, arm only vs arm + flippers
  (:func:`mmstab.planner.levers.solve_path_flippers`), on the problem's ramp and on the
  side slope's ramp; both with the exhaustive Eq. 6 search (no sampling noise between them).

One module per experiment (``dynamic``, ``payload``, ``variants``, ``flippers``; shared
settings and helpers in ``common``); :func:`run_levers` runs them all.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

from experiments.levers.common import bisect_largest, levers_settings
from experiments.levers.dynamic import (
    draw_dynamic,
    draw_route_dynamic,
    lap_measure,
    lap_motion,
    posture_spline,
    route_dynamic,
    run_dynamic,
    simulated_check,
)
from experiments.levers.flippers import draw_flippers, run_flippers
from experiments.levers.payload import draw_payload, run_payload, stowed_holding
from experiments.levers.variants import (
    check_variant_files,
    draw_variants,
    run_variants,
    variants_table,
)
from mmstab.core.files import write_json, write_text
from mmstab.core.problem import Problem, load_problem
from mmstab.outputs.common import output_dir, save_settings

__all__ = [
    "bisect_largest",
    "draw_dynamic",
    "draw_flippers",
    "draw_payload",
    "draw_route_dynamic",
    "draw_variants",
    "lap_measure",
    "lap_motion",
    "levers_settings",
    "posture_spline",
    "route_dynamic",
    "run_dynamic",
    "run_flippers",
    "run_levers",
    "run_payload",
    "run_variants",
    "simulated_check",
    "stowed_holding",
    "variants_table",
]


def run_levers(problem: Problem, out: str | Path | None = None) -> dict[str, Any]:
    """Every levers experiment; figures, ``variants.md`` and ``summary.json`` in ``out``."""
    from mmstab.app import plan as plan_of
    from mmstab.app import workspace

    settings = levers_settings(problem)
    check_variant_files(problem, settings)  # before any work or output
    d = output_dir(out, "levers")
    t0 = time.perf_counter()
    ws = workspace(problem)
    plan = plan_of(problem, ws=ws)
    summary: dict[str, Any] = {"problem": str(problem.path), "margin_N_rad": settings.margin}
    dyn, dyn_curves = run_dynamic(problem, plan.postures, settings)
    dyn["simulated_planned"] = simulated_check(problem, plan, settings)
    if settings.rough_problem is not None:
        rough = load_problem(problem.path.parent / settings.rough_problem)
        if rough.route is not None:
            dyn["rough_route"], route_curves = route_dynamic(rough)
            draw_route_dynamic(route_curves, settings, d / "dynamic_route.png")
    summary["dynamic"] = dyn
    draw_dynamic(dyn_curves, settings, d / "dynamic.png")
    summary["payload"] = run_payload(problem, ws.valid_q, settings)
    draw_payload(summary["payload"], d / "payload.png")
    summary["variants"] = run_variants(problem, settings)
    draw_variants(summary["variants"], d / "variants.png")
    write_text(d / "variants.md", variants_table(summary["variants"]))
    flip, flip_curves = run_flippers(problem, ws, settings)
    summary["flippers"] = flip
    fl = problem.robot.base.flippers
    lim = None if fl is None else fl.limits
    span = (lim.lower, lim.upper) if lim is not None else (-math.pi / 2, math.pi / 2)
    draw_flippers(flip_curves, flip, span, d / "flippers.png")
    summary["seconds"] = time.perf_counter() - t0
    save_settings(d, problem)
    write_json(d / "summary.json", summary)
    return summary
