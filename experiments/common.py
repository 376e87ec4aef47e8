"""What the experiments share: the periodic local extrema, the study command lines' runner."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from mmstab.core.files import MmstabError


def circular_extrema(values: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the strict-or-plateau local maxima and minima of a periodic sequence.

    A plateau counts once, at its first sample.

    Returns:
        (maxima, minima) index arrays.
    """
    v = np.asarray(values, dtype=float)
    prev, nxt = np.roll(v, 1), np.roll(v, -1)
    # find the next different value for plateaus so a flat top is one maximum
    n = len(v)
    nxt_diff = np.empty(n)
    for i in range(n):
        j = (i + 1) % n
        while v[j] == v[i] and j != i:
            j = (j + 1) % n
        nxt_diff[i] = v[j]
    maxima = np.flatnonzero((v > prev) & (v > nxt_diff) & (v >= nxt))
    minima = np.flatnonzero((v < prev) & (v < nxt_diff) & (v <= nxt))
    return maxima, minima


def experiment_run(
    argv: list[str] | None,
    doc: str,
    settings: str,
    out: str,
    run: Callable[[Any, str], dict[str, Any]],
    load: Callable[[str], Any],
) -> tuple[dict[str, Any], str] | int:
    """A ``python -m experiments.NAME [SETTINGS] [-o DIR]`` run, its summary and folder.

    Args:
        argv: the arguments (``None``: the command line's).
        doc: the module's docstring (its first line is the help's description).
        settings: the settings file's default path.
        out: the output folder's default path.
        run: ``(settings, out) -> summary``.
        load: ``path -> settings`` (checked: one line naming the file and field if not).

    Returns:
        ``(summary, out)``, or the exit status: 2 for refused settings (one line on stderr),
        130 for Ctrl-C.
    """
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("settings", nargs="?", default=settings)
    parser.add_argument("-o", "--out", default=out, help="output folder")
    args = parser.parse_args(argv)
    try:
        return run(load(args.settings), args.out), args.out
    except MmstabError as exc:
        print(f"mmstab: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("mmstab: interrupted", file=sys.stderr)
        return 130
