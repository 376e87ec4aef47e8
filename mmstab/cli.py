"""The ``mmstab`` command line: one subcommand per pipeline stage or experiment.

Every subcommand takes a problem (or robot) YAML file. Input errors print one line
(``mmstab: error: FILE: FIELD: what``) and exit with status 2, before anything is written.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from typing import Any

from mmstab.config import MmstabError


def _problem(args: argparse.Namespace) -> Any:
    from mmstab.problem import load_problem

    return load_problem(args.problem)


def _fig5(args: argparse.Namespace) -> None:
    from mmstab.experiments.sweeps import run_fig5

    s = run_fig5(_problem(args), args.out)
    maxima = [round(float(x), 2) for x in s["local_maxima_rad"]]
    print(f"fig5: local maxima at link0 = {maxima} rad")


def _fig6(args: argparse.Namespace) -> None:
    from mmstab.experiments.sweeps import run_fig6

    s = run_fig6(_problem(args), args.out)
    print(f"fig6: {s['poses_with_two_maxima']} of {len(s['poses'])} poses with two maxima")


def _workspace(args: argparse.Namespace) -> None:
    from mmstab.workspace import load_or_build_workspace, workspace_cache_path

    problem = _problem(args)
    path = workspace_cache_path(problem, args.out)
    before = path.stat().st_mtime_ns if path.is_file() else None
    ws = load_or_build_workspace(problem, force=args.force, cache_dir=args.out)
    how = "loaded" if path.stat().st_mtime_ns == before else "built"
    print(
        f"workspace: {ws.postures} postures, {len(ws.valid_com)} valid, "
        f"{len(ws.invalid_com)} invalid, diameter {ws.diameter:.3f} m "
        f"(build {ws.build_seconds:.1f} s); {how}: {path}"
    )


def _fig3(args: argparse.Namespace) -> None:
    from mmstab.experiments.fig3 import run_fig3

    s = run_fig3(_problem(args), args.out, force=args.force)
    print(
        f"fig3: {s['valid']} valid / {s['invalid']} invalid, volume V {s['volume_V']:.4f} m^3, "
        f"recall {s['recall']:.3f}, precision {s['precision']:.3f}"
    )


def _track(args: argparse.Namespace) -> None:
    from mmstab.experiments.tracking import run_tracking

    s = run_tracking(
        _problem(args), args.out, args.plugin, backend=args.backend, duration=args.duration
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


def _urdf(args: argparse.Namespace) -> None:
    from mmstab.robot import load_robot
    from mmstab.urdf import write_urdf

    robot = load_robot(args.robot)
    out = args.out if args.out is not None else f"results/urdf/{robot.name}.urdf"
    print(f"urdf: wrote {write_urdf(robot, out)}")


def _plan(args: argparse.Namespace) -> None:
    from mmstab.experiments.planning import run_fig8

    s = run_fig8(_problem(args), args.out or "results/plan")
    for k, p in enumerate(s["poses"]):
        print(
            f"pose {k}: side {p['side']:5s} mu {p['mu_planned']:7.1f} "
            f"(stowed {p['mu_stowed']:7.1f}, arm removed {p['mu_arm_removed']:7.1f}) "
            f"CoM error {p['realised_com_error_m'] * 1e3:.2f} mm "
            f"{'collision-free' if p['collision_free'] else 'COLLIDES'}"
        )


def _fig7(args: argparse.Namespace) -> None:
    from mmstab.experiments.planning import run_fig7

    s = run_fig7(_problem(args), args.out)
    com = [round(float(x), 3) for x in s["target_com"]]
    print(f"fig7: target arm CoM {com} m, mu {s['mu_planned']:.1f} N rad")


def _fig8(args: argparse.Namespace) -> None:
    from mmstab.experiments.planning import run_fig8

    s = run_fig8(_problem(args), args.out)
    print(f"fig8: arm side per pose {s['sides']}")


def _codegen(args: argparse.Namespace) -> None:
    from mmstab.codegen import build_programs, check_plugin, generate

    if args.plugin is not None:
        check_plugin(args.plugin)  # qpOASES: a clear error before anything is loaded
    problem = _problem(args)
    gen = generate(problem, args.out, args.plugin, force=args.force)
    how = "generated and compiled" if gen.rebuilt else "up to date"
    print(f"codegen: {gen.plugin}: {how}: {gen.source}, {gen.header}, {gen.library}")
    if args.example:
        from mmstab import rollout as ro
        from mmstab.planner import plan_path

        plan = plan_path(problem)  # the ramp circle with the planned arm CoMs
        state0 = ro.initial_state(problem, plan, lateral_offset=0.05, arm=problem.robot.stowed)
        inputs = ro.run_inputs(problem, plan, state0=state0)
        run = ro.write_run_file(ro.run_file_path(gen.directory), inputs)
        progs = build_programs(gen)
        print(f"codegen: example {progs.loop} and timing {progs.bench}; run file {run}")


def _animation(args: argparse.Namespace) -> None:
    from mmstab.experiments.animation import run_animation

    s = run_animation(_problem(args), args.out)
    print(f"animation: {s['frames']} frames -> {s['gif']}")


def _atlas(args: argparse.Namespace) -> None:
    from mmstab.atlas.runner import run_atlas

    s = run_atlas(
        _problem(args), args.out, args.scheduler, args.workers, processes=not args.threads
    )
    r = s["run"]
    print(
        f"atlas: {s['cells']} cells ({r['cells_computed']} computed now, "
        f"{r['cells_already_stored']} resumed) on {r['workers']} workers, "
        f"{r['cells_per_second']:.1f} cells/s; figures and summary in {args.out or 'results/atlas'}"
    )
    for v in s["variants"]:
        lim = v["mean_limit_deg"]
        print(
            f"  {v['robot']}, flippers {v['flipper']}: mean steepest slope with mu >= "
            f"{s['margin_N_rad']:g} N rad: planned {lim['planned']} deg, stowed {lim['stowed']} "
            f"deg, arm removed {lim['arm removed']} deg"
        )


# (name, help, handler, takes a problem file)
COMMANDS: list[tuple[str, str, Callable[[argparse.Namespace], None]]] = [
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
    ("atlas", "tip-over envelope atlas over slope x heading x robot x flippers (Dask)", _atlas),
]

#: Options beyond ``problem`` and ``--out``, by command name.
EXTRA_OPTIONS: dict[str, list[tuple[str, dict[str, Any]]]] = {
    "workspace": [("--force", {"action": "store_true", "help": "rebuild even if cached"})],
    "fig3": [("--force", {"action": "store_true", "help": "rebuild the workspace"})],
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
    ],
    "atlas": [
        (
            "--scheduler",
            {"default": None, "help": "address of a running Dask scheduler (default: local)"},
        ),
        ("--workers", {"type": int, "default": None, "help": "local workers (default: cores)"}),
        (
            "--threads",
            {"action": "store_true", "help": "local workers as threads of one process"},
        ),
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


def build_parser() -> argparse.ArgumentParser:
    """The argument parser (exposed for tests and docs)."""
    parser = argparse.ArgumentParser(
        prog="mmstab",
        description="Stability-aware planning and control of a tracked mobile manipulator.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, help_text, handler in COMMANDS:
        p = sub.add_parser(name, help=help_text, description=help_text)
        p.add_argument("problem", help="problem YAML file (e.g. problems/ramp.yaml)")
        p.add_argument("-o", "--out", default=None, help="output folder (default results/NAME)")
        for flag, kwargs in EXTRA_OPTIONS.get(name, []):
            p.add_argument(flag, **kwargs)
        p.set_defaults(handler=handler)
    # commands that take a robot description rather than a problem
    help_text = "export the robot description as URDF (base_link = body frame B)"
    p = sub.add_parser("urdf", help=help_text, description=help_text)
    p.add_argument("robot", help="robot YAML file (e.g. problems/robots/cameleon.yaml)")
    p.add_argument("-o", "--out", default=None, help="output file (default results/urdf/NAME.urdf)")
    p.set_defaults(handler=_urdf)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        args.handler(args)
    except MmstabError as exc:
        print(f"mmstab: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("mmstab: interrupted", file=sys.stderr)
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
