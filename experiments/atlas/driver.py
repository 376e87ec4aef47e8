"""Running atlas chunks on a Dask cluster: a local one by default, or one at an address.

The client scatters each variant's payload (robot + workspace V) to every worker once,
then keeps a bounded window of chunk tasks in flight (two per worker thread), storing
each result as it arrives (:meth:`AtlasStore.write_chunk` on the client, so workers need
no shared file system). Ctrl-C cancels what is in flight; the chunks already stored stay.

Default local cluster: one single-threaded worker *process* per available core. The
planner is Python-heavy (pycma) and holds the GIL, so threads do not scale; the
measurement is ``make bench-atlas`` (``results/bench/atlas.json``, docs/atlas.md).
"""

from __future__ import annotations

import contextlib
import itertools
import logging
import os
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import dask
from tqdm import tqdm

from experiments.atlas.cell import ChunkResult, ChunkTask, VariantPayload, compute_chunk
from mmstab.core.files import MmstabError

#: Seconds to wait for an existing scheduler to answer.
CONNECT_TIMEOUT = 15.0
#: A run that gets no chunk back for this long submits its outstanding chunks again [s]
#: (a rare stall leaves workers idle with one chunk outstanding: seen once, its worker held
#: no copy of the scattered variants, its fetch of one from the peer ended in state
#: "error", and the chunk waited on it for ever; see docs/atlas.md). Before the first
#: chunk is back ...
STALL_SECONDS = 60.0
#: ... after it, this many times the slowest chunk so far, but at least STALL_MIN_SECONDS.
STALL_FACTOR = 4.0
STALL_MIN_SECONDS = 15.0
#: The run gives up with one line after this many times max(STALL_SECONDS, the current
#: patience) without a chunk back (a slow chunk is resubmitted, never given up on early).
MAX_STALLS = 3
#: Dask settings of the local cluster's workers. Measured per cell on one worker process
#: (``docs/atlas.md``): Dask's default ``MALLOC_TRIM_THRESHOLD_=65536`` (glibc returns
#: freed memory at once, so the planner's many small NumPy temporaries page-fault) and the
#: worker's statistical profiler (10 ms stack samples of a Python-bound task) made a cell
#: 0.14 s instead of 0.08 s. Give the same to ``dask worker`` (docs/atlas.md).
WORKER_CONFIG = {
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": 128 * 2**20,
    "distributed.worker.profile.enabled": False,
}


class RunStats(NamedTuple):
    """What one run of the driver did.

    Attributes:
        chunks: chunks computed and stored.
        cells: cells computed and stored.
        seconds: wall time from the first submission to the last result [s].
        workers: worker processes of the cluster.
        threads: worker threads in all.
    """

    chunks: int
    cells: int
    seconds: float
    workers: int
    threads: int

    @property
    def cells_per_second(self) -> float:
        """Throughput of the run [cells/s] (0 when nothing ran)."""
        return self.cells / self.seconds if self.seconds > 0 else 0.0


def available_cores() -> int:
    """Cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


@contextlib.contextmanager
def dask_client(
    scheduler: str | None = None, workers: int | None = None, processes: bool = True
) -> Iterator[Any]:
    """A ``distributed.Client``: to ``scheduler`` if given, else to a new local cluster.

    Args:
        scheduler: address of a running scheduler (``tcp://host:8786``), or None.
        workers: local cluster only: worker processes (threads when ``processes`` is
            False); default one per available core.
        processes: local cluster only: one single-threaded process per worker (default),
            or one process with ``workers`` threads.

    Raises:
        MmstabError: the scheduler cannot be reached.
    """
    from distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT)
        except (OSError, TimeoutError, ValueError) as exc:
            raise MmstabError(f"cannot reach the Dask scheduler at {scheduler} ({exc})") from None
        with client:
            yield client
        return
    n = workers if workers is not None else available_cores()
    if n < 1:
        raise MmstabError(f"--workers must be at least 1, got {n}")
    with (
        dask.config.set(WORKER_CONFIG),
        LocalCluster(
            n_workers=n if processes else 1,
            threads_per_worker=1 if processes else n,
            processes=processes,
            dashboard_address=None,
            silence_logs=logging.CRITICAL,
        ) as cluster,
        Client(cluster) as client,
    ):
        # every worker registered before the variants are scattered to "all" of them (a
        # worker that registers later gets no copy and must fetch each from a peer)
        client.wait_for_workers(n if processes else 1, timeout=CONNECT_TIMEOUT * 4)
        yield client


def cluster_size(client: Any) -> tuple[int, int]:
    """(worker processes, threads in all) of the client's cluster."""
    threads = client.nthreads()
    return len(threads), int(sum(threads.values()))


def run_chunks(
    client: Any,
    payloads: Sequence[VariantPayload],
    tasks: Sequence[ChunkTask],
    on_result: Callable[[ChunkResult], None],
    progress: bool = True,
    total_cells: int | None = None,
    done_cells: int = 0,
) -> RunStats:
    """Compute ``tasks`` on the cluster, handing each result to ``on_result`` as it comes.

    Args:
        client: a ``distributed.Client``.
        payloads: one per variant that has tasks.
        tasks: the chunks to compute.
        on_result: called on the client for each computed chunk (stores it).
        progress: show a progress bar (cells, cells per second).
        total_cells: the whole atlas's cells, for the bar (default: the tasks' cells).
        done_cells: cells already stored before this run, for the bar.
    """
    from distributed import TimeoutError as DaskTimeoutError
    from distributed import wait

    workers, threads = cluster_size(client)
    if workers == 0:
        raise MmstabError("the Dask cluster has no workers")
    futures = client.scatter(list(payloads), broadcast=True)
    by_variant = {p.position: f for p, f in zip(payloads, futures, strict=True)}
    window = max(2, 2 * threads)
    pending = iter(tasks)
    todo = sum(t.block.cells for t in tasks)
    total = total_cells if total_cells is not None else todo

    t0 = time.perf_counter()
    bar = tqdm(total=total, initial=done_cells, unit="cell", disable=not progress, desc="atlas")
    flight = InFlight(client, by_variant, pending, on_result, bar)
    for task in itertools.islice(pending, window):
        flight.launch(task)
    try:
        while flight.active:
            try:
                finished = wait(
                    list(flight.active), timeout=flight.patience, return_when="FIRST_COMPLETED"
                )
            except DaskTimeoutError:
                flight.resubmit()
                continue
            for future in finished.done:
                flight.take(future)
    except BaseException:
        client.cancel(list(flight.active))
        raise
    finally:
        bar.close()
        client.cancel(futures)
    return RunStats(flight.chunks, flight.cells, time.perf_counter() - t0, workers, threads)


@dataclass
class InFlight:
    """The window of chunks in flight on the cluster and what has come back.

    Attributes:
        client: the ``distributed.Client``.
        by_variant: the scattered payload of each (robot, flipper, payload) index.
        pending: the chunks not submitted yet.
        on_result: called on each chunk back (stores it).
        bar: the progress bar (cells).
        active: future -> its chunk, for every chunk in flight.
        stored: the chunks back (``repr`` of their block): a resubmitted twin is dropped.
        patience: seconds without a chunk back before resubmitting [s].
        last_back: ``time.perf_counter()`` when the last chunk came back [s].
        chunks: chunks back.
        cells: cells back.
    """

    client: Any
    by_variant: dict[Any, Any]
    pending: Iterator[ChunkTask]
    on_result: Callable[[ChunkResult], None]
    bar: Any
    active: dict[Any, ChunkTask] = field(default_factory=dict)
    stored: set[str] = field(default_factory=set)
    patience: float = STALL_SECONDS
    last_back: float = field(default_factory=time.perf_counter)
    chunks: int = 0
    cells: int = 0

    def launch(self, task: ChunkTask) -> None:
        """Submit ``task`` with its variant's payload."""
        variant = self.by_variant[task.block.variant[:3]]  # V is per robot x flipper x payload
        self.active[self.client.submit(compute_chunk, variant, task, pure=False)] = task

    def resubmit(self) -> None:
        """No chunk came back within ``patience``: submit the outstanding ones again.

        Cells are deterministic, so whichever copy answers first is the same. After
        ``MAX_STALLS`` times the patience without a chunk back, the run gives up.
        """
        quiet = time.perf_counter() - self.last_back
        if quiet > MAX_STALLS * max(STALL_SECONDS, self.patience):
            raise MmstabError(f"the Dask cluster returned no chunk for {quiet:.0f} s") from None
        for task in list(self.active.values()):
            self.launch(task)

    def take(self, future: Any) -> None:
        """Store the chunk of a finished ``future`` (once), drop its twins, launch the next."""
        task = self.active.pop(future)
        key = repr(task.block)
        if key in self.stored:
            return
        result = future.result()
        self.last_back = time.perf_counter()
        self.patience = max(
            STALL_MIN_SECONDS,
            STALL_FACTOR * result.seconds,
            self.patience if self.chunks else 0.0,
        )
        self.stored.add(key)
        self.on_result(result)
        self.chunks += 1
        self.cells += result.block.cells
        self.bar.update(result.block.cells)
        twins = [f for f, t in self.active.items() if repr(t.block) == key]
        for f in twins:  # a resubmitted copy of a chunk already stored
            self.active.pop(f)
        self.client.cancel(twins)
        nxt = next(self.pending, None)
        if nxt is not None:
            self.launch(nxt)
