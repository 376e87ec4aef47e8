"""The figure of the verdict grid (``make verdicts`` -> ``results/verdicts/verdicts.png``).

Left, per MuJoCo model: the confusion matrix (mmstab's verdict per row, MuJoCo's per
column). Right: the tip slopes MuJoCo's bisection found against mmstab's, with the 1 deg
band.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from mmstab.core.files import write_figure
from mmstab.physics.verdict_sim import VERDICTS


def verdicts_figure(summary: dict[str, Any], path: str | Path) -> Path:
    """Draw and save the figure (atomically)."""
    import matplotlib.pyplot as plt

    models = list(summary["models"])
    fig, axes = plt.subplots(1, len(models) + 1, figsize=(4.2 * (len(models) + 1), 3.8))
    for ax, name in zip(axes, models, strict=False):
        m = summary["models"][name]
        counts = np.array([[m["confusion"][p][s] for s in VERDICTS] for p in VERDICTS])
        ax.imshow(counts, cmap="Blues")
        for i in range(3):
            for j in range(3):
                dark = counts[i, j] > counts.max() / 2
                color = "white" if dark else "black"
                ax.text(j, i, str(counts[i, j]), ha="center", va="center", color=color)
        ax.set_xticks(range(3), VERDICTS)
        ax.set_yticks(range(3), VERDICTS)
        ax.set_xlabel("MuJoCo")
        ax.set_ylabel("mmstab")
        ax.set_title(f"{name}: {m['agree']}/{m['cases']} agree ({100 * m['agreement']:.1f} %)")
    ax = axes[-1]
    lo, hi = 90.0, 0.0
    for name, s in summary["tip_slopes"].items():
        rows = [r for r in s["rows"] if r["simulated_deg"] is not None]
        p = np.array([r["predicted_deg"] for r in rows])
        q = np.array([r["simulated_deg"] for r in rows])
        if len(p):
            ax.plot(p, q, "o", ms=4, label=name)
            lo, hi = min(lo, p.min(), q.min()), max(hi, p.max(), q.max())
    line = np.array([lo - 1, hi + 1])
    ax.plot(line, line, "k-", lw=0.8)
    ax.fill_between(line, line - 1, line + 1, color="0.85", label="+-1 deg")
    ax.set_xlabel("mmstab tip slope [deg]")
    ax.set_ylabel("MuJoCo tip slope [deg]")
    ax.legend(fontsize=8)
    ax.set_title("critical slope where it tips")
    fig.tight_layout()
    return write_figure(path, fig)
