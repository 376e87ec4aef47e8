"""What every benchmark records about the machine it ran on; the repository on the path.

The repository's root goes on the import path here, so the benchmarks that time the
studies (``experiments/``, not installed) import them, wherever they are run from.
"""

from __future__ import annotations

import os
import platform
import sys
from pathlib import Path
from typing import Any

import casadi as ca

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.append(str(ROOT))


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
