"""``python -m experiments atlas``: spec -> workspaces -> store -> Dask run -> figures.

A rerun with the same problem and output folder resumes: only chunks without a
completion marker are computed. Figures and ``summary.json`` are written once every
chunk is stored.
"""

from __future__ import annotations

import sys
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from experiments.atlas.cell import ChunkResult, ChunkTask, VariantPayload
from experiments.atlas.driver import RunStats, dask_client, run_chunks
from experiments.atlas.figures import envelope_figure, heatmap_figure, summary
from experiments.atlas.spec import AtlasSpec, Block, Variant, atlas_spec
from experiments.atlas.store import AtlasStore
from mmstab.core.files import write_json
from mmstab.core.problem import Problem
from mmstab.stability.static import mu_max

#: The store's folder name inside the output folder.
STORE_NAME = "atlas.zarr"


def variant_workspace(
    variant: Variant, grid: tuple[int, ...], progress: bool, cache_dir: Path | None = None
) -> Any:
    """The variant's workspace V from the workspace cache, built (and cached) if absent.

    Args:
        variant: the robot variant.
        grid: joint grid of V.
        progress: show the build's progress bar.
        cache_dir: cache folder (default mmstab's, as ``mmstab workspace``).
    """
    from mmstab.workspace import (
        build_workspace,
        default_cache_dir,
        load_workspace,
        save_workspace,
        workspace_key,
    )

    folder = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    path = folder / f"{workspace_key(variant.robot, grid)}.npz"
    if path.is_file():
        try:
            return load_workspace(path)
        except (OSError, ValueError, KeyError):
            pass  # stale or unreadable: rebuild
    ws = build_workspace(variant.robot, grid, progress=progress)
    save_workspace(path, ws)
    return ws


def payload(
    spec: AtlasSpec, variant: Variant, progress: bool, cache_dir: Path | None = None
) -> VariantPayload:
    """What the workers need for one variant (its workspace loaded or built here).

    A payload changes the arm's masses and so V: each payload is a variant with its own V,
    loaded from the workspace cache or built once here (then cached), and scattered once to
    every worker.
    """
    import dataclasses

    ws = variant_workspace(variant, spec.workspace_grid, progress, cache_dir)
    if len(ws.valid_com_in_V) == 0:
        raise_empty(spec, variant)
    key = f"{variant.robot.source_hash}|{spec.workspace_grid}|{spec.settings}"
    light = dataclasses.replace(variant.robot)  # without cached CasADi kinematics
    return VariantPayload(key, variant.position, light, ws, spec.settings)


def raise_empty(spec: AtlasSpec, variant: Variant) -> None:
    """Refuse a variant whose workspace V is empty."""
    from mmstab.core.files import MmstabError

    raise MmstabError(
        f"{spec.path}: atlas: the workspace V of {variant.robot_label} "
        f"(flippers {variant.flipper_label}, payload {variant.payload_kg:g} kg) is empty; "
        "no arm CoM can be planned"
    )


def write_outputs(store: AtlasStore, out: Path, run: dict[str, Any]) -> dict[str, Any]:
    """Figures and ``summary.json`` from a complete store (margin: the section's, now)."""
    with store.open() as lazy, warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN envelopes
        ds = lazy.load()
        ds.attrs["margin"] = store.spec.margin
        ds.attrs["friction"] = store.spec.friction
        run = {**run, "history": list(ds.attrs.get("runs", []))}
        s = summary(ds, run)
        heatmap_figure(ds, out / "mu_polar.png")
        envelope_figure(ds, out / "envelope.png")
    write_json(out / "summary.json", s)
    return s


def run_atlas(
    problem: Problem,
    out: str | Path | None = None,
    scheduler: str | None = None,
    workers: int | None = None,
    processes: bool = True,
    progress: bool = True,
    on_chunk: Callable[[ChunkResult], None] | None = None,
    figures: bool = True,
    workspace_cache: Path | None = None,
) -> dict[str, Any]:
    """Compute (or resume) the problem's atlas and write its figures and summary.

    Args:
        problem: a problem with an ``atlas`` section.
        out: output folder (default ``results/atlas``); the store is ``OUT/atlas.zarr``.
        scheduler: address of a running Dask scheduler; default a new local cluster.
        workers: local cluster size (default one process per core).
        processes: local cluster of processes (default) or of threads in one process.
        progress: show progress bars.
        on_chunk: called after each chunk is stored (tests interrupt runs with it).
        figures: write figures and ``summary.json`` at the end.
        workspace_cache: workspace cache folder (default mmstab's).

    Returns:
        The summary (``run`` holds this invocation's statistics).
    """
    from mmstab.outputs.common import output_dir, save_settings

    spec = atlas_spec(problem)
    d = output_dir(out, "atlas")
    mu_maxes = np.array([mu_max(v.robot) for v in spec.variants]).reshape(spec.shape[:3])
    store = AtlasStore.open_or_create(d / STORE_NAME, spec, mu_maxes)
    save_settings(d, problem)
    missing = store.missing()
    stored_cells = spec.cells - sum(b.cells for b in missing)
    stats = RunStats(0, 0, 0.0, 0, 0)
    if missing:
        cluster = Cluster(scheduler, workers, processes)
        stats = compute_missing(
            spec, store, missing, cluster, progress, on_chunk, workspace_cache, stored_cells
        )
    run = {**_run_record(scheduler, stats), "cells_already_stored": stored_cells}
    if stats.cells:
        store.log_run(run)
    if not figures:
        return {"run": run}
    return write_outputs(store, d, run)


class Cluster(NamedTuple):
    """Where the chunks run (:func:`experiments.atlas.driver.dask_client`).

    Attributes:
        scheduler: address of a running Dask scheduler; None = a new local cluster.
        workers: local cluster size (None = one process per core).
        processes: local cluster of processes (True) or of threads in one process.
    """

    scheduler: str | None
    workers: int | None
    processes: bool


def compute_missing(
    spec: AtlasSpec,
    store: AtlasStore,
    missing: list[Block],
    cluster: Cluster,
    progress: bool,
    on_chunk: Callable[[ChunkResult], None] | None,
    workspace_cache: Path | None,
    stored_cells: int,
) -> RunStats:
    """Compute the ``missing`` chunks on the cluster and store each as it comes back.

    An interrupted run (Ctrl-C) logs what it stored and says how to resume, then re-raises.
    """
    needed = sorted({b.variant[:3] for b in missing})
    tasks = [
        ChunkTask(b, spec.slopes[b.slope], spec.headings[b.heading], spec.terrains[b.variant[3]])
        for b in missing
    ]

    written = [0, 0]  # chunks, cells stored by this run (for an interrupted run's log)

    def on_result(result: ChunkResult) -> None:
        store.write_chunk(result)
        written[0] += 1
        written[1] += result.block.cells
        if on_chunk is not None:
            on_chunk(result)

    t0 = time.perf_counter()
    try:
        with dask_client(*cluster) as client:
            # V of each variant, loaded or built once the cluster answers
            payloads = [payload(spec, spec.variant(i), progress, workspace_cache) for i in needed]
            return run_chunks(
                client,
                payloads,
                tasks,
                on_result,
                progress=progress,
                total_cells=spec.cells,
                done_cells=stored_cells,
            )
    except KeyboardInterrupt:
        partial = RunStats(written[0], written[1], time.perf_counter() - t0, 0, 0)
        store.log_run({**_run_record(cluster.scheduler, partial), "interrupted": True})
        left = len(store.missing())
        print(
            f"atlas: interrupted; {left} of {len(spec.blocks())} chunks left in "
            f"{store.path}; rerun the same command to resume",
            file=sys.stderr,
        )
        raise


def _run_record(scheduler: str | None, stats: RunStats) -> dict[str, Any]:
    return {
        "scheduler": scheduler or "local",
        "workers": stats.workers,
        "threads": stats.threads,
        "chunks_computed": stats.chunks,
        "cells_computed": stats.cells,
        "seconds": round(stats.seconds, 3),
        "cells_per_second": round(stats.cells_per_second, 3),
    }
