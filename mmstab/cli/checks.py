"""Checks of a command's options and output folders, before any work."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any


# --------------------------------------------------------------------------- pre-flight checks
def check_options(args: argparse.Namespace, problem: Any) -> None:
    """Options given on the command line, checked before any work.

    Raises:
        MmstabError: naming the option.
    """
    from mmstab.core.files import MmstabError
    from mmstab.core.setting_checks import PLUGINS, check_duration, check_plugin

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
    default_out = getattr(args, "default_out", None)
    if default_out is not None:
        outs.append((Path(args.out or default_out), "output folder"))
    uses_workspace = getattr(args, "uses_workspace", False)
    if uses_workspace or (args.command == "codegen" and args.example):
        from mmstab.workspace import default_cache_dir, workspace_cache_path

        cache_dir = args.out if args.command == "workspace" else None
        cached = workspace_cache_path(problem, cache_dir)
        if getattr(args, "force", False) or not cached.is_file():
            folder = Path(cache_dir) if cache_dir is not None else default_cache_dir()
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
    from mmstab.core.files import ConfigError, MmstabError, writable_dir_problem

    for folder, what in output_dirs(args, problem):
        why = writable_dir_problem(folder)
        if why is None:
            continue
        if what == "codegen.directory":
            raise ConfigError(problem.path, what, f"cannot write to {folder}: {why}")
        raise MmstabError(f"{what} {folder}: {why}")


def report_route(problem: Any) -> None:
    """Say what the route check did: one ``route:`` line per pivot turn (none on a circle).

    A corner whose arc does not fit between its neighbours, or every corner with
    ``turn_radius: 0``, is driven as a pivot turn on the spot (``docs/routes.md``).
    """
    route = problem.route
    for line in [] if route is None else route.report():
        print(f"route: {line}")
