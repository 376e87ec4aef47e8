"""``mmstab view PROBLEM [--run DIR] [--host HOST] [--port PORT] [--no-browser]``."""

from __future__ import annotations

import argparse
import os
import socket
import sys
import time
from typing import Any

from mmstab.core.files import MmstabError

#: Default interface: this machine only (reach it from elsewhere with ``ssh -L``).
DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8080


def port_number(text: str) -> int:
    """An argparse type: a TCP port 0-65535 (0 = any free port)."""
    try:
        port = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a port number: {text!r}") from None
    if not 0 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"port must be 0-65535, got {port}")
    return port


def add_view_command(sub: Any) -> None:
    """Register the ``view`` subcommand on an argparse subparsers object."""
    help_text = "interactive 3-D viewer in the browser: terrain, robot, plan, a stored run"
    p = sub.add_parser("view", help=help_text, description=help_text)
    p.add_argument("problem", help="problem YAML file (e.g. problems/ramp.yaml)")
    p.add_argument(
        "--run", default=None, help="a run folder of `mmstab track` (e.g. results/tracking)"
    )
    p.add_argument(
        "--host",
        default=DEFAULT_HOST,
        help=f"interface to listen on (default {DEFAULT_HOST}: this machine only; "
        "0.0.0.0: every interface)",
    )
    p.add_argument(
        "--port",
        type=port_number,
        default=DEFAULT_PORT,
        help=f"TCP port (default {DEFAULT_PORT}; 0: any free port; "
        "if busy, the next free one is used)",
    )
    p.add_argument("--no-browser", action="store_true", help="only print the URL")
    p.set_defaults(handler=run_view)


def check_listen(host: str) -> None:
    """Refuse a ``--host`` this machine cannot listen on, before anything starts.

    Raises:
        MmstabError: the name does not resolve or is not an address of this machine.
    """
    try:
        infos = socket.getaddrinfo(host, 0, type=socket.SOCK_STREAM)
    except (socket.gaierror, UnicodeError) as exc:
        raise MmstabError(f"--host: cannot resolve {host!r} ({exc})") from None
    family, kind, proto, _, address = infos[0]
    with socket.socket(family, kind, proto) as s:
        try:
            s.bind(address)
        except OSError as exc:
            raise MmstabError(f"--host: cannot listen on {host!r} ({exc.strerror})") from None


def has_display() -> bool:
    """Whether a browser window could be opened here (not on a headless robot)."""
    if sys.platform in ("darwin", "win32"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def run_view(args: argparse.Namespace) -> None:
    """Load the problem (and run), start the server, print its URL, serve until Ctrl-C."""
    from mmstab.core.problem import load_problem
    from mmstab.runs.store import load_run

    problem = load_problem(args.problem)
    run = load_run(args.run, problem) if args.run is not None else None
    check_listen(args.host)
    try:
        from mmstab.viz.viewer.server import Viewer
    except ImportError as exc:
        raise MmstabError(f"mmstab view needs viser ({exc}): pip install 'mmstab[view]'") from None
    viewer = Viewer(problem, run, host=args.host, port=args.port)
    try:
        what = f"run {run.directory} ({run.samples} samples)" if run is not None else "no run"
        print(f"view: {viewer.url} ({problem.path}, {what}; Ctrl-C stops)", flush=True)
        if not args.no_browser and has_display():
            import webbrowser

            webbrowser.open(viewer.url)
        while True:
            time.sleep(3600)
    finally:
        viewer.stop()
