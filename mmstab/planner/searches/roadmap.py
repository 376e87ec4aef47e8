"""``method: roadmap``: one reachable posture-roadmap node per pose (:mod:`mmstab.planner.roadmap`).

Exact on the roadmap's candidates (dynamic programming over poses x nodes, no round limit);
the moves between the chosen postures are roadmap paths, collision-free by construction.
Per pose (a caller planning one pose) it is the exhaustive reference.
"""

from __future__ import annotations

import numpy as np

from mmstab.core.files import MmstabError
from mmstab.planner.climbing import climb_plan
from mmstab.planner.fitness import support_polygons_at
from mmstab.planner.roadmap import solve_roadmap_sequence
from mmstab.planner.search import PathChoice, PathTask, PoseChoice, PoseTask
from mmstab.planner.searches.exhaustive import ExhaustiveSearch
from mmstab.planner.under_arm import GroundUnderArm
from mmstab.workspace.roadmap import load_or_build_roadmap


class RoadmapSearch:
    """The whole path over the posture roadmap's component reachable from the stowed arm."""

    def choose(self, task: PoseTask) -> PoseChoice:
        """The exhaustive answer at a single pose."""
        return ExhaustiveSearch().choose(task)

    def choose_path(self, task: PathTask) -> PathChoice:
        """The chosen nodes' CoMs, postures and the roadmap moves into them."""
        if task.region.workspace is None:
            raise MmstabError("planner: method roadmap needs the labelled workspace V")
        roadmap = load_or_build_roadmap(task.robot, task.region.workspace)
        poses = np.zeros((len(task.gravity_body), 3)) if task.poses is None else task.poses
        under = None
        if task.terrain is not None and task.poses is not None:  # the ground under the arm
            margin = task.settings.attitude_margin or 0.0
            under = GroundUnderArm(task.robot, task.terrain, task.poses, margin=margin)
        elif task.settings.attitude_margin:
            raise MmstabError("planner.attitude_margin: needs a terrain and a route")
        climb = None
        if task.settings.climb and task.terrain is not None and task.poses is not None:
            climb = climb_plan(task.robot, task.terrain, task.poses, task.closed)
        polygons = None
        if task.terrain is not None and task.poses is not None:  # the loaded support
            polygons = support_polygons_at(task.robot, task.terrain, task.poses)
        seq = solve_roadmap_sequence(
            task.robot,
            task.gravity_body,
            roadmap,
            task.settings,
            task.mu_max,
            task.closed,
            poses,
            under=under,
            climb=climb,
            polygons=polygons,
        )
        return PathChoice(
            target_com=seq.com, postures=seq.postures, fitness=seq.fitness, mu=seq.mu,
            moves=seq.moves,
        )  # fmt: skip
