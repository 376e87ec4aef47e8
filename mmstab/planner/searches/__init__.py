"""The registry of the planner's searches: ``planner.method`` -> search.

Each search is one module of this package implementing :class:`mmstab.planner.searches.base.
PoseSearch` (and :class:`~mmstab.planner.searches.base.PathSearch` when it chooses the whole path
at once); adding one is that module and its line below (and its name in the schema's
``planner.method``, :data:`mmstab.core.schema.PLANNER_METHODS`, which a test keeps equal to
this registry). ``docs/planner.md``, "Adding a search".
"""

from __future__ import annotations

from mmstab.core.files import MmstabError
from mmstab.planner.searches.base import PathSearch, PoseSearch
from mmstab.planner.searches.cmaes import CmaesSearch
from mmstab.planner.searches.exhaustive import ExhaustiveSearch
from mmstab.planner.searches.roadmap import RoadmapSearch
from mmstab.planner.searches.sequence import SequenceSearch

#: ``planner.method`` -> its search.
SEARCHES: dict[str, PoseSearch | PathSearch] = {
    "cmaes": CmaesSearch(),
    "exhaustive": ExhaustiveSearch(),
    "sequence": SequenceSearch(),
    "roadmap": RoadmapSearch(),
}


def search_for(method: str) -> PoseSearch | PathSearch:
    """The registered search of ``planner.method``.

    Raises:
        MmstabError: no search of that name.
    """
    try:
        return SEARCHES[method]
    except KeyError:
        raise MmstabError(
            f"planner.method: no search {method!r}; registered: {', '.join(SEARCHES)}"
        ) from None
