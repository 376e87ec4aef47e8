"""The ``mmstab`` command line: one subcommand per pipeline stage or command output.

Every subcommand takes a problem (or robot) YAML file. Before any work, every command loads
and checks the whole problem (schema, the settings registry of
:mod:`mmstab.core.setting_checks`, the size bounds of :mod:`mmstab.core.sizes`; ``rest``
and ``terrain export``: the schema, and the checks of the sections they use), its options
and that its output folders can be written.

Exit statuses (``docs/cli.md``): 0 done; 2 bad input (one line ``mmstab: error: ...``,
nothing written); 3 unstable (the best plan has a pose at or below the stability margin, or
the tracked robot tips over; ``--allow-unstable`` accepts an unstable plan); 4 the tracks
would slide (tilt beyond atan(terrain.friction) at a pose; ``--allow-sliding``); 5 arm
collision (``--allow-collision``); 6 no plan; 130 interrupted (Ctrl-C: workers stopped, no
file half-written); 141 stdout's reader left (``| head``).
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
from collections.abc import Callable, Collection, Mapping, Sequence
from pathlib import Path
from typing import Any

from mmstab.cli.checks import check_options, check_outputs, report_route
from mmstab.cli.commands import (
    COMMANDS,
    DEFAULT_OUT,
    EXTRA_OPTIONS,
    USES_WORKSPACE,
    Handler,
    _urdf,
    _urdf_out,
    arm_from_urdf,
)
from mmstab.cli.node import add_node_commands
from mmstab.cli.online import add_online_commands
from mmstab.cli.physics import add_physics_commands
from mmstab.cli.status import (
    EXIT_BAD_INPUT,
    EXIT_BROKEN_PIPE,
    EXIT_INTERRUPTED,
    EXIT_NO_PLAN,
    EXIT_OK,
    EXIT_UNSTABLE,
)
from mmstab.cli.terrain import _add_terrain_commands

__all__ = [
    "EPILOG",
    "add_problem_commands",
    "build_parser",
    "check_options",
    "check_outputs",
    "entry",
    "main",
]

#: The exit statuses, as every parser's epilog says them.
EPILOG = (
    "exit status: 0 done, 2 bad input, 3 unstable, 4 slides, 5 arm collision, 6 no plan,"
    " 130 interrupted, 141 output pipe closed (docs/cli.md)"
)


def add_problem_commands(
    sub: Any,
    commands: Sequence[tuple[str, str, Handler]],
    options: Mapping[str, list[tuple[str, dict[str, Any]]]],
    default_out: Mapping[str, str],
    uses_workspace: Collection[str],
) -> None:
    """Add commands that take a problem file to the subparsers ``sub``.

    Each gets ``problem``, ``-o/--out``, ``--force-size`` and its ``options``; before it
    runs, :func:`main` loads and checks the problem and the folders it will write
    (``default_out``: its default output folder; ``uses_workspace``: it may build the
    workspace cache). ``python -m experiments`` adds its own this way.
    """
    for name, help_text, handler in commands:
        p = sub.add_parser(name, help=help_text, description=help_text)
        p.add_argument("problem", help="problem YAML file (e.g. problems/ramp.yaml)")
        p.add_argument("-o", "--out", default=None, help="output folder (default results/NAME)")
        p.add_argument(
            "--force-size",
            action="store_true",
            help="run sizes whose time estimate exceeds the bound (not beyond the memory)",
        )
        for flag, kwargs in options.get(name, []):
            p.add_argument(flag, **kwargs)
        p.set_defaults(
            handler=handler,
            problem_command=True,
            default_out=default_out.get(name),
            uses_workspace=name in uses_workspace,
        )


def build_parser() -> argparse.ArgumentParser:
    """The argument parser (exposed for tests and docs)."""
    parser = argparse.ArgumentParser(
        prog="mmstab",
        description="Stability-aware planning and control of a tracked mobile manipulator.",
        epilog=EPILOG,
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    add_problem_commands(sub, COMMANDS, EXTRA_OPTIONS, DEFAULT_OUT, USES_WORKSPACE)
    # commands that take a robot description rather than a problem
    help_text = "export the robot description as URDF (base_link = body frame B)"
    p = sub.add_parser("urdf", help=help_text, description=help_text)
    p.add_argument("robot", help="robot YAML file (e.g. problems/robots/cameleon.yaml)")
    p.add_argument("-o", "--out", default=None, help="output file (default results/urdf/NAME.urdf)")
    p.set_defaults(handler=_urdf)
    help_text = "the robot file's arm: section from a URDF's chain of revolute joints"
    p = sub.add_parser("arm-from-urdf", help=help_text, description=help_text)
    p.add_argument("urdf", help="URDF file of the arm (or of a robot that has it)")
    p.add_argument(
        "--base",
        default=None,
        help="the link the arm is mounted on (default: the file's root link)",
    )
    p.add_argument(
        "--tip",
        default=None,
        help="the arm's last link, its flange or tool "
        "(default: the one leaf below the most revolute joints)",
    )
    p.add_argument(
        "--mount",
        nargs=6,
        type=float,
        default=None,
        metavar=("X", "Y", "Z", "ROLL", "PITCH", "YAW"),
        help="the base link's pose in the body frame B [m, rad] (default: B)",
    )
    p.add_argument(
        "--package-dir",
        action="append",
        default=[],
        metavar="DIR",
        help="a folder holding the packages of package:// meshes (repeatable)",
    )
    p.add_argument("-o", "--out", default=None, help="output YAML file (default: stdout)")
    p.set_defaults(handler=arm_from_urdf)
    from mmstab.viz.viewer.cli import add_view_command  # the browser viewer

    add_view_command(sub)
    _add_terrain_commands(sub)
    add_online_commands(sub)
    add_node_commands(sub)
    add_physics_commands(sub)
    return parser


def _run(args: argparse.Namespace) -> int:
    if args.handler is _urdf:
        from mmstab.core.files import MmstabError, check_output_dir

        out = Path(_urdf_out(args, "robot"))
        if args.out is not None:
            if out.is_dir():
                raise MmstabError(f"output file {out}: is a folder")
            check_output_dir(out.parent, f"output file {out}: folder")
        return args.handler(args, None) or EXIT_OK
    if not getattr(args, "problem_command", False):  # rest, stability-map, terrain, view
        return args.handler(args) or EXIT_OK  # they load the problem themselves
    from mmstab.core.problem import load_problem

    problem = load_problem(args.problem, force_size=args.force_size)
    check_options(args, problem)
    check_outputs(args, problem)
    report_route(problem)
    return args.handler(args, problem) or EXIT_OK


Parser = Callable[[], argparse.ArgumentParser]


def main(argv: Sequence[str] | None = None, parser: Parser = build_parser) -> int:
    """Entry point; returns the exit status (0, 2-6 or 130; module docstring).

    ``parser``: the command line's parser (default ``mmstab``'s; ``python -m experiments``
    passes its own).
    """
    previous = None
    try:
        from mmstab.core.pool import note_interrupts

        previous = note_interrupts()  # remembered even where C code swallows it
        return _main(argv, parser)
    except KeyboardInterrupt:  # at any moment, imports included
        _close_progress_bars()
        print("mmstab: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)


def _close_progress_bars() -> None:
    """Close the progress bars the interrupt left open, so the last line is the verdict.

    A bar left open is closed (and drawn once more) whenever the unwound frames holding it
    are freed, which may come after ``mmstab: interrupted``.
    """
    tqdm = sys.modules.get("tqdm")
    for bar in list(getattr(getattr(tqdm, "tqdm", None), "_instances", ())):
        bar.close()


def _main(argv: Sequence[str] | None, parser: Parser) -> int:
    """The command's status; the problem's load-time notes after it, unless it was refused."""
    from mmstab.core.notes import held_notes

    with held_notes() as notes:
        status = _status(argv, parser)
    if status != EXIT_BAD_INPUT:  # bad input: one line
        for line in notes:
            print(line, file=sys.stderr)
    return status


def _status(argv: Sequence[str] | None, parser: Parser) -> int:
    from mmstab.core.files import MmstabError, PlanningError, UnstableError

    try:
        return _run(parser().parse_args(argv))
    except UnstableError as exc:
        print(f"mmstab: unstable: {exc}", file=sys.stderr)
        return EXIT_UNSTABLE
    except PlanningError as exc:
        print(f"mmstab: no plan: {exc}", file=sys.stderr)
        return EXIT_NO_PLAN
    except MmstabError as exc:
        print(f"mmstab: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except MemoryError:
        print("mmstab: error: out of memory (reduce the sizes in the problem)", file=sys.stderr)
        return EXIT_BAD_INPUT


def entry(parser: Parser = build_parser) -> None:
    """The ``mmstab`` program: exit with :func:`main`'s status; after a Ctrl-C, at once.

    An interrupted run has already removed its temporary files while unwinding, and its
    workers are dead; the interpreter's own shutdown (a fraction of a second, more on a
    loaded machine) is skipped, and so is any stray ``KeyboardInterrupt`` that C code
    left pending.
    """
    try:
        status = main(parser=parser)
    except KeyboardInterrupt:
        status = EXIT_INTERRUPTED
    except BrokenPipeError:  # stdout's reader left (| head): stop quietly, as a C program
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no flush error
        status = EXIT_BROKEN_PIPE
    if status == EXIT_INTERRUPTED:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):
                pass
        os._exit(status)
    sys.exit(status)
