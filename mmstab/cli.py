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
    print(f"fig5: local maxima at link0 = {[round(x, 2) for x in s['local_maxima_rad']]} rad")


def _fig6(args: argparse.Namespace) -> None:
    from mmstab.experiments.sweeps import run_fig6

    s = run_fig6(_problem(args), args.out)
    print(f"fig6: {s['poses_with_two_maxima']} of {len(s['poses'])} poses with two maxima")


def _urdf(args: argparse.Namespace) -> None:
    from mmstab.robot import load_robot
    from mmstab.urdf import write_urdf

    robot = load_robot(args.robot)
    out = args.out if args.out is not None else f"results/urdf/{robot.name}.urdf"
    print(f"urdf: wrote {write_urdf(robot, out)}")


# (name, help, handler, takes a problem file)
COMMANDS: list[tuple[str, str, Callable[[argparse.Namespace], None]]] = [
    ("fig5", "paper Fig. 5: stability over a link0 sweep at one rolled pose", _fig5),
    ("fig6", "paper Fig. 6: link0 sweeps at poses along the circle", _fig6),
]


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
