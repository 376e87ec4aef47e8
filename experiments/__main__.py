"""``python -m experiments COMMAND PROBLEM``: the paper's figures and the studies.

Run from the repository root (the Makefile's targets do): ``fig3``, ``fig5``, ``fig6``,
``fidelity``, ``atlas`` and ``levers``, with ``mmstab``'s checks before any work and its
exit statuses (:func:`mmstab.cli.main`). The studies with a settings file of their own run
as modules (``python -m experiments.verdicts``, ``skid``, ``validate_routes``, ``rest_mu``).
"""

from __future__ import annotations

import argparse
from typing import Any

from mmstab.cli import EPILOG, add_problem_commands, entry
from mmstab.cli.commands import Handler, _announce

#: Default output folder of each command (``-o`` overrides it).
DEFAULT_OUT = {
    "fig5": "results/fig5",
    "fig6": "results/fig6",
    "fig3": "results/fig3",
    "fidelity": "results/fidelity",
    "atlas": "results/atlas",
    "levers": "results/levers",
}
#: Commands that load or build the workspace (its cache folder must be writable to build).
USES_WORKSPACE = {"fig3", "atlas", "levers"}
#: Options beyond ``problem``, ``--out`` and ``--force-size``, by command name.
OPTIONS: dict[str, list[tuple[str, dict[str, Any]]]] = {
    "fig3": [("--force", {"action": "store_true", "help": "rebuild the workspace"})],
    "fidelity": [
        ("--results", {"default": "results", "help": "where fig6/, fig8/, tracking/ are"})
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
}


def _fig5(args: argparse.Namespace, problem: Any) -> None:
    from experiments.sweeps import run_fig5

    s = run_fig5(problem, args.out)
    maxima = [round(float(x), 2) for x in s["local_maxima_rad"]]
    print(f"fig5: local maxima at link0 = {maxima} rad")


def _fig6(args: argparse.Namespace, problem: Any) -> None:
    from experiments.sweeps import run_fig6

    _announce(problem, "sweep")
    s = run_fig6(problem, args.out)
    print(f"fig6: {s['poses_with_two_maxima']} of {len(s['poses'])} poses with two maxima")


def _fig3(args: argparse.Namespace, problem: Any) -> None:
    from experiments.fig3 import run_fig3

    _announce(problem, "precision")
    s = run_fig3(problem, args.out, force=args.force)
    print(
        f"fig3: {s['valid']} valid / {s['invalid']} invalid, volume V {s['volume_V']:.4f} m^3, "
        f"recall {s['recall']:.3f}, precision {s['precision']:.3f}"
    )


def _fidelity(args: argparse.Namespace, problem: Any) -> None:
    from experiments.fidelity import run_fidelity

    s = run_fidelity(problem, args.out, args.results)
    f6, f8, f11, f12 = s["fig6"], s["fig8"], s["fig11"], s["fig12"]
    below = ", ".join(f"{i['start_s']:.2f}-{i['end_s']:.2f} s" for i in f12["below_stowed"])
    print(
        f"fidelity: fig6 {f6['poses_with_two_maxima']}/{f6['poses']} sweeps with two maxima; "
        f"fig8 sides {f8['sides']}; fig11 saturates: {f11['saturates']}; "
        f"fig12 below the stowed arm: {below or 'never'}"
    )


def _atlas(args: argparse.Namespace, problem: Any) -> None:
    from experiments.atlas.runner import run_atlas

    s = run_atlas(problem, args.out, args.scheduler, args.workers, processes=not args.threads)
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


def _levers(args: argparse.Namespace, problem: Any) -> None:
    from experiments.levers import run_levers

    s = run_levers(problem, args.out)
    d, p = s["dynamic"], s["payload"]
    lap = {k: d[k]["fastest_safe_lap_time_s"] for k in ("planned", "stowed")}
    print(
        f"levers: fastest safe lap (mu >= {s['margin_N_rad']:g} N rad): planned arm "
        f"{lap['planned']:.2f} s, stowed {lap['stowed']:.2f} s (the tracks allow "
        f"{d['track_speed_limit_lap_time_s']:.2f} s); heaviest payload planned front/left/right "
        + "/".join(
            "-"
            if p[k]["planned"]["heaviest_kg"] is None
            else f"{p[k]['planned']['heaviest_kg']:.1f}"
            for k in ("front", "left", "right")
        )
        + f" kg; {s['seconds']:.0f} s; figures and summary in {args.out or 'results/levers'}"
    )


# (name, help, handler)
COMMANDS: list[tuple[str, str, Handler]] = [
    ("fig5", "paper Fig. 5: stability over a link0 sweep at one rolled pose", _fig5),
    ("fig6", "paper Fig. 6: link0 sweeps at poses along the circle", _fig6),
    ("fig3", "paper Fig. 3: workspace V, hull of invalid CoMs, hull of all CoMs", _fig3),
    ("atlas", "tip-over envelope atlas over slope x heading x robot x flippers (Dask)", _atlas),
    ("fidelity", "paper claims vs the saved results of fig6, fig8, tracking", _fidelity),
    ("levers", "payload, flippers, lap speed and robot variants as stability levers", _levers),
]


def build_parser() -> argparse.ArgumentParser:
    """The experiments' argument parser (exposed for tests)."""
    parser = argparse.ArgumentParser(
        prog="python -m experiments",
        description="The paper's figures and the studies of mmstab.",
        epilog=EPILOG,
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    add_problem_commands(sub, COMMANDS, OPTIONS, DEFAULT_OUT, USES_WORKSPACE)
    return parser


if __name__ == "__main__":
    entry(build_parser)
