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
    from mmstab.app import workspace
    from mmstab.workspace import workspace_cache_path

    problem = _problem(args)
    path = workspace_cache_path(problem, args.out)
    before = path.stat().st_mtime_ns if path.is_file() else None
    ws = workspace(problem, force=args.force, cache_dir=args.out)
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


def _fidelity(args: argparse.Namespace) -> None:
    from mmstab.experiments.fidelity import run_fidelity

    s = run_fidelity(_problem(args), args.out, args.results)
    f6, f8, f11, f12 = s["fig6"], s["fig8"], s["fig11"], s["fig12"]
    below = ", ".join(f"{i['start_s']:.2f}-{i['end_s']:.2f} s" for i in f12["below_stowed"])
    print(
        f"fidelity: fig6 {f6['poses_with_two_maxima']}/{f6['poses']} sweeps with two maxima; "
        f"fig8 sides {f8['sides']}; fig11 saturates: {f11['saturates']}; "
        f"fig12 below the stowed arm: {below or 'never'}"
    )


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
        from mmstab.app import plan as plan_of
        from mmstab.reference import initial_state

        plan = plan_of(problem)  # the problem's path with the planned arm CoMs
        state0 = initial_state(problem.circle, problem.robot.stowed, lateral_offset=0.05)
        inputs = ro.run_inputs(problem, plan, state0=state0)
        run = ro.write_run_file(ro.run_file_path(gen.directory), inputs)
        progs = build_programs(gen)
        print(f"codegen: example {progs.loop} and timing {progs.bench}; run file {run}")


def _animation(args: argparse.Namespace) -> None:
    from mmstab.experiments.animation import run_animation

    s = run_animation(_problem(args), args.out)
    print(f"animation: {s['frames']} frames -> {s['gif']}")


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
    ("fidelity", "paper claims vs the saved results of fig6, fig8, tracking", _fidelity),
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
    from mmstab.experiments.terrain import run_stability_map

    if not args.spacing > 0 or args.headings < 1:
        raise MmstabError("--spacing must be > 0 [m] and --headings >= 1")
    s = run_stability_map(_problem(args), args.out, args.spacing, args.headings)
    print(
        f"stability-map: {s['poses']} poses ({s['rest_ms_per_pose']:.3f} ms/pose at rest), "
        f"stable share {s['share_stable']:.3f}; cells stable at every heading "
        f"{s['cells_stable_at_every_heading']}, at none {s['cells_unstable_at_every_heading']}"
    )


def _terrain_export(args: argparse.Namespace) -> None:
    from pathlib import Path

    from mmstab.terrain.factory import as_heightmap
    from mmstab.terrain.io import save_npz

    if Path(args.out).suffix.lower() != ".npz":
        raise MmstabError(f"-o {args.out}: the export is an .npz file")
    _finite("--size", args.size)
    if min(args.size) <= 0 or not args.resolution > 0:
        raise MmstabError("--size and --resolution must be positive [m]")
    problem = _problem(args)
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
    from mmstab.viewer.cli import add_view_command  # issue 18: the browser viewer

    add_view_command(sub)
    _add_terrain_commands(sub)
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
