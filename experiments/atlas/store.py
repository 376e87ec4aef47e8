"""The atlas's chunked Zarr store (through xarray): created whole, filled chunk by chunk.

Layout (``DIR/atlas.zarr``), dims ``robot x flipper x payload x terrain x slope x
heading`` with the axes as coordinates (robot name, flipper label, payload [kg], terrain
label, slope [rad], heading [rad]); variables

- ``mu_planned``, ``mu_stowed``, ``mu_arm_removed`` [N rad], ``planner_seconds`` [s];
- ``arm_com`` [m] (extra dim ``xyz``): the planner's arm CoM in the body frame;
- ``flipper_angle`` [rad] per (robot, flipper), ``mu_max`` [N rad] per (robot, flipper,
  payload), ``terrain_seed`` per terrain (-1: the ramp);
- ``chunk_done`` (robot, flipper, payload, terrain, slope_block, heading_block): 1 once a
  chunk is stored.

A store is created in a temporary folder and renamed into place, so it exists whole or
not at all. A chunk is stored by region writes of its cells (one Zarr chunk per variable,
each file written atomically by Zarr) and then its ``chunk_done`` marker; Ctrl-C is
held back until both are written. A chunk whose marker is 0 is missing and recomputed on
the next run, whatever its cells hold. ``attrs['atlas_key']`` ties the store to the
atlas that made it: a store of another atlas is never resumed.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from experiments.atlas.cell import ChunkResult
from experiments.atlas.spec import AtlasSpec, Block
from mmstab.core.files import MmstabError

VARIANT_DIMS = ("robot", "flipper", "payload", "terrain")
DIMS = (*VARIANT_DIMS, "slope", "heading")
BLOCK_DIMS = (*VARIANT_DIMS, "slope_block", "heading_block")
#: Per-cell variables: name -> (unit, description).
CELL_VARIABLES = {
    "mu_planned": ("N rad", "force-angle measure at the planner's arm CoM"),
    "mu_stowed": ("N rad", "force-angle measure with the arm stowed"),
    "mu_arm_removed": ("N rad", "force-angle measure of the base alone (arm removed)"),
    "planner_seconds": ("s", "planner wall time of the cell"),
}


def _xr() -> Any:
    import xarray

    return xarray


def template(spec: AtlasSpec, mu_max: np.ndarray) -> Any:
    """The empty store as an ``xarray.Dataset`` (cells NaN, no chunk done).

    Args:
        spec: the atlas.
        mu_max: Eq. 6 normaliser per (robot, flipper, payload) [N rad].
    """
    xr = _xr()
    shape = spec.shape
    nb = spec.block_shape
    data: dict[str, Any] = {}
    for name, (unit, what) in CELL_VARIABLES.items():
        data[name] = xr.Variable(DIMS, np.full(shape, np.nan), {"units": unit, "long_name": what})
    data["arm_com"] = xr.Variable(
        (*DIMS, "xyz"),
        np.full((*shape, 3), np.nan),
        {"units": "m", "long_name": "planner's arm CoM, body frame"},
    )
    angles = np.array([v.flipper_angle for v in spec.variants]).reshape(shape[:3])[:, :, 0]
    data["flipper_angle"] = xr.Variable(("robot", "flipper"), angles, {"units": "rad"})
    data["mu_max"] = xr.Variable(("robot", "flipper", "payload"), mu_max, {"units": "N rad"})
    seeds = np.array([t.seed for t in spec.terrains])
    data["terrain_seed"] = xr.Variable("terrain", seeds, {"long_name": "generator seed, -1 ramp"})
    data["chunk_done"] = xr.Variable(BLOCK_DIMS, np.zeros((*shape[:4], *nb), dtype=np.int8))
    coords = {
        "robot": list(spec.robot_labels),
        "flipper": list(spec.flipper_labels),
        "payload": xr.Variable(
            "payload", spec.payloads, {"units": "kg", "long_name": "payload at the wrist"}
        ),
        "terrain": list(spec.terrain_labels),
        "slope": xr.Variable("slope", spec.slopes, {"units": "rad"}),
        "heading": xr.Variable(
            "heading", spec.headings, {"units": "rad", "long_name": "0 across, pi/2 uphill"}
        ),
        "xyz": ["x", "y", "z"],
    }
    attrs = {
        "atlas_key": spec.key(),
        "chunks": list(spec.chunks),
        "payload_com_wrist_m": spec.payload_com.tolist(),
    }
    return xr.Dataset(data, coords=coords, attrs=attrs)


def _encoding(spec: AtlasSpec) -> dict[str, dict[str, Any]]:
    cs, ch = spec.chunks
    one = (1,) * len(VARIANT_DIMS)
    enc: dict[str, dict[str, Any]] = {n: {"chunks": (*one, cs, ch)} for n in CELL_VARIABLES}
    enc["arm_com"] = {"chunks": (*one, cs, ch, 3)}
    enc["chunk_done"] = {"chunks": (*one, 1, 1)}
    return enc


@contextlib.contextmanager
def deferred_interrupt() -> Iterator[None]:
    """Hold back Ctrl-C (SIGINT) until the block ends, then raise it (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[Any] = []
    previous = signal.signal(signal.SIGINT, lambda *a: caught.append(a))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if caught:
            raise KeyboardInterrupt


class AtlasStore:
    """An atlas store on disk (see the module docstring)."""

    def __init__(self, path: str | os.PathLike[str], spec: AtlasSpec):
        self.path = Path(path)
        self.spec = spec

    @classmethod
    def open_or_create(
        cls, path: str | os.PathLike[str], spec: AtlasSpec, mu_max: np.ndarray
    ) -> AtlasStore:
        """Open the store at ``path`` if it holds this atlas, else create it (atomically).

        Raises:
            MmstabError: ``path`` holds something else (another atlas or not a store).
        """
        store = cls(path, spec)
        if store.path.exists():
            store.check()
            return store
        store.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(dir=store.path.parent, prefix=f".{store.path.name}."))
        try:
            template(spec, mu_max).to_zarr(
                tmp, mode="w", encoding=_encoding(spec), consolidated=False, zarr_format=2
            )
            os.replace(tmp, store.path)
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
        return store

    def open(self) -> Any:
        """The store as a lazy ``xarray.Dataset``."""
        # chunks=None: plain lazy arrays, read here; dask arrays would be computed on the
        # active distributed client, whose workers may be busy or gone (seen to hang)
        return _xr().open_zarr(self.path, consolidated=False, chunks=None)

    def check(self) -> None:
        """Raise unless the store was made by this atlas (same ``atlas_key``)."""
        try:
            key = self.open().attrs.get("atlas_key")
        except Exception as exc:  # any reading failure: not an atlas store
            raise MmstabError(f"{self.path}: not an atlas store ({type(exc).__name__})") from None
        if key != self.spec.key():
            raise MmstabError(
                f"{self.path}: holds another atlas (axes, robots or planner changed); "
                f"use another output folder (-o) or remove it"
            )

    def done(self) -> np.ndarray:
        """The chunk markers (robot, flipper, payload, terrain, slope_block, heading_block)."""
        with self.open() as ds:
            return ds["chunk_done"].values.astype(bool)

    def missing(self) -> list[Block]:
        """The blocks without a completion marker, in the atlas's order."""
        done = self.done()
        return [b for b in self.spec.blocks() if not done[(*b.variant, *b.block)]]

    def runs(self) -> list[dict[str, Any]]:
        """The log of the runs that filled the store (``attrs['runs']``)."""
        with self.open() as ds:
            return list(ds.attrs.get("runs", []))

    def log_run(self, run: dict[str, Any]) -> None:
        """Append one run's statistics to ``attrs['runs']`` (Ctrl-C deferred)."""
        import zarr

        with deferred_interrupt():
            group = zarr.open_group(self.path, mode="r+")
            runs: list[Any] = list(group.attrs.get("runs", []))  # type: ignore[arg-type]
            group.attrs["runs"] = [*runs, run]

    def write_chunk(self, result: ChunkResult) -> None:
        """Store a computed chunk: its cells, then its completion marker (Ctrl-C deferred)."""
        xr = _xr()
        b = result.block
        at = {d: slice(i, i + 1) for d, i in zip(VARIANT_DIMS, b.variant, strict=True)}
        region = {**at, "slope": b.slope, "heading": b.heading}
        lead = (None,) * len(VARIANT_DIMS)
        cells: dict[str, tuple[tuple[str, ...], Any]] = {
            n: (DIMS, getattr(result, n)[lead]) for n in CELL_VARIABLES
        }
        cells["arm_com"] = ((*DIMS, "xyz"), result.arm_com[lead])
        ones = np.ones((1,) * len(BLOCK_DIMS), dtype=np.int8)
        marker = {"chunk_done": (BLOCK_DIMS, ones)}
        bs, bh = b.block
        block_region = {**at, "slope_block": slice(bs, bs + 1), "heading_block": slice(bh, bh + 1)}
        with deferred_interrupt():
            xr.Dataset(cells).to_zarr(
                self.path, region={**region, "xyz": slice(0, 3)}, consolidated=False
            )
            xr.Dataset(marker).to_zarr(self.path, region=block_region, consolidated=False)
