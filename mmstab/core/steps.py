"""Stepped computations: a generator that yields between steps and returns its result.

A long computation written so (:meth:`mmstab.workspace.roadmap.Roadmap.shortcut_steps`) can
be run at once (:func:`drain`) or a few steps at a time, between other work, with the same
result (the online loop's moves, :mod:`mmstab.runs.online.moves_ahead`).
"""

from __future__ import annotations

from collections.abc import Generator
from typing import TypeVar

T = TypeVar("T")


def drain(steps: Generator[None, None, T]) -> T:
    """Run a stepped computation to its result."""
    while True:
        try:
            next(steps)
        except StopIteration as done:
            return done.value
