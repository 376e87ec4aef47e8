"""Where a re-plan's computation ends its steps (:mod:`mmstab.runs.online.replan_jobs`).

A re-plan (:class:`~mmstab.runs.online.roadmap_horizon.RoadmapHorizon`) calls the offline
planner's candidate search (:func:`~mmstab.planner.candidates.route_candidates`) and the
ground check under the arm; these subclasses of what it hands them end a step of the
running job (:func:`~mmstab.runs.online.replan_jobs.pause`) where they are called: the
pose's fitness each time a round of the search values rows, the ground check before each
pose it measures, the arm's pieces every :data:`PIECES_STEP` new nodes. They compute what
their bases compute; outside a stepped job they only call them.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from mmstab.model.robot import FloatArray
from mmstab.planner.fitness import LinearFitness
from mmstab.planner.ground.map_ground import MapGround
from mmstab.planner.ground.under_arm import GroundUnderArm, KeptPieces
from mmstab.runs.online.replan_jobs import pause, stepped

#: Nodes whose arm pieces one step of a re-plan computes (:class:`PausedPieces`).
PIECES_STEP = 32


class PausedFitness(LinearFitness):
    """Eq. 6 at a pose that ends a job's step each time it values rows (:func:`pause`)."""

    def __call__(self, com_body: Any) -> FloatArray:
        """As :class:`LinearFitness`, after a pause."""
        pause()
        return super().__call__(com_body)


class PausedGround(MapGround):
    """A map's ground under the arm whose check ends a job's step per pose measured."""

    def under(self, ks: list[int]) -> GroundUnderArm:
        """As :meth:`MapGround.under`; its ``clear`` after a pause."""
        g = super().under(ks)
        clear = g.clear

        def paused(*args: Any, **kwargs: Any) -> NDArray[np.bool_]:
            pause()
            return clear(*args, **kwargs)

        g.clear = paused  # type: ignore[method-assign]
        return g


class PausedPieces(KeptPieces):
    """:class:`KeptPieces` that computes new rows' pieces in steps of a job (:func:`pause`)."""

    def add(self, rows: NDArray[np.intp]) -> None:
        """As :meth:`KeptPieces.add`, :data:`PIECES_STEP` rows per step (in one, outside)."""
        if not stepped():
            super().add(rows)
            return
        new = np.unique(rows[self.slot[rows] < 0])
        for i in range(0, len(new), PIECES_STEP):
            pause()
            super().add(new[i : i + PIECES_STEP])
