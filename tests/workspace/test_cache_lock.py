"""One builder per cache file (mmstab.core.locks): who waits for the lock reads, not rebuilds.

Two pytest workers (``make test`` runs two) or two commands asking for the same workspace V
or roadmap at once: the second waits while the first builds and then loads its file.
"""

from __future__ import annotations

import threading

import numpy as np
from conftest import write_problem

import mmstab.workspace.cache as cache_module
import mmstab.workspace.roadmap as roadmap_module
from mmstab.core.locks import build_lock, file_stamp
from mmstab.core.problem import load_problem
from mmstab.workspace import build_workspace, load_or_build_workspace, workspace_cache_path
from mmstab.workspace.roadmap import build_roadmap, load_or_build_roadmap, roadmap_arrays


def _small(p, r):
    p["workspace"]["grid"] = [6, 5, 5, 5]


def _waits_at_the_lock(monkeypatch, module, path, publish, load):
    """Run ``load`` in a thread; once it found no file and asks for the lock, ``publish``.

    The test holds the lock meanwhile, as another process building the file would.
    Returns what ``load`` returned.
    """
    asked = threading.Event()
    lock = module.build_lock

    def spy(p):
        asked.set()  # the thread found no file and now takes the lock
        return lock(p)

    monkeypatch.setattr(module, "build_lock", spy)
    out = {}
    with build_lock(path):
        thread = threading.Thread(target=lambda: out.setdefault("got", load()))
        thread.start()
        assert asked.wait(60)
        publish()
    thread.join(60)
    return out["got"]


def test_a_workspace_built_meanwhile_is_read_not_rebuilt(tmp_path, monkeypatch):
    problem = load_problem(write_problem(tmp_path, _small))
    path = workspace_cache_path(problem, tmp_path / "cache")
    built = build_workspace(problem.robot, [6, 5, 5, 5], progress=False)
    calls = []
    monkeypatch.setattr(cache_module, "build_workspace", lambda *a, **k: calls.append(a))

    def load():
        return load_or_build_workspace(problem, progress=False, cache_dir=tmp_path / "cache")

    got = _waits_at_the_lock(
        monkeypatch, cache_module, path, lambda: cache_module.save_workspace(path, built), load
    )
    assert calls == []  # the file the lock's holder wrote was read
    np.testing.assert_array_equal(got.valid_q, built.valid_q)


def test_a_roadmap_built_meanwhile_is_read_not_rebuilt(robot, tmp_path, monkeypatch):
    ws = build_workspace(robot, [6, 5, 5, 5], progress=False)
    built = build_roadmap(robot, ws)
    res, version = roadmap_module.DEFAULT_RESOLUTION, roadmap_module.ROADMAP_VERSION
    path = tmp_path / f"roadmap-{roadmap_module.roadmap_key(robot, ws.grid, res, version)}.npz"
    calls = []
    monkeypatch.setattr(roadmap_module, "build_roadmap", lambda *a, **k: calls.append(a))
    monkeypatch.setattr(roadmap_module, "_MEMORY", {})

    def publish():
        roadmap_module.write_npz(path, **roadmap_arrays(built))

    got = _waits_at_the_lock(
        monkeypatch,
        roadmap_module,
        path,
        publish,
        lambda: load_or_build_roadmap(robot, ws, cache_dir=tmp_path),
    )
    assert calls == []
    np.testing.assert_array_equal(got.nodes_q, built.nodes_q)


def test_stamp_tells_a_replaced_file(tmp_path):
    path = tmp_path / "f.npz"
    assert file_stamp(path) is None
    path.write_bytes(b"a")
    first = file_stamp(path)
    other = tmp_path / "g"
    other.write_bytes(b"b")
    other.replace(path)  # how the atomic writers publish a file
    assert file_stamp(path) not in (None, first)
