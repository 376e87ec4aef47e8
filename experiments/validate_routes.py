"""``make validate-routes``: mmstab's verdicts on random routes refereed by MuJoCo.

Seeded random routes (:func:`experiments.random_routes.random_route`) over seeded
user-like maps (:func:`~experiments.random_routes.user_ground`: side slopes, bumps,
ditches and kerbs across the route), each written as a problem file and then

- **planned** as ``mmstab plan`` plans it (the problem's defaults), with its verdict and exit
  status: ``accepted`` (0), ``tips`` (3: a pose below the planner's margin), ``slides``
  (4: the tracks slide), ``no plan`` (6); the plan's warnings beside it (high-centred, a
  step the planned arm may stall at);
- **simulated** as ``mmstab simulate`` runs it (the plan's arm, the controller in the loop),
  every route whatever the plan's verdict (a refused one forced, as ``--allow-sliding`` and
  ``--allow-unstable`` would): MuJoCo's outcome, the first of ``tips``, ``leaves the map``,
  ``slides``, ``stalls`` (the reference gave up waiting: stuck, high-centred) and ``holds``;
- with ``track: true``, also **tracked** as ``mmstab track`` tracks it: its verdict
  (``accepted``, ``tips``, ``slides``, ``arm collision``) beside the plan's and MuJoCo's.

Writes ``summary.json`` (settings, per-route records, the confusion table plan x MuJoCo,
μ predicted against simulated on the loaded contacts, the tracking errors of the accepted
routes at the body origin and at the control point, the acceptance bars) and
``validate_routes.png``; the problem files in ``problems/``, and the picture of each run
where mmstab and MuJoCo disagree in ``runs/``. The routes run in a process pool
(``workers``).
"""

from __future__ import annotations

import multiprocessing
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from experiments.common import experiment_run
from mmstab.app.settings import Settings
from mmstab.core.files import read_yaml, validate, write_figure, write_json
from mmstab.outputs.verify import EVENTS, OUTCOMES, PLAN_VERDICTS, outcome_of, plan_verdict_of

_RANGE = {"type": "array", "items": {"type": "number"}, "minItems": 2, "maxItems": 2}
_P = {"type": "number", "minimum": 0, "maximum": 1}


def _obj(**props: Any) -> dict[str, Any]:
    return {"type": "object", "additionalProperties": False, "required": list(props),
            "properties": props}  # fmt: skip


SCHEMA = _obj(
    robot={"type": "string"},
    seed={"type": "integer", "minimum": 0},
    routes={"type": "integer", "minimum": 1, "maximum": 1000},
    workers={"type": "integer", "minimum": 1, "maximum": 64},
    route=_obj(waypoints={**_RANGE, "items": {"type": "integer", "minimum": 3}},
               leg_m=_RANGE, turn_max_deg={"type": "number", "minimum": 0, "maximum": 180},
               speed_m_s=_RANGE, margin_m={"type": "number", "minimum": 0}),
    ground=_obj(resolution_m={"type": "number", "exclusiveMinimum": 0}, slope_deg=_RANGE,
                roughness_m=_RANGE, correlation_m=_RANGE, hill_m=_RANGE,
                ditch=_obj(probability=_P, depth_m=_RANGE, width_m=_RANGE),
                kerb=_obj(probability=_P, height_m=_RANGE),
                bumps=_obj(probability=_P, amplitude_m=_RANGE, wavelength_m=_RANGE)),
    problem={"type": "object"},
    bars=_obj(tracking_m={"type": "number"}, mu_relative={"type": "number"},
              refused_fail_share=_P, accepted_share=_P, slope_limit_deg={"type": "number"}),
    runs_figures={"type": "boolean"},
)  # fmt: skip
# optional: also run ``mmstab track`` on each route (its verdict beside the plan's)
SCHEMA["properties"]["track"] = {"type": "boolean"}


def load_settings(path: str | Path) -> dict[str, Any]:
    """Read and check the settings file (errors name the file and the field)."""
    data = read_yaml(path)
    validate(path, data, SCHEMA)
    data["robot_path"] = str((Path(path).parent / data["robot"]).resolve())
    return data


# ------------------------------------------------------------------------- the routes
def route_problem(settings: dict[str, Any], k: int) -> dict[str, Any]:
    """Route k's problem mapping (seed ``seed + k``; even k pivot at every corner)."""
    from experiments.random_routes import random_route, user_ground

    rng = np.random.default_rng(settings["seed"] + k)
    r = settings["route"]
    turn = float(r["turn_max_deg"])
    route = random_route(rng, k % 2 == 0, tuple(r["waypoints"]), tuple(r["leg_m"]), turn,
                         (0.0, turn), tuple(r["speed_m_s"]))  # fmt: skip
    extent = route.waypoints.max(axis=0) - route.waypoints.min(axis=0)
    size = [float(np.ceil(e + 2 * r["margin_m"])) for e in extent]
    waypoints = np.round(route.waypoints, 3)
    return {
        "robot": settings["robot_path"],
        "terrain": user_ground(rng, waypoints, size, settings["ground"]),
        "path": {
            "waypoints": waypoints.tolist(),
            "speed": round(route.speed, 4),
            "turn_radius": round(route.turn_radius, 3),
        },  # fmt: skip
        **settings.get("problem", {}),
    }


def ground_record(data: dict[str, Any]) -> dict[str, Any]:
    """What was drawn: slope [deg], roughness, bump, the features."""
    g = data["terrain"]["generate"]
    f = g.get("features", {})
    return {
        "slope_deg": float(np.degrees(g["slope"])),
        "roughness_m": g["amplitude"],
        "hill_m": g["hill_height"],
        "ditch": f.get("ditch"),
        "kerb": f.get("kerb"),
        "bumps": f.get("bumps"),
        "waypoints": len(data["path"]["waypoints"]),
        "turn_radius_m": data["path"]["turn_radius"],
    }


def event_place(data: dict[str, Any], xy: Any) -> dict[str, float | None]:
    """How far the point ``xy`` (2,) [m] in M is from the map's ditch, kerb and corners [m].

    The ditch's distance is from its band (0 inside it), the kerb's from its edge, the
    corners' from the nearest interior waypoint; None where the map has no such feature.
    """
    p = np.asarray(xy, dtype=float)
    features = data["terrain"]["generate"].get("features", {})
    out: dict[str, float | None] = {}
    for name in ("ditch", "kerb"):
        f = features.get(name)
        if f is None:
            out[f"to_{name}_m"] = None
            continue
        along = p @ [np.cos(f["azimuth"]), np.sin(f["azimuth"])] - f["distance"]
        out[f"to_{name}_m"] = float(max(abs(along) - f.get("width", 0.0) / 2, 0.0))
    corners = np.asarray(data["path"]["waypoints"], dtype=float)[1:-1]
    out["to_corner_m"] = float(np.min(np.linalg.norm(corners - p, axis=1)))
    return out


def worst_window_turn(t: Any, heading: Any, window: float) -> float:
    """The most the heading turns within any ``window`` [s] of a run [rad].

    Args:
        t: sample times (N,) [s], evenly spaced.
        heading: the heading at each (N,) [rad] (unwrapped here).
        window: the slide verdict's window [s] (``physics.slip_window``).
    """
    h = np.unwrap(np.asarray(heading, dtype=float))
    if len(h) < 2:
        return 0.0
    w = max(int(round(window / float(t[1] - t[0]))), 1)
    if len(h) <= w:
        return float(np.ptp(h))
    return float(np.max(np.abs(h[w:] - h[:-w])))


def run_route(task: tuple[dict[str, Any], int, str]) -> dict[str, Any]:
    """Plan and simulate route k (the pool's job): its record."""
    settings, k, out = task
    from mmstab.app import plan as make_plan
    from mmstab.core.files import PlanningError
    from mmstab.core.problem import load_problem
    from mmstab.outputs.routes import route_summary
    from mmstab.outputs.simulate import loop_settings, simulate_run, summarize
    from mmstab.planner import RoutePlan, route_risk

    data = route_problem(settings, k)
    path = Path(out) / "problems" / f"route{k:02d}.yaml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump(data))
    problem = load_problem(path)
    assert problem.route is not None
    record: dict[str, Any] = {"route": k, "seed": settings["seed"] + k,
                              "problem": str(path.relative_to(out)),
                              "length_m": problem.route.length, **ground_record(data)}  # fmt: skip
    t0 = time.perf_counter()
    try:
        plan = make_plan(problem)
    except PlanningError as e:
        return record | {"plan": "no plan", "plan_exit": PLAN_VERDICTS["no plan"],
                         "plan_error": str(e), "mujoco": None}  # fmt: skip
    assert isinstance(plan, RoutePlan)  # a route's plan
    if settings.get("track", False):  # mmstab track's verdict on the same plan
        from mmstab.outputs.tracking import track_verdict

        record["track"] = track_verdict(problem, plan)
    problem = problem.following(plan)  # the route timed with its slowed turns
    margin = Settings.from_problem(problem).verdicts.margin
    s = route_summary(problem, plan, route_risk(plan, margin))
    verdict = plan_verdict_of(s)
    record |= {
        "plan": verdict,
        "plan_exit": PLAN_VERDICTS[verdict],
        "plan_seconds": time.perf_counter() - t0,
        "plan_mu_min": float(min(s["mu_planned"])),
        "plan_high_centred": bool(s["high_centred"]["high_centred"]),
        "plan_climb_stalls": [x for x in s["climb"]["steps"] if not x["planned_climbs"]] != [],
        # the arm in the ground on its reference at rest (a refusal of its own, after tip and slide)
        "plan_arm_in_ground": bool(s["along_path"]["arm_in_ground"]["contact"]),
        "plan_slides": s["risk"]["slides"],
    }
    loop = loop_settings(problem)
    t0 = time.perf_counter()
    run = simulate_run(problem, loop, plan)
    sim = summarize(run, loop)
    route = problem.route
    assert route is not None  # every problem here is a route
    outcome = outcome_of(sim)
    ok = np.isfinite(run.mu_simulated) & np.isfinite(run.mu_predicted)
    rel = np.abs(run.mu_simulated[ok] - run.mu_predicted[ok]) / np.abs(run.mu_predicted[ok])
    record |= {
        "mujoco": outcome,
        "sim_seconds": time.perf_counter() - t0,
        "simulated_s": sim["duration_s"],
        "route_duration_s": route.duration,
        "events": {key: sim[key] for key in EVENTS},
        "disagreement": sim["disagreement"],
        "tilt_off_rest_max_rad": sim["tilt_off_rest_max_rad"],
        "mu_predicted_median": float(np.median(run.mu_predicted[ok])) if ok.any() else None,
        "mu_simulated_median": float(np.median(run.mu_simulated[ok])) if ok.any() else None,
        "mu_relative_difference_median": float(np.median(rel)) if ok.any() else None,
        "mu_simulated_min": sim["mu_simulated_min"],
        "base_error_max_m": sim["base_error_max_m"],
        "base_origin_error_max_m": sim["base_origin_error_max_m"],
        "base_error_median_m": float(np.median(run.base_error)),
        "base_origin_error_median_m": None
        if run.base_origin_error is None
        else float(np.median(run.base_origin_error)),
        "downhill_drift_max_m": sim["downhill_drift_max_m"],
        # the heading's most in one slide window: MuJoCo's base and its reference (the
        # verdict prices a turn's slide at the path's rate)
        "turn_in_window_rad": {
            "mujoco": worst_window_turn(run.t, run.state[:, 2], loop.slip_window),
            "reference": None
            if run.heading_reference is None
            else worst_window_turn(run.t, run.heading_reference, loop.slip_window),
        },
        "arm_ground_contact": sim["arm_ground_contact"],
        "qp_failures": sim["qp_failures"],
    }
    if outcome != "holds":  # where the run failed: near the ditch, the kerb, the corner?
        t_event = min(
            e.get("time_s", e.get("first_time_s")) for e in record["events"].values() if e
        )
        k_event = min(int(np.searchsorted(run.t, t_event)), len(run.t) - 1)
        record["event_place"] = event_place(data, run.state[k_event, :2])
    if settings.get("runs_figures", True) and (verdict == "accepted") != (outcome == "holds"):
        from mmstab.outputs.simulate_figure import write_run_figure

        write_run_figure(Path(out) / "runs" / f"route{k:02d}.png", problem, run, loop)
        record["figure"] = f"runs/route{k:02d}.png"
    return record


# ------------------------------------------------------------------------- the summary
def confusion(records: list[dict[str, Any]]) -> dict[str, dict[str, int]]:
    """Plan's verdict x MuJoCo's outcome: route counts (``not simulated``: no plan)."""
    table = {v: dict.fromkeys([*OUTCOMES, "not simulated"], 0) for v in PLAN_VERDICTS}
    for r in records:
        table[r["plan"]][r["mujoco"] or "not simulated"] += 1
    return table


def _share(n: int, total: int) -> float | None:
    return n / total if total else None


def _stats(values: list[float | None]) -> dict[str, Any]:
    v = np.asarray([x for x in values if x is not None], dtype=float)
    if not v.size:
        return {"n": 0}
    return {"n": int(v.size), "min": float(v.min()), "median": float(np.median(v)),
            "p90": float(np.percentile(v, 90)), "max": float(v.max())}  # fmt: skip


def _off_path(record: dict[str, Any], tracking_m: float) -> bool:
    """The body origin's largest error beyond ``tracking_m`` [m]."""
    return (record["base_origin_error_max_m"] or 0.0) > tracking_m


def bars(records: list[dict[str, Any]], b: dict[str, Any]) -> dict[str, Any]:
    """The acceptance bars, each with its numbers and whether it holds.

    A refused route fails when forced if MuJoCo's outcome is an event (tips, slides, stalls,
    touches the ground, leaves the map) or if it holds but its body origin ends up farther
    than the accepted routes' tracking bar from its reference (``off_path``): either way an
    accepted route would have broken a bar. ``share_events`` counts the events alone.
    ``accepted_on_slopes.drivable``: the routes up to the slope limit that MuJoCo holds on
    their path (no event, within the tracking bar), the most a verdict could accept there
    without an unsafe miss.
    """
    accepted = [r for r in records if r["plan"] == "accepted"]
    refused = [r for r in records if r["plan"] != "accepted" and r["mujoco"] is not None]
    fail_acc = [r["route"] for r in accepted if r["mujoco"] != "holds"]
    fail_ref = [r for r in refused if r["mujoco"] != "holds"]
    # a forced route MuJoCo drives without an event but tracks worse than an accepted route
    # may be: accepting it would break the tracking bar, so the refusal stands
    off_path = [r for r in refused if r["mujoco"] == "holds" and _off_path(r, b["tracking_m"])]
    slope = [r for r in records if r["slope_deg"] <= b["slope_limit_deg"]]
    slope_acc = [r for r in slope if r["plan"] == "accepted"]
    # the most any verdict could accept there without a miss: MuJoCo holds them on the path
    drivable = [r for r in slope if r["mujoco"] == "holds" and not _off_path(r, b["tracking_m"])]
    held = [r for r in accepted if r["mujoco"] == "holds"]
    origin = [r for r in held if _off_path(r, b["tracking_m"])]
    mu = [r for r in accepted if (r["mu_relative_difference_median"] or 0.0) > b["mu_relative"]]
    # the other reading of "within 5 % (median per route)": the route's median mu simulated
    # against its median predicted (the checks' differences of either sign cancel there)
    medians = [(r.get("mu_predicted_median"), r.get("mu_simulated_median")) for r in accepted]
    of_medians = [abs(s - p) / abs(p) for p, s in medians if p and s is not None]
    out = {
        "accepted_never_fail": {"accepted": len(accepted), "fail_in_mujoco": len(fail_acc),
                                "routes": fail_acc},
        "refused_fail_when_forced": {"refused": len(refused), "fail_in_mujoco": len(fail_ref),
                                     "off_path": [r["route"] for r in off_path],
                                     "share": _share(len(fail_ref) + len(off_path), len(refused)),
                                     "share_events": _share(len(fail_ref), len(refused)),
                                     "bar": b["refused_fail_share"]},
        "accepted_on_slopes": {"slope_limit_deg": b["slope_limit_deg"], "routes": len(slope),
                               "accepted": len(slope_acc),
                               "share": _share(len(slope_acc), len(slope)),
                               "drivable": len(drivable),
                               "drivable_share": _share(len(drivable), len(slope)),
                               "bar": b["accepted_share"]},
        "tracking_body_origin": {"bar_m": b["tracking_m"], "routes": len(held),
                                 "over": [r["route"] for r in origin]},
        "mu_median_relative": {"bar": b["mu_relative"], "routes": len(accepted),
                               "over": [r["route"] for r in mu],
                               "of_medians_max": max(of_medians) if of_medians else None},
    }  # fmt: skip
    out["accepted_never_fail"]["holds"] = not fail_acc
    r, s = out["refused_fail_when_forced"], out["accepted_on_slopes"]
    r["holds"] = r["share"] is not None and r["share"] >= r["bar"]
    s["holds"] = s["share"] is not None and s["share"] >= s["bar"]
    out["tracking_body_origin"]["holds"] = bool(held) and not origin
    out["mu_median_relative"]["holds"] = bool(accepted) and not mu
    return out


def _turn_ratio(record: dict[str, Any]) -> float | None:
    """MuJoCo's most turn in a slide window over its reference's (None: under 0.1 rad)."""
    turn = record.get("turn_in_window_rad") or {}
    ref = turn.get("reference")
    return None if ref is None or ref < 0.1 else float(turn["mujoco"] / ref)


def summarize_routes(
    settings: dict[str, Any], records: list[dict[str, Any]], seconds: float
) -> dict[str, Any]:
    """The JSON written as ``summary.json``."""
    sim = [r for r in records if r["mujoco"] is not None]
    accepted = [r for r in sim if r["plan"] == "accepted"]
    return {
        "routes": len(records),
        "confusion": confusion(records),
        "plan_verdicts": {v: sum(r["plan"] == v for r in records) for v in PLAN_VERDICTS},
        "mujoco_outcomes": {o: sum(r["mujoco"] == o for r in records) for o in OUTCOMES},
        "plan_exit_statuses": PLAN_VERDICTS,
        "mu_relative_difference_median": {
            "all": _stats([r["mu_relative_difference_median"] for r in sim]),
            "accepted": _stats([r["mu_relative_difference_median"] for r in accepted]),
        },
        "tracking_accepted": {
            key: _stats([r[key] for r in accepted])
            for key in (
                "base_origin_error_max_m",
                "base_error_max_m",
                "base_origin_error_median_m",
                "base_error_median_m",
            )
        },  # fmt: skip
        # MuJoCo's most turn in a slide window over its reference's, by MuJoCo's outcome
        # (routes whose reference turns 0.1 rad or more in a window)
        "turn_in_window_ratio": {
            o: _stats([_turn_ratio(r) for r in sim if r["mujoco"] == o])
            for o in ("holds", "slides")
        },
        "disagreements": sum(r.get("disagreement") is not None for r in sim),
        "tip_causes": {
            c: sum((r["events"]["tipped"] or {}).get("cause") == c for r in sim)
            for c in ("support lost", "overturned")
        },  # fmt: skip
        # routes whose arm touches the ground in MuJoCo, and those whose plan has it there
        "arm_ground_contact": {
            "mujoco": [r["route"] for r in sim if r["events"]["arm_ground_contact"] is not None],
            "plan": [r["route"] for r in records if r.get("plan_arm_in_ground")],
        },
        "bars": bars(records, settings["bars"]),
        **({"track": track_agreement(records)} if settings.get("track", False) else {}),
        "seconds": seconds,
        "settings": {k: v for k, v in settings.items() if k != "robot_path"},
        "records": records,
    }


def track_agreement(records: list[dict[str, Any]]) -> dict[str, Any]:
    """``mmstab track``'s verdicts against the plan's and MuJoCo's (routes with a plan).

    ``disagrees``: each route where track's verdict is not the plan's, with MuJoCo's outcome.
    """
    from mmstab.outputs.tracking import TRACK_VERDICTS

    both = [r for r in records if "track" in r]
    return {
        "routes": len(both),
        "verdicts": {v: sum(r["track"] == v for r in both) for v in TRACK_VERDICTS},
        "agrees_with_plan": sum(r["track"] == r["plan"] for r in both),
        "tips_where_mujoco_tips": sum(r["track"] == "tips" and r["mujoco"] == "tips" for r in both),
        "disagrees": [{"route": r["route"], "plan": r["plan"], "track": r["track"],
                       "mujoco": r["mujoco"]} for r in both if r["track"] != r["plan"]],
    }  # fmt: skip


def run_routes(
    settings: dict[str, Any], out: str | Path, indices: list[int] | None = None
) -> dict[str, Any]:
    """Plan and simulate the routes (all, or ``indices``), write the summary and figure."""
    from experiments.validate_routes_figure import draw
    from mmstab.core.problem import load_problem
    from mmstab.workspace import load_or_build_workspace

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    indices = list(range(settings["routes"])) if indices is None else indices
    t0 = time.perf_counter()
    first = out / "problems" / f"route{indices[0]:02d}.yaml"  # the workspace, built once
    first.parent.mkdir(parents=True, exist_ok=True)
    first.write_text(yaml.safe_dump(route_problem(settings, indices[0])))
    load_or_build_workspace(load_problem(first), progress=False)
    tasks = [(settings, k, str(out)) for k in indices]
    if settings["workers"] == 1 or len(tasks) == 1:
        records = [run_route(t) for t in tasks]
    else:
        ctx = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(settings["workers"], mp_context=ctx) as pool:
            records = []
            for r in pool.map(run_route, tasks):
                records.append(r)
                print(f"route {r['route']:2d}: slope {r['slope_deg']:4.1f} deg "
                      f"{'ditch ' if r['ditch'] else ''}{'kerb ' if r['kerb'] else ''}"
                      f"plan {r['plan']}, "
                      f"{'track ' + r['track'] + ', ' if 'track' in r else ''}"
                      f"MuJoCo {r['mujoco']}", flush=True)  # fmt: skip
    summary = summarize_routes(settings, records, time.perf_counter() - t0)
    drawn = {str(out / r["figure"]) for r in records if r.get("figure")}
    for old in (out / "runs").glob("route*.png"):  # an earlier run's, of a route run again
        if str(old) not in drawn and int(old.stem[5:]) in indices:
            old.unlink()
    write_json(out / "summary.json", summary)
    write_figure(out / "validate_routes.png", draw(summary))
    return summary


def main(argv: list[str] | None = None) -> int:
    """``python -m experiments.validate_routes [SETTINGS] [-o DIR]``; exit status."""
    got = experiment_run(
        argv,
        __doc__,
        "problems/validate_routes.yaml",
        "results/validate_routes",
        run_routes,
        load_settings,
    )
    if isinstance(got, int):
        return got
    s, out = got
    for name, bar in s["bars"].items():
        print(f"{name}: {'holds' if bar['holds'] else 'FAILS'}: "
              f"{ {k: v for k, v in bar.items() if k != 'holds'} }")  # fmt: skip
    print(f"-> {out}/summary.json, validate_routes.png ({s['seconds']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
