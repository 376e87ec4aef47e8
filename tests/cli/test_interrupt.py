"""Ctrl-C at any moment: exit 130 within 2 s, workers included, nothing half-written.

Each command runs as a subprocess in its own session; the test waits for a marker on its
stderr (the progress bar of the stage to interrupt, or the time estimate announced before
it), then sends SIGINT to the process alone or to its whole process group (what a
terminal's Ctrl-C does).
"""

from __future__ import annotations

import os
import selectors
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import write_problem

#: Longest a command may take to end after SIGINT [s].
LIMIT_S = 2.0
#: Longest wait for both runs to end [s] (a generous bound on a loaded 2-core machine).
MARKER_TIMEOUT_S = 60.0


def _start(args: list[str], cwd: Path) -> subprocess.Popen[bytes]:
    env = {**os.environ, "MPLBACKEND": "Agg", "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen(
        [sys.executable, "-m", "mmstab", *args],
        cwd=cwd,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        start_new_session=True,
    )


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


def _no_partial_files(folder: Path) -> None:
    if folder.exists():
        leftovers = [p.name for p in folder.rglob(".*") if p.is_file()]
        assert leftovers == [], leftovers  # atomic writers' temp files are removed


def _both(args: list[str], cwd: Path, marker: bytes, settle: float = 0.0) -> list[str]:
    """Run the command twice at once; SIGINT one to its process, one to its group.

    Each gets its signal ``settle`` seconds after its ``marker`` appears on its stderr.

    Returns:
        The stderr of each, after asserting exit 130 within ``LIMIT_S`` of the signal, no
        traceback and no process of the group left.
    """
    procs = [_start(args, cwd / f"run{k}") for k in range(2)]
    seen, sent, ended = [b"", b""], [0.0, 0.0], [0.0, 0.0]
    sel = selectors.DefaultSelector()
    for k, proc in enumerate(procs):
        assert proc.stderr is not None
        sel.register(proc.stderr, selectors.EVENT_READ, k)
    deadline = time.monotonic() + MARKER_TIMEOUT_S
    try:
        while not all(ended):
            assert time.monotonic() < deadline, f"no end: {seen[0][-300:]!r} {seen[1][-300:]!r}"
            for key, _ in sel.select(timeout=0.02):
                chunk = os.read(key.fd, 65536)
                seen[key.data] += chunk
                if not chunk:
                    sel.unregister(key.fileobj)
            for k, proc in enumerate(procs):
                if not sent[k] and marker in seen[k]:
                    assert proc.poll() is None, f"ended before the signal: {seen[k][-300:]!r}"
                    time.sleep(settle)
                    if k == 1:
                        os.killpg(proc.pid, signal.SIGINT)
                    else:
                        proc.send_signal(signal.SIGINT)
                    sent[k] = time.monotonic()
                if sent[k] and not ended[k] and proc.poll() is not None:
                    ended[k] = time.monotonic()
                assert sent[k] or proc.poll() is None, f"ended early: {seen[k][-300:]!r}"
    finally:
        for proc in procs:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        sel.close()
    errs = []
    for k, proc in enumerate(procs):
        assert proc.stderr is not None
        err = (seen[k] + proc.stderr.read()).decode(errors="replace")
        assert proc.returncode == 130, (k, err[-500:])
        assert ended[k] - sent[k] < LIMIT_S, (k, ended[k] - sent[k])
        assert err.rstrip().endswith("mmstab: interrupted") and "Traceback" not in err, err
        limit = time.monotonic() + LIMIT_S
        while _group_alive(proc.pid) and time.monotonic() < limit:
            time.sleep(0.02)
        assert not _group_alive(proc.pid), "worker processes outlived the command"
        errs.append(err)
    return errs


@pytest.mark.slow
def test_workspace_build_stops_with_its_workers(tmp_path):
    path = write_problem(
        tmp_path, lambda p, r: p["workspace"].__setitem__("grid", [24, 29, 25, 25])
    )
    for k in range(2):
        (tmp_path / f"run{k}").mkdir()
    # the progress bar: the pool is up and labelling
    _both(["workspace", str(path), "-o", "ws"], tmp_path, b"workspace:")
    for k in range(2):
        cache = tmp_path / f"run{k}" / "ws"
        assert not (cache.exists() and list(cache.glob("*.npz")))  # no cache written
        _no_partial_files(cache)
    # the next run recovers: builds the same cache from nothing
    from mmstab.core.problem import load_problem
    from mmstab.workspace import load_or_build_workspace, workspace_cache_path

    problem = load_problem(path)
    cache = tmp_path / "run1" / "ws"
    ws = load_or_build_workspace(problem, progress=False, cache_dir=cache)
    assert ws.postures == 24 * 29 * 25 * 25
    assert workspace_cache_path(problem, cache).is_file()


def _planner_problem(p, r):
    p["workspace"]["grid"] = [10, 8, 8, 8]
    p["planner"]["poses"] = 400  # about a minute: its time estimate is announced first


@pytest.mark.slow
def test_planner_stops(tmp_path):
    path = write_problem(tmp_path, _planner_problem)
    for k in range(2):
        (tmp_path / f"run{k}").mkdir()
    # after the announced estimate, 0.3 s into the CMA-ES runs (the small V takes ~0.1 s)
    _both(["plan", str(path), "-o", "plan"], tmp_path, b"mmstab: planner.poses:", settle=0.3)
    for k in range(2):
        out = tmp_path / f"run{k}" / "plan"
        assert not (out / "summary.json").exists()
        _no_partial_files(out)


def _tracking_problem(p, r):
    p["workspace"]["grid"] = [10, 8, 8, 8]
    p["planner"]["poses"] = 4
    p["controller"]["duration"] = 20.0  # the loop runs ~1 s: the signal lands in it


@pytest.mark.slow
def test_tracking_run_stops(tmp_path):
    path = write_problem(tmp_path, _tracking_problem)
    for k in range(2):
        (tmp_path / f"run{k}").mkdir()
    _both(["track", str(path), "-o", "track"], tmp_path, b"tracking:")  # the control loop
    for k in range(2):
        out = tmp_path / f"run{k}" / "track"
        assert not (out / "summary.json").exists()
        _no_partial_files(out)


def test_an_open_progress_bar_is_closed_before_the_verdict(monkeypatch, capsys):
    """A bar the interrupt leaves open is drawn again when it is freed: before the last line."""
    import gc

    from tqdm import tqdm

    import mmstab.cli as cli

    def interrupted(args):
        bar = tqdm(total=10, desc="workspace", file=sys.stderr)
        bar.update(3)
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "_run", interrupted)
    assert cli.main(["workspace", "problems/ramp.yaml"]) == 130
    gc.collect()  # the unwound frames are freed: an open bar would close (and draw) now
    err = capsys.readouterr().err
    assert "workspace" in err and err.rstrip().endswith("mmstab: interrupted")
