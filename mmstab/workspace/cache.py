"""The workspace cache: ``<key>.npz`` in mmstab's cache folder (:func:`default_cache_dir`).

The folder is shared by every working folder: ``$MMSTAB_CACHE``, else the user's cache
folder (``$XDG_CACHE_HOME/mmstab``, else ``~/.cache/mmstab``); the key holds the robot
description, the grid and the version, so robots and settings never mix.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import sys
from collections.abc import Sequence
from concurrent.futures import Executor
from pathlib import Path
from typing import Any

import numpy as np

from mmstab.core import clib
from mmstab.core.clib import CACHE_ENV  # noqa: F401 (the variable that moves the cache)
from mmstab.core.files import write_npy, write_npz
from mmstab.core.locks import build_lock, file_stamp
from mmstab.core.problem import Problem
from mmstab.core.sizes import announce, workspace_estimate, workspace_postures
from mmstab.model.robot import Robot
from mmstab.workspace.build import build_workspace
from mmstab.workspace.kept import kept_beside
from mmstab.workspace.region import Workspace
from mmstab.workspace.settings import WorkspaceSettings

#: Bump when labelling or the cache format changes: old cache files are then ignored.
WORKSPACE_VERSION = 1


def default_cache_dir() -> Path:
    """Where ``load_or_build_workspace`` keeps workspaces and roadmaps (module text).

    Read at every call, so ``$MMSTAB_CACHE`` set after import counts.
    """
    return clib.cache_dir()


# ---------------------------------------------------------------------------------- cache
def workspace_key(
    robot: Robot, grid: Sequence[int], samples: int | None = None, seed: int = 0
) -> str:
    """Cache key of a robot description, a grid (and its draw, if sampled) and the version."""
    text = f"v{WORKSPACE_VERSION}|{robot.source_hash}|{[int(n) for n in grid]}"
    count, sampled = workspace_postures(grid, samples)
    if sampled:  # a whole grid's key is unchanged (the 4-DoF caches stay valid)
        text += f"|samples={count}|seed={int(seed)}"
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def save_workspace(path: str | os.PathLike[str], ws: Workspace) -> Path:
    """Write a workspace to ``.npz`` atomically."""
    arrays = {f.name: getattr(ws, f.name) for f in dataclasses.fields(ws)}
    return write_npz(path, version=WORKSPACE_VERSION, **arrays)


def load_workspace(path: str | os.PathLike[str]) -> Workspace:
    """Read a workspace written by :func:`save_workspace`.

    Its arrays are kept uncompressed beside the file (:mod:`mmstab.workspace.kept`): a new
    process maps them instead of inflating the ``.npz`` (30 ms a command on the default grid).

    Raises:
        ValueError: the file is from another ``WORKSPACE_VERSION``.
    """

    def read() -> dict[str, np.ndarray]:
        with np.load(path) as z:
            if int(z["version"]) != WORKSPACE_VERSION:
                raise ValueError(f"{path}: workspace cache version {int(z['version'])}")
            return {f.name: z[f.name] for f in dataclasses.fields(Workspace) if f.name in z}

    kw: dict[str, Any] = dict(kept_beside(Path(path), "arrays", read))  # uncompressed: fast
    kw["grid"] = tuple(int(n) for n in kw["grid"])
    kw["samples"], kw["seed"] = int(kw.get("samples", 0)), int(kw.get("seed", 0))
    kw["diameter"] = float(kw["diameter"])
    kw["build_seconds"] = float(kw["build_seconds"])
    return Workspace(**kw)


def _short(exc: BaseException, width: int = 60) -> str:
    """``Type: first line of the message`` within about ``width`` characters."""
    text = (str(exc).splitlines() or [""])[0]
    text = text if len(text) <= width else text[: width - 3] + "..."
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def load_or_build_workspace(
    problem: Problem,
    force: bool = False,
    progress: bool = True,
    cache_dir: str | os.PathLike[str] | None = None,
    executor: Executor | None = None,
) -> Workspace:
    """The problem's workspace (:func:`robot_workspace` of its robot and ``workspace:``)."""
    settings = WorkspaceSettings.from_section(problem.section("workspace"))
    return robot_workspace(problem.robot, settings, force, progress, cache_dir, executor)


def robot_workspace(
    robot: Robot,
    settings: WorkspaceSettings | None = None,
    force: bool = False,
    progress: bool = True,
    cache_dir: str | os.PathLike[str] | None = None,
    executor: Executor | None = None,
) -> Workspace:
    """A robot's workspace: from the cache when robot and grid are unchanged, else built.

    One process at a time builds a cache file (:mod:`mmstab.core.locks`): a second one asking
    for the same workspace meanwhile waits and reads the first one's file.

    Args:
        robot: the robot.
        settings: the grid, its draw and seed (default :class:`WorkspaceSettings`).
        force: rebuild (and overwrite the cache) even when a cached copy matches.
        progress: show a progress bar while building.
        cache_dir: cache folder (default :func:`default_cache_dir`).
        executor: passed to :func:`build_workspace`.
    """
    settings = settings if settings is not None else WorkspaceSettings()
    grid, samples, seed = settings.grid, settings.samples, settings.seed
    path = robot_cache_path(robot, settings, cache_dir)
    seen = file_stamp(path)  # before reading: a file published after it is seen below
    ws = None if force else _read_cache(path)
    if ws is not None:
        return with_in_V(ws, path)
    with build_lock(path):  # one builder per cache file: another process may be building it
        if not force and file_stamp(path) not in (None, seen):  # it did, while we waited
            ws = _read_cache(path)
            if ws is not None:
                return with_in_V(ws, path)
        if progress:
            announce(workspace_estimate(grid, samples))
        ws = build_workspace(
            robot, grid, executor=executor, progress=progress, samples=samples, seed=seed
        )
        save_workspace(path, ws)
    return with_in_V(ws, path)


def _read_cache(path: Path) -> Workspace | None:
    """The cached workspace at ``path``, or None (absent, or unreadable: a one-line notice)."""
    if not path.is_file():
        return None
    try:
        return load_workspace(path)
    except Exception as exc:  # noqa: BLE001 - any unreadable cache (0-byte, cut, garbage)
        why = _short(exc)
        print(
            f"mmstab: notice: workspace cache {path} unreadable ({why}); rebuilding",
            file=sys.stderr,
        )
    return None


def in_V_path(path: Path) -> Path:
    """The file beside a workspace's cache file that keeps ``Workspace.valid_in_V``."""
    return path.with_name(f"{path.stem}-in-V.npy")


def with_in_V(ws: Workspace, path: Path) -> Workspace:
    """``ws`` with ``valid_in_V`` read from beside its cache file ``path``, else computed.

    V's membership of every valid CoM (both hulls' tests, about a second on the default
    grid) is the same at every load: kept in ``<key>-in-V.npy`` (written when missing, or
    older than the workspace's file, or of another length) and read from there.
    """
    side = in_V_path(path)
    try:
        if side.stat().st_mtime_ns >= path.stat().st_mtime_ns:
            flags = np.load(side)
            if flags.dtype == np.bool_ and flags.shape == (len(ws.valid_com),):
                ws.__dict__["valid_in_V"] = flags  # the cached property, filled
                return ws
    except (OSError, ValueError):
        pass
    try:
        write_npy(side, ws.valid_in_V)
    except OSError:  # a read-only cache: computed every time
        pass
    return ws


def workspace_cache_path(problem: Problem, cache_dir: str | os.PathLike[str] | None = None) -> Path:
    """Where ``load_or_build_workspace`` keeps the problem's workspace."""
    settings = WorkspaceSettings.from_section(problem.section("workspace"))
    return robot_cache_path(problem.robot, settings, cache_dir)


def robot_cache_path(
    robot: Robot, settings: WorkspaceSettings, cache_dir: str | os.PathLike[str] | None = None
) -> Path:
    """Where :func:`robot_workspace` keeps a robot's workspace for ``settings``."""
    base = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    key = workspace_key(robot, settings.grid, settings.samples, settings.seed)
    return base / f"{key}.npz"
