"""``mmstab node`` (the online loop as a ROS 2 node) and ``mmstab play`` (recording -> topics).

docs/online.md, "On the robot: a ROS 2 node".
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from mmstab.cli.status import EXIT_BAD_INPUT


def _ready() -> int | None:
    """Re-exec with the ROS environment; exit 2 with one line when the ros extra is missing."""
    from mmstab.runs.online.rosenv import ensure_ros_env, ros_available

    why = ros_available()
    if why is not None:
        print(f"mmstab: error: {why}", file=sys.stderr)
        return EXIT_BAD_INPUT
    ensure_ros_env()
    return None


def _node(args: argparse.Namespace) -> int | None:
    status = _ready()
    if status is not None:
        return status
    import importlib.util

    from mmstab.core.problem import load_problem
    from mmstab.runs.online.node import MmstabNode

    if args.foxglove and importlib.util.find_spec("foxglove") is None:
        print("mmstab: error: --foxglove: no foxglove-sdk: install the ros extra", file=sys.stderr)
        return EXIT_BAD_INPUT

    problem = load_problem(args.problem)
    view = None
    if args.foxglove:
        from mmstab.runs.online.foxglove_view import FoxgloveView

        view = FoxgloveView(problem, args.foxglove_host, args.foxglove_port)
        print(f"node: Foxglove live view on ws://{args.foxglove_host}:{args.foxglove_port}")
    ros_args = None if args.ros_args is None else ["--ros-args", *args.ros_args]
    MmstabNode(problem, ros_args, view).spin()
    return None


def _play(args: argparse.Namespace) -> int | None:
    status = _ready()
    if status is not None:
        return status
    from mmstab.core.defaults import SECTION_DEFAULTS
    from mmstab.runs.online.player import parse_faults, play
    from mmstab.runs.online.rosenv import NodeTopics

    faults = parse_faults(args.fault)
    topics = NodeTopics.of(SECTION_DEFAULTS["online"])
    if args.problem is not None:
        from mmstab.core.problem import load_problem

        topics = NodeTopics.of(load_problem(args.problem).section("online"))
    n = play(args.recording, topics, args.rate, faults, args.answers, args.limit)
    print(
        f"play: {n['maps']} maps, {n['messages']} messages"
        + ("" if n["answers"] is None else f", {n['answers']} answers read back")
    )
    return None


def add_node_commands(sub: Any) -> None:
    """``node`` and ``play``."""
    h = "the online loop as a ROS 2 node: maps, odometry, joints in; arm, commands, verdicts out"
    p = sub.add_parser("node", help=h, description=h)
    p.add_argument("problem", help="route problem YAML file (its online: section: topics)")
    p.add_argument("--foxglove", action="store_true", help="serve a live Foxglove view (WebSocket)")
    p.add_argument("--foxglove-host", default="127.0.0.1", help="its address (default 127.0.0.1)")
    p.add_argument("--foxglove-port", type=int, default=8765, help="its port (default 8765)")
    p.add_argument(
        "--ros-args", nargs=argparse.REMAINDER, default=None,
        help="ROS arguments, e.g. --ros-args -p max_map_age:=1.0 -p odom_topic:=/odometry",
    )  # fmt: skip
    p.set_defaults(handler=_node)
    h = "play a recording onto ROS 2 topics, stamped now (to drive mmstab node)"
    p = sub.add_parser("play", help=h, description=h)
    p.add_argument("recording", help=".mcap, ROS 1 .bag or ROS 2 bag folder")
    p.add_argument("--problem", default=None, help="take the topics from this problem's online:")
    p.add_argument("--rate", type=float, default=1.0, help="playback speed (default 1: real time)")
    p.add_argument("--limit", type=int, default=None, help="play up to the N-th map")
    p.add_argument(
        "--fault", action="append", default=[],
        help="NAME@T: odom-stops, no-transform, old-map, malformed or restart from T [s] on",
    )  # fmt: skip
    p.add_argument("--answers", default=None, help="write the node's answers here (JSON lines)")
    p.set_defaults(handler=_play)
