"""What every command's output shares: its folder, its saved settings, a route's corners."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from mmstab.core.files import write_yaml
from mmstab.core.problem import Problem


def output_dir(out: str | Path | None, name: str) -> Path:
    """``out`` if given, else ``results/<name>``; created."""
    d = Path(out) if out is not None else Path("results") / name
    d.mkdir(parents=True, exist_ok=True)
    return d


def save_settings(out_dir: Path, problem: Problem, **extra: Any) -> None:
    """Save everything the run depended on beside its results (``problem.yaml``)."""
    write_yaml(
        out_dir / "problem.yaml", {"source": str(problem.path), **problem.to_dict(), **extra}
    )


def route_corners(problem: Problem) -> dict[str, Any]:
    """``{"corners": [...]}``: how a route turns at each corner (arc or pivot), else ``{}``.

    The route check's account for a summary (``mmstab.paths.route.RoutePath.corners``).
    """
    route = problem.route
    return {} if route is None else {"corners": route.corners(), "pivots": route.report()}
