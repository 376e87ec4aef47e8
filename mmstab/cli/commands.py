"""The problem commands of ``mmstab``: their handlers and default outputs.

Their options are :mod:`mmstab.cli.options`'s, their exit-status verdicts
:mod:`mmstab.cli.verdicts`'s (both re-exported here).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from mmstab.cli.options import EXTRA_OPTIONS
from mmstab.cli.verdicts import (
    arm_collision_status,
    high_centred_warning,
    limits_line,
    plan_contact_status,
    plan_status,
    slides_status,
    timing_line,
    tipped_status,
    turn_slide_line,
    verify_status,
)

#: Default output folder of each command (``-o`` overrides it).
DEFAULT_OUT = {
    "plan": "results/plan",
    "fig7": "results/fig7",
    "fig8": "results/fig8",
    "track": "results/tracking",
    "animation": "results/tracking",
}
#: Commands that load or build the workspace (its cache folder must be writable to build).
USES_WORKSPACE = {
    "workspace",
    "plan",
    "fig7",
    "fig8",
    "track",
    "animation",
}
#: Commands that run the planner (``--allow-unstable``).
PLANS = ("plan", "fig7", "fig8", "track", "animation")

Handler = Callable[[argparse.Namespace, Any], int | None]

__all__ = [
    "COMMANDS",
    "DEFAULT_OUT",
    "EXTRA_OPTIONS",
    "PLANS",
    "PROBLEM_COMMANDS",
    "USES_WORKSPACE",
    "Handler",
    "_arm_collision",
    "arm_collision_status",
    "plan_status",
    "slides_status",
    "tipped_status",
]

_arm_collision = arm_collision_status  # its former name


def _problem(args: argparse.Namespace, sections: tuple[str, ...] | None = None) -> Any:
    """The problem of a command outside :data:`COMMANDS` (checked at load, as everywhere).

    ``sections``: the sections the command uses (None: all): the checks and size bounds of
    the others are skipped (:func:`mmstab.core.problem.problem_from_dict`).
    """
    from mmstab.core.problem import load_problem

    force = getattr(args, "force_size", False)
    return load_problem(args.problem, force_size=force, sections=sections)


def _announce(problem: Any, *sections: str, duration: float | None = None) -> None:
    """Show the time estimates of long stages before they start.

    The tracking run's is for the time it will simulate: ``--duration`` if given, else the
    route's driving time on a route, else ``controller.duration`` (``Problem.size_estimates``).
    """
    from mmstab.core.sizes import announce

    found = problem.size_estimates(duration)
    for name in sections:
        announce(found[name])


def _workspace(args: argparse.Namespace, problem: Any) -> None:
    from mmstab.app import workspace
    from mmstab.workspace import workspace_cache_path

    path = workspace_cache_path(problem, args.out)
    before = path.stat().st_mtime_ns if path.is_file() else None
    ws = workspace(problem, force=args.force, cache_dir=args.out)
    how = "loaded" if path.stat().st_mtime_ns == before else "built"
    print(
        f"workspace: {ws.postures} postures{ws.how_sampled}, {len(ws.valid_com)} valid, "
        f"{len(ws.invalid_com)} invalid, diameter {ws.diameter:.3f} m "
        f"(build {ws.build_seconds:.1f} s); {how}: {path}"
    )


def _track(args: argparse.Namespace, problem: Any) -> int | None:
    from mmstab.outputs.tracking import run_tracking

    _announce(problem, "planner", "controller", duration=args.duration)
    s = run_tracking(
        problem,
        args.out,
        args.plugin,
        backend=args.backend,
        duration=args.duration,
        allow_unstable=args.allow_unstable,
    )
    print(
        f"track: {s['steps']} steps ({s['plugin']}, {s['backend']}) in {s['wall_seconds']:.2f} s "
        f"({s['us_per_step']:.1f} us/step); max error base {s['base_error_max_m']:.3g} m, "
        f"arm CoM {s['arm_com_error_max_m']:.3g} m; final {s['base_error_final_m']:.2g} m, "
        f"{s['arm_com_error_final_m']:.2g} m; QP failures {s['qp_failures']}; arm self-collision "
        f"{100 * s['arm_self_collision']['colliding_share']:.1f} % of the samples, minimum "
        f"clearance {s['arm_self_collision']['min_clearance_m']:.4f} m; posture "
        f"reference: {len(s['posture_reference']['via_postures'])} via postures, colliding "
        f"samples {s['posture_reference']['reference']['colliding_samples']}"
    )
    timing_line("track", s.get("arm_timing"))
    return tipped_status(s) or slides_status(s, args) or arm_collision_status(s, args)


def _urdf(args: argparse.Namespace, problem: Any) -> None:
    from mmstab.model.robot import load_robot
    from mmstab.model.urdf import write_urdf

    robot = load_robot(args.robot)
    print(f"urdf: wrote {write_urdf(robot, _urdf_out(args, robot.name))}")


def arm_from_urdf(args: argparse.Namespace) -> int:
    """``mmstab arm-from-urdf``: the arm section as YAML, to a file or stdout; notes on stderr."""
    import math

    import numpy as np
    import yaml

    from mmstab.core.files import MmstabError, check_output_dir, refuse_degrees, write_text
    from mmstab.model.robot import homogeneous, rpy_matrix
    from mmstab.model.urdf_arm import arm_section, build_arm

    mount = None
    if args.mount is not None:
        if not all(math.isfinite(v) for v in args.mount):
            raise MmstabError(
                "--mount: give six finite numbers (x, y, z [m], roll, pitch, yaw [rad])"
            )
        for name, angle in zip(("roll", "pitch", "yaw"), args.mount[3:], strict=True):
            refuse_degrees(f"--mount: {name}", angle)
        mount = homogeneous(rpy_matrix(np.array(args.mount[3:])), np.array(args.mount[:3]))
    if args.out is not None:
        if Path(args.out).is_dir():
            raise MmstabError(f"output file {args.out}: is a folder")
        check_output_dir(Path(args.out).parent, f"output file {args.out}: folder")
    arm = build_arm(args.urdf, args.base, args.tip, args.package_dir)
    header = (
        f"# The arm of {args.urdf} from link {arm.base} to link {arm.tip}, written by\n"
        "# mmstab arm-from-urdf: the robot file's arm: section (docs/robot.md). Check the\n"
        "# mount (the base link's place on the body) and the stowed posture.\n"
    )
    section = {"arm": arm_section(arm, mount)}
    text = header + yaml.safe_dump(section, sort_keys=False, default_flow_style=None)
    for note in arm.notes:
        print(f"mmstab: note: {args.urdf}: {note}", file=sys.stderr)
    if args.out is None:
        sys.stdout.write(text)
    else:
        print(f"arm-from-urdf: {len(arm.rows)} joints -> {write_text(args.out, text)}")
    return 0


def _urdf_out(args: argparse.Namespace, name: str) -> str:
    return str(args.out) if args.out is not None else f"results/urdf/{name}.urdf"


def _plan(args: argparse.Namespace, problem: Any) -> int | None:
    from mmstab.outputs.planning import run_fig8

    if problem.route is not None:
        return _plan_route(args, problem)
    _announce(problem, "planner")
    s = run_fig8(problem, args.out or DEFAULT_OUT["plan"])
    for k, p in enumerate(s["poses"]):
        print(
            f"pose {k}: side {p['side']:5s} mu {p['mu_planned']:7.1f} "
            f"(stowed {p['mu_stowed']:7.1f}, arm removed {p['mu_arm_removed']:7.1f}) "
            f"CoM error {p['realised_com_error_m'] * 1e3:.2f} mm "
            f"{'collision-free' if p['collision_free'] else 'COLLIDES'}"
        )
    limits_line("plan", s["verdicts"], s["along_path"]["spacing_m"])
    lap = problem.circle.length
    _climb_line(s["climb"], [p["fraction"] * lap for p in s["poses"]], lap)
    high_centred_warning(s["high_centred"])
    return plan_status(s, args) or slides_status(s, args) or plan_contact_status(s, args)


def _plan_route(args: argparse.Namespace, problem: Any) -> int | None:
    from mmstab.outputs.routes import run_route_plan

    s = run_route_plan(problem, args.out or DEFAULT_OUT["plan"], verify=args.verify)
    r = s["risk"]

    def spans(key: str) -> str:
        found = [f"{x['start_s']:.1f}-{x['end_s']:.1f} m" for x in r[key]]
        return ", ".join(found) or "none"

    print(
        f"plan: route {s['route']['length_m']:.2f} m, {len(s['s'])} poses, "
        f"{_pose_times(s)}; "
        f"at the planned poses mu planned min {min(s['mu_planned']):.1f}, stowed min "
        f"{min(s['mu_stowed']):.1f}, arm removed min {min(s['mu_removed']):.1f} N rad; "
        f"stowed below the margin {r['margin']:g} where the planned arm is not: "
        f"{spans('saved_by_planning')}"
    )
    for line in s["route"]["slowed_turns"]:  # the turns slowed so that they do not slide
        print(f"plan: {line}")
    limits_line("plan", s["verdicts"], s["along_path"]["spacing_m"])
    turn_slide_line("plan", s.get("turn_slide"))
    _climb_line(s["climb"], s["s"])
    high_centred_warning(s["high_centred"])
    status = plan_status(s, args) or slides_status(s, args) or plan_contact_status(s, args)
    return verify_status(s.get("verify"), status)


def _pose_times(s: dict[str, Any]) -> str:
    """The plan's time per pose, warm-started or the whole search's share, and fixed costs."""
    fixed = f", fixed costs {s['fixed_seconds']:.2f} s (caches, once per process)"
    if s["warm_started"]:
        return (
            f"{s['ms_per_pose']:.1f} ms per warm-started pose (median; the first, cold, "
            f"{s['ms_first_pose']:.1f} ms){fixed}"
        )
    return f"{s['ms_per_pose']:.1f} ms per pose (the whole-route search / poses){fixed}"


def _climb_line(climb: dict[str, Any], s: list[float], lap: float | None = None) -> None:
    """The climb limit's verdict on the path's steps (docs/climbing.md, "The climb limit").

    One entry per step, where the front wheels meet it (the poses before and after it both
    keep its limit, so the summary lists it twice). ``lap``: a lap's length [m]: a step met
    past its end is met that far into the next lap.
    """
    steps: dict[int, list[dict[str, Any]]] = {}
    for x in climb["steps"]:
        steps.setdefault(x["met_from"], []).append(x)
    if not steps:
        return

    def at(k: int) -> float:
        x = s[k] + steps[k][0]["met_after_m"]
        return x % lap if lap else x

    def met(k: int) -> str:
        return f"{at(k):.2f} m"

    steps = dict(sorted(steps.items(), key=lambda kv: at(kv[0])))  # in path order
    where = ", ".join(f"{met(k)} ({100 * xs[0]['height']:.0f} cm)" for k, xs in steps.items())
    stalls = [met(k) for k, xs in steps.items() if not all(x["planned_climbs"] for x in xs)]
    verdict = (
        "the planned arm climbs them all"
        if not stalls
        else f"the planned arm may stall at {', '.join(stalls)} (it needs momentum there)"
    )
    stowed = "stalls" if climb["stowed_stalls"] else "climbs"
    print(f"plan: steps met at s = {where}: {verdict}; the stowed arm {stowed} (quasi-static)")


def _fig7(args: argparse.Namespace, problem: Any) -> int | None:
    from mmstab.outputs.planning import run_fig7

    s = run_fig7(problem, args.out)
    com = [round(float(x), 3) for x in s["target_com"]]
    print(f"fig7: target arm CoM {com} m, mu {s['mu_planned']:.1f} N rad")
    return plan_status(s, args)


def _fig8(args: argparse.Namespace, problem: Any) -> int | None:
    from mmstab.outputs.planning import run_fig8

    _announce(problem, "planner")
    s = run_fig8(problem, args.out)
    print(f"fig8: arm side per pose {s['sides']}")
    return plan_status(s, args) or slides_status(s, args) or plan_contact_status(s, args)


def _codegen(args: argparse.Namespace, problem: Any) -> None:
    from mmstab.codegen import build_programs, generate

    gen = generate(problem, args.out, args.plugin, force=args.force, native=args.native)
    how = "generated and compiled" if gen.rebuilt else "up to date"
    print(f"codegen: {gen.plugin}: {how}: {gen.source}, {gen.header}, {gen.library}")
    if args.example:
        from mmstab.app import plan as plan_of
        from mmstab.control.reference import initial_state
        from mmstab.runs import rollout as ro

        plan = plan_of(problem)  # the problem's path with the planned arm CoMs
        state0 = initial_state(problem.circle, problem.robot.stowed, lateral_offset=0.05)
        inputs = ro.run_inputs(problem, plan, state0=state0)
        run = ro.write_run_file(ro.run_file_path(gen.directory), inputs)
        progs = build_programs(gen)
        print(f"codegen: example {progs.loop} and timing {progs.bench}; run file {run}")


def _animation(args: argparse.Namespace, problem: Any) -> int | None:
    from mmstab.outputs.animation import run_animation

    stored = (Path(args.out or DEFAULT_OUT["animation"]) / "run.npz").is_file()
    _announce(problem, *(("animation",) if stored else ("planner", "controller", "animation")))
    s = run_animation(problem, args.out, allow_unstable=args.allow_unstable)
    print(f"animation: {s['frames']} frames -> {s['gif']}")
    # the rendered run's verdicts, judged as ``track`` judged it
    return tipped_status(s) or slides_status(s, args) or arm_collision_status(s, args)


# (name, help, handler)
COMMANDS: list[tuple[str, str, Handler]] = [
    ("workspace", "build (or load the cached) arm-CoM workspace V", _workspace),
    ("plan", "plan the arm CoM along the path (circle or route) and the postures", _plan),
    ("fig7", "paper Fig. 7: CMA-ES samples and the converged CoM at the rolled pose", _fig7),
    ("fig8", "paper Fig. 8: planned configurations along the circle on the ramp", _fig8),
    ("track", "paper Fig. 9-12: track the path and the planned arm CoM (one run)", _track),
    ("codegen", "the controller step as C + a compiled library (-o DIR)", _codegen),
    ("animation", "the tracking run as a GIF (results/tracking/animation.gif)", _animation),
]

#: Commands of :data:`COMMANDS`: handlers of (args, the problem loaded and checked).
PROBLEM_COMMANDS = frozenset(name for name, _, _ in COMMANDS)
