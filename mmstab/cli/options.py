"""The options of the problem commands beyond ``problem``, ``--out`` and ``--force-size``."""

from __future__ import annotations

from typing import Any

_ALLOW_UNSTABLE = (
    "--allow-unstable",
    {
        "action": "store_true",
        "help": "accept a plan with poses at or below the stability margin (exit 0, warning)",
    },
)

_ALLOW_SLIDING = (
    "--allow-sliding",
    {
        "action": "store_true",
        "help": "accept poses where the tracks would slide (tilt > atan(terrain.friction); "
        "exit 0, warning)",
    },
)

_ALLOW_COLLISION = (
    "--allow-collision",
    {
        "action": "store_true",
        "help": "exit 0 (warning) when the arm touches the robot (plan: at a planned posture "
        "or between two, or the ground on its posture reference at rest; track: or comes "
        "closer than the required clearance, runs/verdict.py MIN_CLEARANCE)",
    },
)

#: Options beyond ``problem``, ``--out`` and ``--force-size``, by command name.
EXTRA_OPTIONS: dict[str, list[tuple[str, dict[str, Any]]]] = {
    "workspace": [("--force", {"action": "store_true", "help": "rebuild even if cached"})],
    "plan": [
        _ALLOW_UNSTABLE,
        _ALLOW_SLIDING,
        _ALLOW_COLLISION,
        (
            "--verify",
            {
                "action": "store_true",
                "help": "then run the route in MuJoCo and report whether physics agrees "
                "(an accepted route that fails there exits 3 or 4; the validate extra)",
            },
        ),
    ],
    "fig7": [_ALLOW_UNSTABLE],
    "fig8": [_ALLOW_UNSTABLE, _ALLOW_SLIDING, _ALLOW_COLLISION],
    "animation": [_ALLOW_UNSTABLE, _ALLOW_SLIDING, _ALLOW_COLLISION],
    "track": [
        (
            "--plugin",
            {"help": "QP plugin: qpoases, osqp, qrqp, daqp or box (default: the problem's)"},
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
        _ALLOW_SLIDING,
        _ALLOW_COLLISION,
    ],
    "codegen": [
        (
            "--plugin",
            {
                "default": None,
                "help": "QP plugin: box, qrqp, daqp or osqp (default codegen.plugin)",
            },
        ),
        ("--force", {"action": "store_true", "help": "regenerate even if up to date"}),
        (
            "--native",
            {
                "action": "store_true",
                "help": "compile with -march=native (this machine's instruction set only)",
            },
        ),
        (
            "--example",
            {"action": "store_true", "help": "also build the embedded example (embedded/)"},
        ),
    ],
}
