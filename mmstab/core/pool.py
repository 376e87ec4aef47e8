"""A small process pool that a Ctrl-C stops at once, workers included.

``concurrent.futures.ProcessPoolExecutor`` cannot stop a running worker: after a Ctrl-C it
waits for the chunks in flight, and killing its workers can leave its manager thread
waiting forever on a half-written result, so the interpreter never exits. This pool has
no threads: each worker owns one pipe, the parent waits on the pipes and on the workers'
sentinels, and on any exception (``KeyboardInterrupt`` included) it kills the workers and
returns at once. Workers ignore SIGINT (a Ctrl-C to the whole process group is the
parent's to handle). While they start, the parent's SIGINT handler only notes the signal
(so a worker forked meanwhile inherits a harmless handler) and the parent raises
``KeyboardInterrupt`` once they are up. SIGINT is never blocked: a blocked signal goes to
another thread (a BLAS thread), and CPython 3.11 then handles it late or not at all.
"""

from __future__ import annotations

import multiprocessing as mp
import signal
import threading
from collections.abc import Callable, Iterable, Iterator
from multiprocessing.connection import Connection, wait
from types import TracebackType
from typing import Any, cast

from mmstab.core.files import MmstabError

#: Set by :func:`note_interrupts`' SIGINT handler: a Ctrl-C came (it may have been swallowed).
INTERRUPTED = threading.Event()
#: Seconds to wait for a killed worker to be reaped.
JOIN_TIMEOUT = 1.0
#: The parent wakes at least this often [s] (pending signals are handled between waits).
POLL_SECONDS = 0.2


def _serve(conn: Connection, fn: Callable[..., Any], fixed: tuple[Any, ...]) -> None:
    """A worker: ``fn(*fixed, *task)`` for every task received, until ``None`` or EOF."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    while True:
        try:
            task = conn.recv()
        except (EOFError, OSError):
            return
        if task is None:
            return
        try:
            conn.send((True, fn(*fixed, *task)))
        except Exception as exc:  # noqa: BLE001 - handed to the parent, raised there
            conn.send((False, exc))


class ChunkPool:
    """``workers`` processes running ``fn(*fixed, *task)``; use as a context manager.

    Args:
        fn: a module-level function (picklable where processes are spawned).
        fixed: leading arguments, sent to each worker once.
        workers: number of processes.
    """

    def __init__(self, fn: Callable[..., Any], fixed: tuple[Any, ...], workers: int):
        self.fn, self.fixed, self.workers = fn, fixed, max(int(workers), 1)
        self._procs: list[Any] = []
        self._conns: list[Connection] = []

    def __enter__(self) -> ChunkPool:
        """Start the workers (a Ctrl-C meanwhile is raised once they are up)."""
        methods = mp.get_all_start_methods()
        ctx = mp.get_context("fork" if "fork" in methods else None)
        caught: list[int] = []
        old: Any = signal.getsignal(signal.SIGINT)
        try:
            signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
            noting = True
        except ValueError:  # not the main thread: signals are not ours to handle
            noting = False
        try:
            for _ in range(self.workers):
                parent, child = ctx.Pipe()
                proc = ctx.Process(target=_serve, args=(child, self.fn, self.fixed), daemon=True)
                proc.start()
                child.close()
                self._procs.append(proc)
                self._conns.append(parent)
        except BaseException:
            self._kill()
            raise
        finally:
            if noting:
                signal.signal(signal.SIGINT, old if old is not None else signal.SIG_DFL)
        if caught:
            self._kill()
            raise KeyboardInterrupt
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        """Stop the workers: politely after success, killed after any exception."""
        if exc_type is None:
            for conn in self._conns:
                try:
                    conn.send(None)
                except OSError:
                    pass
            for proc in self._procs:
                proc.join(JOIN_TIMEOUT)
        self._kill()

    def _kill(self) -> None:
        for proc in self._procs:
            if proc.is_alive():
                proc.kill()
        for proc in self._procs:
            proc.join(JOIN_TIMEOUT)
        for conn in self._conns:
            conn.close()
        self._procs, self._conns = [], []

    def run(self, tasks: Iterable[tuple[Any, ...]]) -> Iterator[Any]:
        """Results of every task, in completion order.

        Raises:
            MmstabError: a worker died (killed by the system, out of memory).
            Exception: whatever a task raised, re-raised here.
        """
        pending = iter(tasks)
        busy: dict[Connection, Any] = {}  # connection -> its worker
        for proc, conn in zip(self._procs, self._conns, strict=True):
            task = next(pending, None)
            if task is None:
                break
            conn.send(task)
            busy[conn] = proc
        while busy:
            sentinels: dict[Any, Connection] = {p.sentinel: c for c, p in busy.items()}
            for ready in wait([*busy, *sentinels], timeout=POLL_SECONDS):
                conn = sentinels[ready] if ready in sentinels else cast(Connection, ready)
                if conn not in busy:
                    continue
                if not conn.poll():
                    if ready in sentinels:  # exited with no answer
                        raise MmstabError(
                            f"a worker process died (exit code {busy[conn].exitcode}); "
                            "out of memory?"
                        )
                    continue
                try:
                    ok, value = conn.recv()
                except EOFError:
                    raise MmstabError("a worker process died while answering") from None
                if not ok:
                    raise value
                task = next(pending, None)
                if task is None:
                    del busy[conn]
                else:
                    conn.send(task)
                yield value


def run_interruptibly(fn: Callable[..., Any], *args: Any) -> Any:
    """``fn(*args)`` in a helper thread, the caller waiting in short slices.

    For long C calls that release the GIL but never check for signals (a k-d tree of
    millions of points): a Ctrl-C raises ``KeyboardInterrupt`` here within
    :data:`POLL_SECONDS`; the abandoned call finishes (or dies with the process) in its
    daemon thread. Exceptions of ``fn`` are raised here.
    """
    box: dict[str, Any] = {}

    def target() -> None:
        try:
            box["value"] = fn(*args)
        except BaseException as exc:  # noqa: BLE001 - handed to the caller
            box["error"] = exc

    thread = threading.Thread(target=target, name=f"mmstab-{getattr(fn, '__name__', 'call')}")
    thread.daemon = True
    thread.start()
    while thread.is_alive():
        thread.join(POLL_SECONDS)
    if "error" in box:
        raise box["error"]
    return box["value"]


def _on_sigint(signum: int, frame: Any) -> None:
    INTERRUPTED.set()
    raise KeyboardInterrupt


def note_interrupts() -> Any:
    """Install a SIGINT handler that remembers the Ctrl-C besides raising ``KeyboardInterrupt``.

    Some C code asks Python for pending signals and swallows the ``KeyboardInterrupt``
    (CasADi's IPOPT interface stops the solve with ``NonIpopt_Exception_Thrown`` and goes
    on); :func:`raise_if_interrupted` after such a call raises it again. Main thread only.

    Returns:
        The previous handler (to restore).
    """
    INTERRUPTED.clear()
    return signal.signal(signal.SIGINT, _on_sigint)


def raise_if_interrupted() -> None:
    """Raise ``KeyboardInterrupt`` if a Ctrl-C was noted (see :func:`note_interrupts`)."""
    if INTERRUPTED.is_set():
        raise KeyboardInterrupt
