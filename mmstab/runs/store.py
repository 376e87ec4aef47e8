"""A stored tracking run (``results/tracking/``, as ``mmstab track`` writes it), read and checked.

One simulated run serves every product after it: the animation and the viewer read
``run.npz`` (base poses, arm postures and μ per sample for the three arm modes, the plan's
arm-CoM targets) instead of simulating again, after checking that the run belongs to the
problem by comparing the run's saved ``problem.yaml`` with it.
"""

from __future__ import annotations

import math
import zipfile
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from mmstab.core.files import ConfigError, MmstabError, read_yaml
from mmstab.model.robot import FloatArray

#: Sections of a problem that decide what a run is: a run made with other values there
#: belongs to another problem. (``animation``, ``sweep``, ``codegen`` ... only present it.)
RUN_SECTIONS = ("robot", "terrain", "path", "planner", "controller")
#: Arrays read from ``run.npz``.
RUN_ARRAYS = (
    "t",
    "state",
    "mu_reconfigured",
    "mu_stowed",
    "mu_arm_removed",
    "plan_fractions",
    "plan_target_com",
)


class Run(NamedTuple):
    """A stored run, per sample.

    Attributes:
        directory: the run's folder.
        t: sample times (N,) [s].
        poses: base poses (N, 3) of (x [m], y [m], yaw [rad]) in the map frame M.
        q: arm postures (N, 4) [rad].
        mu: μ per arm mode (``planned``, ``stowed``, ``arm removed``), each (N,) [N rad].
        plan_fractions: path fractions of the planned poses (K,) in [0, 1).
        plan_target_com: planned arm CoMs in the body frame (K, 3) [m].
    """

    directory: Path
    t: FloatArray
    poses: FloatArray
    q: FloatArray
    mu: dict[str, FloatArray]
    plan_fractions: FloatArray
    plan_target_com: FloatArray

    @property
    def samples(self) -> int:
        """Number of samples N."""
        return int(self.t.size)


def first_difference(saved: Any, live: Any, where: str = "") -> str | None:
    """Dotted path of the first field where two YAML-like trees differ, or None if equal.

    Numbers compare with a relative tolerance of 1e-12 (a YAML round trip of a float).
    """
    if isinstance(saved, dict) and isinstance(live, dict):
        for key in sorted(set(saved) | set(live), key=str):
            sub = f"{where}.{key}" if where else str(key)
            if key not in saved or key not in live:
                return sub
            found = first_difference(saved[key], live[key], sub)
            if found is not None:
                return found
        return None
    if isinstance(saved, list | tuple) and isinstance(live, list | tuple):
        if len(saved) != len(live):
            return where
        for i, (a, b) in enumerate(zip(saved, live, strict=True)):
            found = first_difference(a, b, f"{where}[{i}]")
            if found is not None:
                return found
        return None
    numbers = (int, float)
    if isinstance(saved, numbers) and isinstance(live, numbers) and not isinstance(saved, bool):
        same = math.isclose(float(saved), float(live), rel_tol=1e-12, abs_tol=0.0)
        return None if same else where
    return None if saved == live else where


def _lookup(tree: Any, dotted: str) -> Any:
    node = tree
    for part in dotted.replace("[", ".[").split("."):
        if not part:
            continue
        try:
            node = node[int(part[1:-1])] if part.startswith("[") else node[part]
        except (KeyError, IndexError, TypeError):
            return "(absent)"
    return node


def _short(value: Any, width: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= width else text[: width - 3] + "..."


def check_run_matches(directory: Path, problem: Any) -> None:
    """Refuse a run whose saved ``problem.yaml`` differs from ``problem`` in :data:`RUN_SECTIONS`.

    Raises:
        ConfigError: naming the saved file and the first differing field.
    """
    saved_path = directory / "problem.yaml"
    if not saved_path.is_file():
        raise ConfigError(directory, "", "no problem.yaml: not a run folder of `mmstab track`")
    saved = read_yaml(saved_path)
    live = problem.to_dict()
    for section in RUN_SECTIONS:
        diff = first_difference(saved.get(section), live.get(section), section)
        if diff is not None:
            raise ConfigError(
                saved_path,
                diff,
                f"the run was made with {_short(_lookup(saved, diff))}, {problem.path} has "
                f"{_short(_lookup(live, diff))}: a run of another problem (re-run `mmstab track`)",
            )


def load_run(directory: str | Path, problem: Any) -> Run:
    """Read and check a stored tracking run against the problem shown.

    Args:
        directory: the run's folder (``results/tracking``).
        problem: the :class:`mmstab.core.problem.Problem` the run must belong to.

    Raises:
        MmstabError: the folder or ``run.npz`` is missing or unreadable.
        ConfigError: the run is of another problem, or an array is missing or misshapen.
    """
    d = Path(directory)
    if not d.is_dir():
        raise MmstabError(f"{d}: no such run folder (make one with `mmstab track PROBLEM`)")
    check_run_matches(d, problem)
    npz = d / "run.npz"
    try:
        with np.load(npz, allow_pickle=False) as data:
            missing = [k for k in RUN_ARRAYS if k not in data.files]
            if missing:
                raise ConfigError(npz, missing[0], "missing: not a run of `mmstab track`")
            arrays = {k: np.asarray(data[k], dtype=float) for k in RUN_ARRAYS}
    except (OSError, ValueError, zipfile.BadZipFile) as exc:
        raise MmstabError(f"{npz}: cannot read the run ({exc})") from None
    n, joints = arrays["t"].size, problem.robot.arm_joints
    shapes = {
        "t": (n,),
        "state": (n, 5 + joints),  # pose, sprockets, the arm's joints
        "mu_reconfigured": (n,),
        "mu_stowed": (n,),
        "mu_arm_removed": (n,),
        "plan_target_com": (arrays["plan_fractions"].size, 3),
    }
    for key, shape in shapes.items():
        if arrays[key].shape != shape:
            raise ConfigError(npz, key, f"shape {arrays[key].shape}, expected {shape}")
    if n < 1 or not all(np.all(np.isfinite(arrays[k])) for k in ("t", "state")):
        raise ConfigError(npz, "state", "empty or not finite")
    state = arrays["state"]
    return Run(
        directory=d,
        t=arrays["t"],
        poses=state[:, :3],
        q=state[:, 5:],
        mu={
            "planned": arrays["mu_reconfigured"],
            "stowed": arrays["mu_stowed"],
            "arm removed": arrays["mu_arm_removed"],
        },
        plan_fractions=arrays["plan_fractions"],
        plan_target_com=arrays["plan_target_com"],
    )
