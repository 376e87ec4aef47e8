"""mmstab's cache folder: where it is, what a load keeps beside V, what a build says."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from conftest import write_problem


def test_the_cache_folder_follows_mmstab_cache_then_xdg_then_home(monkeypatch, tmp_path):
    from mmstab.workspace import default_cache_dir

    monkeypatch.setenv("MMSTAB_CACHE", str(tmp_path / "mine"))
    assert default_cache_dir() == tmp_path / "mine"  # read at the call, not at import
    monkeypatch.delenv("MMSTAB_CACHE")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert default_cache_dir() == tmp_path / "xdg" / "mmstab"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert default_cache_dir() == Path(tmp_path / "home" / ".cache" / "mmstab")


def _grid(p, r):
    p["workspace"]["grid"] = [6, 5, 5, 5]


def test_v_membership_is_kept_beside_the_workspace_and_checked(tmp_path, monkeypatch):
    from mmstab.core.problem import load_problem
    from mmstab.workspace import load_or_build_workspace, workspace_cache_path
    from mmstab.workspace.cache import in_V_path

    monkeypatch.setenv("MMSTAB_CACHE", str(tmp_path / "cache"))
    problem = load_problem(write_problem(tmp_path, _grid))
    built = load_or_build_workspace(problem, progress=False)
    side = in_V_path(workspace_cache_path(problem))
    expected = built.contains(built.valid_com)  # the hulls' test itself
    assert side.is_file() and np.array_equal(np.load(side), expected)
    assert 0 < expected.sum() < len(expected)  # V drops some valid CoMs: a real mask
    loaded = load_or_build_workspace(problem, progress=False)
    assert "valid_in_V" in loaded.__dict__  # read from the file, not computed
    assert np.array_equal(loaded.valid_in_V, expected)
    np.save(side, ~expected[:-1])  # another length (and newer): not trusted, computed again
    again = load_or_build_workspace(problem, progress=False)
    assert np.array_equal(again.valid_in_V, expected)
    assert np.array_equal(np.load(side), expected)  # and written again


def test_a_roadmap_build_says_where_its_file_goes(tmp_path, monkeypatch, capsys):
    from mmstab.core.problem import load_problem
    from mmstab.workspace import load_or_build_workspace
    from mmstab.workspace import roadmap as rm_module

    monkeypatch.setenv("MMSTAB_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(rm_module, "_MEMORY", {})
    problem = load_problem(write_problem(tmp_path, _grid))
    ws = load_or_build_workspace(problem, progress=False)
    rm = rm_module.load_or_build_roadmap(problem.robot, ws)
    err = capsys.readouterr().err
    files = list((tmp_path / "cache").glob("roadmap-*.npz"))
    assert len(files) == 1 and f"-> {files[0]}" in err and "posture roadmap" in err
    monkeypatch.setattr(rm_module, "_MEMORY", {})
    again = rm_module.load_or_build_roadmap(problem.robot, ws)  # from the file: silent
    assert capsys.readouterr().err == ""
    assert np.array_equal(again.edges, rm.edges)


def test_what_plans_derive_from_a_roadmap_is_kept_beside_it_and_equal(tmp_path, monkeypatch):
    """The ground graph, start node, its tree and component view: read back the same."""
    import os

    from mmstab.core.problem import load_problem
    from mmstab.planner.grounded import ground_graph
    from mmstab.planner.searches.roadmap import component_view
    from mmstab.planner.searches.roadmap.moves import start_tree
    from mmstab.workspace import load_or_build_workspace
    from mmstab.workspace import roadmap as rm_module

    monkeypatch.setenv("MMSTAB_CACHE", str(tmp_path / "cache"))
    problem = load_problem(write_problem(tmp_path, _grid))
    robot = problem.robot
    ws = load_or_build_workspace(problem, progress=False)

    def derived():
        monkeypatch.setattr(rm_module, "_MEMORY", {})  # a new process's view
        rm = rm_module.load_or_build_roadmap(robot, ws, progress=False)
        start = rm.connect(robot.stowed, robot)
        g = ground_graph(rm, 0.02)
        view = component_view(robot, rm, start, 0.02)
        return rm, start, g, view, start_tree(rm, start, 0.02)[1]

    first = derived()  # built (the roadmap, no copy of it), computed and written
    folder = rm_module.default_cache_dir()

    def kept():
        return sorted(p.name.split("-")[0] for p in next(folder.glob("roadmap-*/")).iterdir())

    assert kept() == ["connect", "ground", "tree", "view"]
    again = derived()  # read back (and the roadmap's arrays copied uncompressed)
    assert kept() == ["arrays", "connect", "ground", "tree", "view"]
    assert again[0] is not first[0] and again[1] == first[1]
    assert (again[2].graph != first[2].graph).nnz == 0
    assert np.array_equal(again[2].component, first[2].component)
    assert np.array_equal(again[3].reach, first[3].reach)
    assert np.array_equal(again[3].clusters.cluster_of, first[3].clusters.cluster_of)
    assert again[3].diameter == first[3].diameter and again[3].joint_span == first[3].joint_span
    assert np.array_equal(again[4], first[4])
    assert np.array_equal(again[0].edges, first[0].edges)
    # a rebuilt roadmap file (newer): its old derived arrays are not used
    source = next(folder.glob("roadmap-*.npz"))
    stamp = source.stat().st_mtime_ns
    os.utime(source, ns=(stamp + 10**9, stamp + 10**9))
    tree = next(folder.glob("roadmap-*/tree-*"))
    assert isinstance(np.load(tree / "pred.npy", mmap_mode="r"), np.memmap)  # mappable
    np.save(tree / "pred.npy", np.zeros(3, np.int32))  # wrong, and stamped for the old file
    assert int(np.load(tree / "_stamp.npy")) == stamp
    third = derived()
    assert np.array_equal(third[4], first[4])  # computed again, not the stale file
