"""What every benchmark records about the machine it ran on."""

from __future__ import annotations

import os
import platform
from typing import Any

import casadi as ca


def machine_info(**extra: Any) -> dict[str, Any]:
    """Platform, processor, core count and library versions, plus ``extra`` entries."""
    return {
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
        "casadi": ca.__version__,
        **extra,
    }
