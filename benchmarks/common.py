"""What every benchmark records about the machine it ran on."""

from __future__ import annotations

import os
import platform
from typing import Any

import casadi as ca


def machine_info(**extra: Any) -> dict[str, Any]:
    """Platform, processor, core count, library versions and load, plus ``extra`` entries.

    ``load_average``: the 1, 5 and 15 min load averages when the benchmark wrote its result
    (other jobs on a shared machine slow every figure; compare peers from the same run).
    """
    return {
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
        "casadi": ca.__version__,
        "load_average": [round(x, 2) for x in os.getloadavg()]
        if hasattr(os, "getloadavg")
        else None,
        **extra,
    }
