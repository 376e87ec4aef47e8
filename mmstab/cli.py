"""The ``mmstab`` command line: one subcommand per pipeline stage or experiment.

Every subcommand takes a problem (or robot) YAML file. Before any work, every command loads
and checks the whole problem (schema, the settings registry of :mod:`mmstab.settings`, the
size bounds of :mod:`mmstab.sizes`), its options and that its output folders can be written.

Exit statuses (``docs/cli.md``): 0 done; 2 bad input (one line ``mmstab: error: ...``,
nothing written); 3 unstable (the best plan has a pose at or below the stability margin, or
the tracked robot tips over; ``--allow-unstable`` accepts an unstable plan); 130
interrupted (Ctrl-C: workers stopped, no file half-written).
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

#: Exit statuses.
EXIT_OK, EXIT_BAD_INPUT, EXIT_UNSTABLE, EXIT_INTERRUPTED = 0, 2, 3, 130

#: Default output folder of each command (``-o`` overrides it).
DEFAULT_OUT = {
    "fig5": "results/fig5",
    "fig6": "results/fig6",
    "fig3": "results/fig3",
    "plan": "results/plan",
    "fig7": "results/fig7",
    "fig8": "results/fig8",
    "track": "results/tracking",
    "animation": "results/tracking",
    "fidelity": "results/fidelity",
}
#: Commands that load or build the workspace (its cache folder must be writable to build).
USES_WORKSPACE = {"workspace", "fig3", "plan", "fig7", "fig8", "track", "animation"}
#: Commands that run the planner (``--allow-unstable``).
PLANS = ("plan", "fig7", "fig8", "track", "animation")

Handler = Callable[[argparse.Namespace, Any], int | None]


def _problem(args: argparse.Namespace) -> Any:
    """The problem of a command outside :data:`COMMANDS` (checked at load, as everywhere)."""
    from mmstab.problem import load_problem

    return load_problem(args.problem, force_size=getattr(args, "force_size", False))


def _announce(problem: Any, *sections: str, duration: float | None = None) -> None:
    """Show the time estimates of long stages before they start (``--duration`` if given)."""
    from mmstab.sizes import announce, estimates, steps_estimate

    found = estimates(problem.data)
    if duration is not None:
        dt = problem.section("controller")["dt"]
        found["controller"] = steps_estimate("--duration", duration, dt)
    for name in sections:
        announce(found[name])


def _fig5(args: argparse.Namespace, problem: Any) -> None:
    from mmstab.experiments.sweeps import run_fig5

    s = run_fig5(problem, args.out)
    maxima = [round(float(x), 2) for x in s["local_maxima_rad"]]
    print(f"fig5: local maxima at link0 = {maxima} rad")


def _fig6(args: argparse.Namespace, problem: Any) -> None:
    from mmstab.experiments.sweeps import run_fig6

    _announce(problem, "sweep")
    s = run_fig6(problem, args.out)
    print(f"fig6: {s['poses_with_two_maxima']} of {len(s['poses'])} poses with two maxima")


def _workspace(args: argparse.Namespace, problem: Any) -> None:
    from mmstab.app import workspace
    from mmstab.workspace import workspace_cache_path

    path = workspace_cache_path(problem, args.out)
    before = path.stat().st_mtime_ns if path.is_file() else None
    ws = workspace(problem, force=args.force, cache_dir=args.out)
    how = "loaded" if path.stat().st_mtime_ns == before else "built"
    print(
        f"workspace: {ws.postures} postures, {len(ws.valid_com)} valid, "
        f"{len(ws.invalid_com)} invalid, diameter {ws.diameter:.3f} m "
        f"(build {ws.build_seconds:.1f} s); {how}: {path}"
    )


def _fig3(args: argparse.Namespace, problem: Any) -> None:
    from mmstab.experiments.fig3 import run_fig3

    _announce(problem, "precision")
    s = run_fig3(problem, args.out, force=args.force)
    print(
        f"fig3: {s['valid']} valid / {s['invalid']} invalid, volume V {s['volume_V']:.4f} m^3, "
        f"recall {s['recall']:.3f}, precision {s['precision']:.3f}"
    )


def _tipped(summary: dict[str, Any]) -> int | None:
    from mmstab.verdict import describe_tipping

    if summary.get("tipped") is None:
        return None
    print(f"mmstab: unstable: {describe_tipping(summary['tipped'])}", file=sys.stderr)
    return EXIT_UNSTABLE


def _track(args: argparse.Namespace, problem: Any) -> int | None:
    from mmstab.experiments.tracking import run_tracking

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
        f"{100 * s['arm_self_collision']['colliding_share']:.1f} % of the samples; posture "
        f"reference: {len(s['posture_reference']['via_postures'])} via postures, colliding "
        f"samples {s['posture_reference']['reference']['colliding_samples']}"
    )
    return _tipped(s)


def _urdf(args: argparse.Namespace, problem: Any) -> None:
    from mmstab.robot import load_robot
    from mmstab.urdf import write_urdf

    robot = load_robot(args.robot)
    print(f"urdf: wrote {write_urdf(robot, _urdf_out(args, robot.name))}")


def _urdf_out(args: argparse.Namespace, name: str) -> str:
    return str(args.out) if args.out is not None else f"results/urdf/{name}.urdf"


def _plan_verdict(s: dict[str, Any], args: argparse.Namespace) -> int | None:
    """Report an unstable plan on stderr; exit status 3 unless ``--allow-unstable``."""
    from mmstab.verdict import describe_plan_verdict

    verdict = s["stability"]
    if verdict["stable"]:
        return None
    total = len(s["poses"]) if isinstance(s.get("poses"), list) else 1
    line = describe_plan_verdict(verdict, total)
    if args.allow_unstable:
        print(f"mmstab: warning: {line} (--allow-unstable)", file=sys.stderr)
        return None
    print(f"mmstab: unstable: {line}; pass --allow-unstable to accept it", file=sys.stderr)
    return EXIT_UNSTABLE


def _plan(args: argparse.Namespace, problem: Any) -> int | None:
    from mmstab.experiments.planning import run_fig8

    _announce(problem, "planner")
    s = run_fig8(problem, args.out or DEFAULT_OUT["plan"])
    for k, p in enumerate(s["poses"]):
        print(
            f"pose {k}: side {p['side']:5s} mu {p['mu_planned']:7.1f} "
            f"(stowed {p['mu_stowed']:7.1f}, arm removed {p['mu_arm_removed']:7.1f}) "
            f"CoM error {p['realised_com_error_m'] * 1e3:.2f} mm "
            f"{'collision-free' if p['collision_free'] else 'COLLIDES'}"
        )
    return _plan_verdict(s, args)


def _fig7(args: argparse.Namespace, problem: Any) -> int | None:
    from mmstab.experiments.planning import run_fig7

    s = run_fig7(problem, args.out)
    com = [round(float(x), 3) for x in s["target_com"]]
    print(f"fig7: target arm CoM {com} m, mu {s['mu_planned']:.1f} N rad")
    return _plan_verdict(s, args)


def _fig8(args: argparse.Namespace, problem: Any) -> int | None:
    from mmstab.experiments.planning import run_fig8

    _announce(problem, "planner")
    s = run_fig8(problem, args.out)
    print(f"fig8: arm side per pose {s['sides']}")
    return _plan_verdict(s, args)


def _fidelity(args: argparse.Namespace, problem: Any) -> None:
    from mmstab.experiments.fidelity import run_fidelity

    s = run_fidelity(problem, args.out, args.results)
    f6, f8, f11, f12 = s["fig6"], s["fig8"], s["fig11"], s["fig12"]
    below = ", ".join(f"{i['start_s']:.2f}-{i['end_s']:.2f} s" for i in f12["below_stowed"])
    print(
        f"fidelity: fig6 {f6['poses_with_two_maxima']}/{f6['poses']} sweeps with two maxima; "
        f"fig8 sides {f8['sides']}; fig11 saturates: {f11['saturates']}; "
        f"fig12 below the stowed arm: {below or 'never'}"
    )


def _codegen(args: argparse.Namespace, problem: Any) -> None:
    from mmstab.codegen import build_programs, generate

    gen = generate(problem, args.out, args.plugin, force=args.force)
    how = "generated and compiled" if gen.rebuilt else "up to date"
    print(f"codegen: {gen.plugin}: {how}: {gen.source}, {gen.header}, {gen.library}")
    if args.example:
        from mmstab import rollout as ro
        from mmstab.app import plan as plan_of
        from mmstab.reference import initial_state

        plan = plan_of(problem)  # the problem's path with the planned arm CoMs
        state0 = initial_state(problem.circle, problem.robot.stowed, lateral_offset=0.05)
        inputs = ro.run_inputs(problem, plan, state0=state0)
        run = ro.write_run_file(ro.run_file_path(gen.directory), inputs)
        progs = build_programs(gen)
        print(f"codegen: example {progs.loop} and timing {progs.bench}; run file {run}")


def _animation(args: argparse.Namespace, problem: Any) -> int | None:
    from mmstab.experiments.animation import run_animation

    stored = (Path(args.out or DEFAULT_OUT["animation"]) / "run.npz").is_file()
    _announce(problem, *(("animation",) if stored else ("planner", "controller", "animation")))
    s = run_animation(problem, args.out, allow_unstable=args.allow_unstable)
    print(f"animation: {s['frames']} frames -> {s['gif']}")
    return _tipped(s)


# (name, help, handler)
COMMANDS: list[tuple[str, str, Handler]] = [
    ("fig5", "paper Fig. 5: stability over a link0 sweep at one rolled pose", _fig5),
    ("fig6", "paper Fig. 6: link0 sweeps at poses along the circle", _fig6),
    ("workspace", "build (or load the cached) arm-CoM workspace V", _workspace),
    ("fig3", "paper Fig. 3: workspace V, hull of invalid CoMs, hull of all CoMs", _fig3),
    ("plan", "plan the arm CoM along the circle (CMA-ES) and the postures realising it", _plan),
    ("fig7", "paper Fig. 7: CMA-ES samples and the converged CoM at the rolled pose", _fig7),
    ("fig8", "paper Fig. 8: planned configurations along the circle on the ramp", _fig8),
    ("track", "paper Fig. 9-12: track the circle and the planned arm CoM (one run)", _track),
    ("codegen", "the controller step as C + a compiled library (-o DIR)", _codegen),
    ("animation", "the tracking run as a GIF (results/tracking/animation.gif)", _animation),
    ("fidelity", "paper claims vs the saved results of fig6, fig8, tracking", _fidelity),
]

_ALLOW_UNSTABLE = (
    "--allow-unstable",
    {
        "action": "store_true",
        "help": "accept a plan with poses at or below the stability margin (exit 0, warning)",
    },
)

#: Commands of :data:`COMMANDS`: handlers of (args, the problem loaded and checked).
PROBLEM_COMMANDS = frozenset(name for name, _, _ in COMMANDS)

#: Options beyond ``problem``, ``--out`` and ``--force-size``, by command name.
EXTRA_OPTIONS: dict[str, list[tuple[str, dict[str, Any]]]] = {
    "workspace": [("--force", {"action": "store_true", "help": "rebuild even if cached"})],
    "fig3": [("--force", {"action": "store_true", "help": "rebuild the workspace"})],
    "plan": [_ALLOW_UNSTABLE],
    "fig7": [_ALLOW_UNSTABLE],
    "fig8": [_ALLOW_UNSTABLE],
    "animation": [_ALLOW_UNSTABLE],
    "track": [
        (
            "--plugin",
            {"help": "QP plugin: qpoases, osqp, qrqp or daqp (default: the problem's)"},
        ),
        (
            "--backend",
            {
                "choices": ("interpreted", "generated"),
                "default": "interpreted",
                "help": "controller step: CasADi interpreted, or the generated C library",
            },
        ),
        ("--duration", {"type": float, "help": "simulated time [s] (default: the problem's)"}),
        _ALLOW_UNSTABLE,
    ],
    "fidelity": [
        ("--results", {"default": "results", "help": "where fig6/, fig8/, tracking/ are"})
    ],
    "codegen": [
        (
            "--plugin",
            {"default": None, "help": "QP plugin: qrqp, daqp or osqp (default codegen.plugin)"},
        ),
        ("--force", {"action": "store_true", "help": "regenerate even if up to date"}),
        (
            "--example",
            {"action": "store_true", "help": "also build the embedded example (embedded/)"},
        ),
    ],
}


# ------------------------------------------------- terrain (issue 14): rest, maps, export
def _arm_posture(robot: Any, arm: list[str] | None) -> Any:
    """``--arm``: ``stowed`` (or absent) -> None; four angles [rad] within the joint limits."""
    import numpy as np

    from mmstab.config import MmstabError

    if arm is None or arm == ["stowed"]:
        return None
    try:
        q = np.array([float(a) for a in arm])
    except ValueError:
        raise MmstabError(f"--arm: expected 'stowed' or 4 angles [rad], got {arm}") from None
    if q.shape != (4,) or not np.isfinite(q).all():
        raise MmstabError(f"--arm: expected 'stowed' or 4 finite angles [rad], got {arm}")
    bad = np.flatnonzero((q < robot.joint_lower) | (q > robot.joint_upper))
    if bad.size:
        i = int(bad[0])
        raise MmstabError(
            f"--arm: joint {i} = {q[i]} rad is outside its limits "
            f"[{robot.joint_lower[i]}, {robot.joint_upper[i]}]"
        )
    return q


def _finite(name: str, values: Sequence[float]) -> None:
    import math

    from mmstab.config import MmstabError

    if not all(math.isfinite(v) for v in values):
        raise MmstabError(f"{name}: must be finite, got {list(values)}")


def _rest(args: argparse.Namespace) -> None:
    import json

    import numpy as np

    from mmstab.stance import stance

    _finite("--pose", args.pose)
    if args.flipper is not None:
        _finite("--flipper", [args.flipper])
    problem = _problem(args)
    q = _arm_posture(problem.robot, args.arm)
    st = stance(problem.terrain, problem.robot, args.pose, args.flipper, q)
    if args.json:
        print(json.dumps(st.to_json(), allow_nan=True))
        return
    np.set_printoptions(precision=4, suppress=True)
    print(
        f"rest: roll {st.roll:+.5f} rad ({np.degrees(st.roll):+.2f} deg), pitch {st.pitch:+.5f}"
        f" rad ({np.degrees(st.pitch):+.2f} deg), z {st.z:+.4f} m"
    )
    print(f"rest: mu {st.mu:.2f} N rad; flags: {', '.join(st.flags) or 'none'}")
    print(f"rest: {len(st.contacts)} contacts; support polygon (G, m):")
    print(np.array2string(st.support_polygon, prefix="  "))
    print(f"rest: G_T_B =\n{st.G_T_B}")


def _stability_map(args: argparse.Namespace) -> None:
    from mmstab.config import MmstabError, check_output_dir
    from mmstab.experiments.terrain import run_stability_map

    if not args.spacing > 0 or args.headings < 1:
        raise MmstabError("--spacing must be > 0 [m] and --headings >= 1")
    problem = _problem(args)
    check_output_dir(args.out or f"results/terrain/{problem.name}")
    s = run_stability_map(problem, args.out, args.spacing, args.headings)
    print(
        f"stability-map: {s['poses']} poses ({s['rest_ms_per_pose']:.3f} ms/pose at rest), "
        f"stable share {s['share_stable']:.3f}; cells stable at every heading "
        f"{s['cells_stable_at_every_heading']}, at none {s['cells_unstable_at_every_heading']}"
    )


def _terrain_export(args: argparse.Namespace) -> None:
    from pathlib import Path

    from mmstab.config import MmstabError, check_output_dir
    from mmstab.terrain.factory import as_heightmap
    from mmstab.terrain.io import save_npz

    if Path(args.out).suffix.lower() != ".npz":
        raise MmstabError(f"-o {args.out}: the export is an .npz file")
    _finite("--size", args.size)
    if min(args.size) <= 0 or not args.resolution > 0:
        raise MmstabError("--size and --resolution must be positive [m]")
    problem = _problem(args)
    check_output_dir(Path(args.out).parent, f"output file {args.out}: folder")
    hm = as_heightmap(problem.terrain, tuple(args.size), args.resolution)
    path = save_npz(args.out, hm)
    ny, nx = hm.shape
    print(f"terrain export: {nx} x {ny} cells at {hm.resolution} m -> {path}")


def _add_terrain_commands(sub: Any) -> None:
    """``rest``, ``stability-map`` and ``terrain export`` (mmstab.terrain)."""
    h = "the resting pose of the base at one pose: roll, pitch, z, contacts, polygon, mu, flags"
    p = sub.add_parser("rest", help=h, description=h)
    p.add_argument("problem", help="problem YAML file (e.g. problems/kerb.yaml)")
    p.add_argument(
        "--pose",
        nargs=3,
        type=float,
        required=True,
        metavar=("X", "Y", "YAW"),
        help="base pose [m, m, rad]: in G on a heightmap, (x, y, heading) in S on the ramp",
    )
    p.add_argument("--flipper", type=float, default=None, help="flipper angle [rad]")
    p.add_argument(
        "--arm", nargs="+", default=None, metavar="Q", help="'stowed' or 4 joint angles [rad]"
    )
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    p.set_defaults(handler=_rest)

    h = "mu of the stowed arm over a grid of positions x headings: worst and best heading"
    p = sub.add_parser("stability-map", help=h, description=h)
    p.add_argument("problem", help="problem YAML file")
    p.add_argument("-o", "--out", default=None, help="output folder (default results/terrain/NAME)")
    p.add_argument("--spacing", type=float, default=0.25, help="grid spacing [m] (0.25)")
    p.add_argument("--headings", type=int, default=8, help="headings per cell (8)")
    p.set_defaults(handler=_stability_map)

    h = "terrain files"
    p = sub.add_parser("terrain", help=h, description=h)
    tsub = p.add_subparsers(dest="terrain_command", required=True, metavar="ACTION")
    h = "write the problem's terrain as .npz (elevation, resolution, origin)"
    e = tsub.add_parser("export", help=h, description=h)
    e.add_argument("problem", help="problem YAML file")
    e.add_argument("-o", "--out", required=True, help="output .npz file")
    e.add_argument(
        "--size",
        nargs=2,
        type=float,
        default=[6.0, 6.0],
        metavar=("X", "Y"),
        help="extent sampled for a ramp [m] (6 6)",
    )
    e.add_argument("--resolution", type=float, default=0.05, help="ramp cell size [m] (0.05)")
    e.set_defaults(handler=_terrain_export)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser (exposed for tests and docs)."""
    parser = argparse.ArgumentParser(
        prog="mmstab",
        description="Stability-aware planning and control of a tracked mobile manipulator.",
        epilog="exit status: 0 done, 2 bad input, 3 unstable, 130 interrupted (docs/cli.md)",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, help_text, handler in COMMANDS:
        p = sub.add_parser(name, help=help_text, description=help_text)
        p.add_argument("problem", help="problem YAML file (e.g. problems/ramp.yaml)")
        p.add_argument("-o", "--out", default=None, help="output folder (default results/NAME)")
        p.add_argument(
            "--force-size",
            action="store_true",
            help="run sizes whose time estimate exceeds the bound (not beyond the memory)",
        )
        for flag, kwargs in EXTRA_OPTIONS.get(name, []):
            p.add_argument(flag, **kwargs)
        p.set_defaults(handler=handler)
    # commands that take a robot description rather than a problem
    help_text = "export the robot description as URDF (base_link = body frame B)"
    p = sub.add_parser("urdf", help=help_text, description=help_text)
    p.add_argument("robot", help="robot YAML file (e.g. problems/robots/cameleon.yaml)")
    p.add_argument("-o", "--out", default=None, help="output file (default results/urdf/NAME.urdf)")
    p.set_defaults(handler=_urdf)
    from mmstab.viewer.cli import add_view_command  # issue 18: the browser viewer

    add_view_command(sub)
    _add_terrain_commands(sub)
    return parser


# --------------------------------------------------------------------------- pre-flight checks
def check_options(args: argparse.Namespace, problem: Any) -> None:
    """Options given on the command line, checked before any work.

    Raises:
        MmstabError: naming the option.
    """
    from mmstab.config import MmstabError
    from mmstab.settings import PLUGINS, check_duration, check_plugin

    plugin = getattr(args, "plugin", None)
    if args.command == "codegen" and plugin is not None:
        check_plugin(plugin)  # qpOASES: a clear error before anything is loaded
    if args.command == "track":
        if plugin is not None and plugin not in PLUGINS:
            raise MmstabError(f"--plugin: unknown QP plugin {plugin!r}; choose one of {PLUGINS}")
        if args.backend == "generated":
            check_plugin(plugin if plugin is not None else problem.section("codegen")["plugin"])
        if args.duration is not None:
            dt = float(problem.section("controller")["dt"])
            check_duration(args.duration, dt, force_size=args.force_size)


def output_dirs(args: argparse.Namespace, problem: Any) -> list[tuple[Path, str]]:
    """The folders a command will write to, with what they are (for messages)."""
    outs: list[tuple[Path, str]] = []
    if args.command in DEFAULT_OUT:
        outs.append((Path(args.out or DEFAULT_OUT[args.command]), "output folder"))
    if args.command in USES_WORKSPACE or (args.command == "codegen" and args.example):
        from mmstab.workspace import DEFAULT_CACHE_DIR, workspace_cache_path

        cache_dir = args.out if args.command == "workspace" else None
        cached = workspace_cache_path(problem, cache_dir)
        if getattr(args, "force", False) or not cached.is_file():
            folder = Path(cache_dir) if cache_dir is not None else DEFAULT_CACHE_DIR
            outs.append((folder, "workspace cache folder"))
    generated = args.command == "codegen" or getattr(args, "backend", None) == "generated"
    if generated and not (args.command == "codegen" and args.out is not None):
        outs.append((Path(problem.section("codegen")["directory"]), "codegen.directory"))
    if args.command == "codegen" and args.out is not None:
        outs.append((Path(args.out), "output folder"))
    return outs


def check_outputs(args: argparse.Namespace, problem: Any) -> None:
    """Refuse, before any work, output folders that cannot be written.

    Raises:
        MmstabError: one line naming the folder (ConfigError for ``codegen.directory``).
    """
    from mmstab.config import ConfigError, MmstabError, writable_dir_problem

    for folder, what in output_dirs(args, problem):
        why = writable_dir_problem(folder)
        if why is None:
            continue
        if what == "codegen.directory":
            raise ConfigError(problem.path, what, f"cannot write to {folder}: {why}")
        raise MmstabError(f"{what} {folder}: {why}")


def _run(args: argparse.Namespace) -> int:
    if args.handler is _urdf:
        from mmstab.config import MmstabError, check_output_dir

        out = Path(_urdf_out(args, "robot"))
        if args.out is not None:
            if out.is_dir():
                raise MmstabError(f"output file {out}: is a folder")
            check_output_dir(out.parent, f"output file {out}: folder")
        return args.handler(args, None) or EXIT_OK
    if args.command not in PROBLEM_COMMANDS:  # rest, stability-map, terrain, view
        return args.handler(args) or EXIT_OK  # they load the problem (all checks) themselves
    from mmstab.problem import load_problem

    problem = load_problem(args.problem, force_size=args.force_size)
    check_options(args, problem)
    check_outputs(args, problem)
    return args.handler(args, problem) or EXIT_OK


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit status (0, 2, 3 or 130; module docstring)."""
    previous = None
    try:
        from mmstab.pool import note_interrupts

        previous = note_interrupts()  # remembered even where C code swallows it
        return _main(argv)
    except KeyboardInterrupt:  # at any moment, imports included
        print("mmstab: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)


def _main(argv: Sequence[str] | None) -> int:
    from mmstab.config import MmstabError, UnstableError

    try:
        return _run(build_parser().parse_args(argv))
    except UnstableError as exc:
        print(f"mmstab: unstable: {exc}", file=sys.stderr)
        return EXIT_UNSTABLE
    except MmstabError as exc:
        print(f"mmstab: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except MemoryError:
        print("mmstab: error: out of memory (reduce the sizes in the problem)", file=sys.stderr)
        return EXIT_BAD_INPUT


def entry() -> None:
    """The ``mmstab`` program: exit with :func:`main`'s status; after a Ctrl-C, at once.

    An interrupted run has already removed its temporary files while unwinding, and its
    workers are dead; the interpreter's own shutdown (a fraction of a second, more on a
    loaded machine) is skipped, and so is any stray ``KeyboardInterrupt`` that C code
    left pending.
    """
    try:
        status = main()
    except KeyboardInterrupt:
        status = EXIT_INTERRUPTED
    if status == EXIT_INTERRUPTED:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):
                pass
        os._exit(status)
    sys.exit(status)


if __name__ == "__main__":
    entry()
