"""Notes on stderr that are not refusals (a skipped collision pair, a link off its segment).

A library call prints them at once; the command line holds them (:func:`held_notes`) and
prints them when the command ends, unless it refused its input: a refusal stays one line.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator

#: Notes held until the command ends, or None: printed at once.
_HELD: list[str] | None = None


@contextlib.contextmanager
def held_notes() -> Iterator[list[str]]:
    """Hold the notes given meanwhile (not printed) in the list yielded."""
    global _HELD
    before, _HELD = _HELD, []
    try:
        yield _HELD
    finally:
        _HELD = before


def note(line: str) -> None:
    """Print ``line`` on stderr, or hold it (:func:`held_notes`)."""
    if _HELD is None:
        print(line, file=sys.stderr)
    else:
        _HELD.append(line)
