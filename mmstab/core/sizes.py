"""Bounds on every size-like setting, from what this machine can do (inputs layer).

Each size-like field of a problem gets an :class:`Estimate`: the work it asks for, the
memory it needs and the time it takes on this machine. The memory is compared with the
memory available now (``MemAvailable`` in ``/proc/meminfo``, else the physical memory):
beyond :data:`MEMORY_SHARE` of it the field is refused, whatever the options (the run
would end in a ``MemoryError`` or fill the machine). The time is compared with
:data:`MAX_SECONDS`: beyond it the field is refused unless ``--force-size`` is given (a
typo should not mean hours of running). Both refusals are one line naming the field and
the estimate. Estimates of :data:`ANNOUNCE_SECONDS` or more are shown before the work
starts (:func:`announce`).

The per-item costs below were measured on the development machine (2 cores, Python
3.11; ``docs/cli.md`` gives the commands) and are deliberately rounded up: they are
bounds against typos, not predictions. The workspace build divides its time by the
worker processes it uses (two when this machine has two cores or more).
"""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Collection, Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

from mmstab.core.files import ConfigError, MmstabError

#: Share of the available memory a single stage may plan to use.
MEMORY_SHARE = 0.8
#: Longest estimated time [s] a stage may take without ``--force-size``.
MAX_SECONDS = 3600.0
#: Estimates from this long [s] on are announced on stderr before the work starts.
ANNOUNCE_SECONDS = 10.0

# Per-item costs (rounded up from measurements; module docstring).
#: Workspace build: labelling one posture, one process [s] (measured 2.9 us idle, 4.6 us
#: on the shared machine).
WS_SECONDS_PER_POSTURE = 1e-5
#: Workspace build: peak memory per posture (labels, CoMs, postures, hull input) [B]
#: (tracemalloc: 186 B at 435000 postures).
WS_BYTES_PER_POSTURE = 250.0
#: Workspace build: working set of one chunk, per process [B] (tracemalloc: ~15 MB).
WS_CHUNK_BYTES = 32e6
#: Worker processes of the workspace build (``mmstab.workspace.build_workspace``).
WS_WORKERS = 2
#: A joint grid of more postures than this is sampled when ``workspace.samples`` is set
#: (a 6-DoF arm's grid), not labelled whole.
WS_FULL_GRID_MAX = 2_000_000
#: Precision of V (fig3): one point drawn in V and its nearest valid CoM [s] (measured
#: 53 us with the cell size's fixed part).
PRECISION_SECONDS_PER_SAMPLE = 1e-4
#: ... and its memory (rejection sampling draws 4 candidates per point) [B].
PRECISION_BYTES_PER_SAMPLE = 400.0
#: Tracking: one control period, reference and post-processing included [s] (measured
#: 70 us).
TRACK_SECONDS_PER_STEP = 2e-4
#: Tracking: building the controller, the references and the figures, once [s].
TRACK_FIXED_SECONDS = 5.0
#: Tracking: memory per control period (recorded run, references, post-processing) [B]
#: (tracemalloc: 400 B beyond the fixed part).
TRACK_BYTES_PER_STEP = 4096.0
#: Tracking: memory of the controller, the lap's posture reference, the figures [B]
#: (tracemalloc: 33 MB).
TRACK_FIXED_BYTES = 128e6
#: Planner: one CMA-ES sample (Eq. 6 and membership of V) [s].
PLAN_SECONDS_PER_SAMPLE = 2e-5
#: Planner: one CMA-ES generation's own work (ask, tell) [s].
PLAN_SECONDS_PER_GENERATION = 2e-3
#: Planner: the posture (IK) realising one pose's target [s].
PLAN_SECONDS_PER_POSE = 0.1
#: Planner: memory per sample of a population (pycma keeps several copies) [B].
PLAN_BYTES_PER_SAMPLE = 2048.0
#: Animation: rendering one frame [s] (measured 0.1 s at 560 x 320).
ANIM_SECONDS_PER_FRAME = 0.5
#: Animation: bytes per pixel of a frame kept until the GIF is written.
ANIM_BYTES_PER_PIXEL = 8.0
#: Link0 sweeps (fig5, fig6): one sample at one pose [s] and [B].
SWEEP_SECONDS_PER_SAMPLE = 5e-5
SWEEP_BYTES_PER_SAMPLE = 2048.0

#: Typical values of the planner's size fields: a refusal names the one most above them.
PLAN_TYPICAL = {
    "poses": 10,
    "popsize": 16,
    "max_iterations": 20,
    "starts": 2,
    "coarse_samples": 16384,
}

#: A generated heightmap (``terrain.generate``): time and peak memory per cell, measured on the
#: ``rough`` generator (the costliest: FFT-filtered noise) at 1e6 and 4e6 cells: 0.85-0.94 us
#: and 312 B per cell [s, B].
TERRAIN_SECONDS_PER_CELL = 1.0e-6
TERRAIN_BYTES_PER_CELL = 320.0


class Estimate(NamedTuple):
    """The work a size-like field asks for.

    Attributes:
        field: dotted field name (``workspace.grid``) or option (``--duration``).
        work: what is done, in words (``435000 postures``).
        seconds: estimated wall time on this machine [s].
        bytes: estimated peak memory [B].
    """

    field: str
    work: str
    seconds: float
    bytes: float


def available_memory() -> float:
    """Memory available to a new computation now [B] (``MemAvailable``, else physical)."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    try:
        return float(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return math.inf


def workspace_workers() -> int:
    """Processes the workspace build uses on this machine."""
    return min(WS_WORKERS, os.cpu_count() or 1)


def human_bytes(n: float) -> str:
    """``1.2 GB`` style."""
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if n < 1000 or unit == "TB":
            return f"{n:.3g} {unit}" if unit != "B" else f"{n:.0f} B"
        n /= 1000
    return f"{n:.3g} TB"  # pragma: no cover


def human_seconds(s: float) -> str:
    """``42 s``, ``3.1 min``, ``2.5 h``, ``4.1e+03 days`` style."""
    if s < 90:
        return f"{s:.2g} s"
    if s < 5400:
        return f"{s / 60:.2g} min"
    if s < 48 * 3600:
        return f"{s / 3600:.2g} h"
    return f"{s / 86400:.2g} days"


# ------------------------------------------------------------------------------- estimates
def workspace_postures(grid: Sequence[int], samples: int | None = None) -> tuple[int, bool]:
    """The postures the workspace build labels, and whether it samples them.

    The full joint grid (one posture per grid point) up to :data:`WS_FULL_GRID_MAX` postures,
    or without ``workspace.samples``; beyond it with ``samples`` set (a 6-DoF arm's grid),
    ``samples`` grid postures drawn at random (seeded by ``workspace.seed``). A grid over the
    bound without ``samples`` is estimated whole (and refused if too large, as any size).

    Returns:
        (postures labelled, True if sampled).
    """
    full = math.prod(int(k) for k in grid)
    if full <= WS_FULL_GRID_MAX or samples is None:
        return full, False
    return min(int(samples), full), True


def workspace_estimate(grid: Sequence[int], samples: int | None = None) -> Estimate:
    """The workspace build of a joint grid (samples per joint): full, or sampled above a bound."""
    n, sampled = workspace_postures(grid, samples)
    shape = " x ".join(str(int(k)) for k in grid)
    hint = f"; over {WS_FULL_GRID_MAX}: set workspace.samples to sample it"
    return Estimate(
        "workspace.grid",
        f"{n} postures sampled of the {shape} grid (over {WS_FULL_GRID_MAX} postures)"
        if sampled
        else f"{n} postures ({shape}{hint if n > WS_FULL_GRID_MAX else ''})",
        n * WS_SECONDS_PER_POSTURE / workspace_workers(),
        # + each joint's samples (8 B each): a sampled grid still holds its axes
        n * WS_BYTES_PER_POSTURE
        + (workspace_workers() + 1) * WS_CHUNK_BYTES
        + 8.0 * sum(float(k) for k in grid),
    )


def terrain_estimate(section: Mapping[str, Any]) -> Estimate | None:
    """A generated heightmap's cells (``terrain.generate``), or None for other terrains."""
    gen: Any = section.get("generate")
    try:  # a malformed section is the terrain schema's to name (mmstab.terrain.factory)
        res = float(gen["resolution"])
        nx, ny = (math.ceil(float(s) / res - 1e-9) + 1 for s in gen["size"])  # as Grid.of_size
    except (TypeError, KeyError, ValueError, ZeroDivisionError, OverflowError):
        return None
    cells = float(nx) * float(ny)
    return Estimate(
        "terrain.generate.size",
        f"{cells:.3g} map cells ({nx} x {ny} at {res:g} m)",
        cells * TERRAIN_SECONDS_PER_CELL,
        cells * TERRAIN_BYTES_PER_CELL,
    )


def steps_estimate(field: str, duration: float, dt: float) -> Estimate:
    """A tracking run of ``duration`` [s] at period ``dt`` [s]."""
    steps = duration / dt
    return Estimate(
        field,
        f"{steps:.6g} control periods ({duration:g} s at dt = {dt:g} s)",
        steps * TRACK_SECONDS_PER_STEP + TRACK_FIXED_SECONDS,
        steps * TRACK_BYTES_PER_STEP + TRACK_FIXED_BYTES,
    )


def planner_estimate(section: Mapping[str, Any], poses: int | None = None) -> Estimate:
    """The planner's CMA-ES budget over the path (at most ``max_iterations`` per run).

    Each pose runs CMA-ES from each start (``seeding: starts``) or from ``coarse_seeds``
    refined optima of a coarse pass over ``coarse_samples`` samples of V (``seeding:
    coarse``, each sample costed as one CMA-ES sample), plus ``restarts`` IPOP reruns with
    the population doubled each time. ``method: exhaustive`` scores every valid grid CoM,
    which the workspace bound already limits; its estimate is the CMA-ES one. ``poses``:
    the number of planned poses when ``planner.poses`` does not set it (a route's, from
    ``planner.spacing``).
    """
    restarts = int(section.get("restarts", 0))
    coarse = section.get("seeding", "starts") == "coarse"
    counts = {
        "poses": int(section["poses"]) if poses is None else int(poses),
        "popsize": int(section["popsize"]),
        "max_iterations": int(section["max_iterations"]),
        "starts": int(section.get("coarse_seeds", 1)) if coarse else len(section["starts"]),
    }
    sample = PLAN_SECONDS_PER_SAMPLE * (1 + int(section["max_resample"]))
    # one run per start and restart r, with popsize * 2**r samples per generation
    per_start = sum(
        counts["max_iterations"] * (counts["popsize"] * 2**r * sample + PLAN_SECONDS_PER_GENERATION)
        for r in range(restarts + 1)
    )
    coarse_samples = int(section.get("coarse_samples", 0)) if coarse else 0
    worst = max(counts, key=lambda k: counts[k] / PLAN_TYPICAL[k])
    work = " x ".join(f"{k} {v}" for k, v in counts.items())
    if restarts:
        work += f", {restarts} restarts"
    if coarse_samples:
        work += f", coarse pass of {coarse_samples} samples"
        if coarse_samples / PLAN_TYPICAL["coarse_samples"] > counts[worst] / PLAN_TYPICAL[worst]:
            worst = "coarse_samples"
    return Estimate(
        f"planner.{worst}",
        f"CMA-ES with {work}",
        counts["poses"] * (counts["starts"] * per_start + coarse_samples * PLAN_SECONDS_PER_SAMPLE)
        + counts["poses"] * PLAN_SECONDS_PER_POSE,
        max(counts["popsize"] * 2**restarts, coarse_samples) * PLAN_BYTES_PER_SAMPLE,
    )


def sweep_estimate(section: Mapping[str, Any]) -> Estimate:
    """The link0 sweeps of fig6 (``poses`` x ``samples``; fig5 is one pose)."""
    samples, poses = int(section["samples"]), int(section["poses"])
    n = samples * poses
    return Estimate(
        "sweep.samples" if samples / 100 >= poses / 11 else "sweep.poses",
        f"{n} sweep samples ({poses} poses x {samples})",
        n * SWEEP_SECONDS_PER_SAMPLE,
        n * SWEEP_BYTES_PER_SAMPLE,
    )


def animation_estimate(section: Mapping[str, Any], samples: float) -> Estimate:
    """The GIF: ``frames`` (at most one per recorded sample) of ``width`` x ``height``."""
    frames = min(int(section["frames"]), max(int(samples), 2))
    pixels = int(section["width"]) * int(section["height"])
    return Estimate(
        "animation.frames",
        f"{frames} frames of {section['width']} x {section['height']} px",
        frames * ANIM_SECONDS_PER_FRAME,
        frames * pixels * ANIM_BYTES_PER_PIXEL,
    )


def precision_estimate(section: Mapping[str, Any]) -> Estimate:
    """Points drawn in V to measure its precision (fig3)."""
    n = int(section["precision_samples"])
    return Estimate(
        "workspace.precision_samples",
        f"{n} points drawn in V",
        n * PRECISION_SECONDS_PER_SAMPLE,
        n * PRECISION_BYTES_PER_SAMPLE,
    )


def estimates(
    data: Mapping[str, Any],
    duration: float | None = None,
    field: str = "controller.duration",
    poses: int | None = None,
) -> dict[str, Estimate]:
    """Every size estimate of a schema-valid problem, by section.

    Args:
        data: the problem.
        duration: the tracking run's simulated time [s] when it is not
            ``controller.duration`` (a route's driving time, ``--duration``).
        field: what sets that time, for messages (``path``, ``--duration``).
        poses: the planned poses when not ``planner.poses`` (a route's).
    """
    ctrl = data["controller"]
    if duration is None:
        duration, field = float(ctrl["duration"]), "controller.duration"
    steps = float(duration) / float(ctrl["dt"])
    terrain = terrain_estimate(data["terrain"])
    return {
        **({"terrain": terrain} if terrain is not None else {}),
        "workspace": workspace_estimate(
            data["workspace"]["grid"], data["workspace"].get("samples")
        ),
        "precision": precision_estimate(data["workspace"]),
        "controller": steps_estimate(field, duration, ctrl["dt"]),
        "planner": planner_estimate(data["planner"], poses),
        "sweep": sweep_estimate(data["sweep"]),
        "animation": animation_estimate(data["animation"], steps + 1),
    }


# ---------------------------------------------------------------------------------- checks
def refusal(est: Estimate, force: bool, memory: float | None = None) -> str | None:
    """Why an estimate is beyond this machine's bounds, or None."""
    memory = available_memory() if memory is None else memory
    if est.bytes > MEMORY_SHARE * memory:
        return (
            f"{est.work} need about {human_bytes(est.bytes)} of memory; this machine has "
            f"{human_bytes(memory)} available"
        )
    if est.seconds > MAX_SECONDS and not force:
        return (
            f"{est.work} take about {human_seconds(est.seconds)} on this machine (bound "
            f"{human_seconds(MAX_SECONDS)}); pass --force-size to run it anyway"
        )
    return None


def check_sizes(
    path: Path,
    data: Mapping[str, Any],
    *,
    force: bool = False,
    sections: Collection[str] | None = None,
) -> dict[str, Estimate]:
    """Refuse a problem whose sizes exceed this machine's bounds (module docstring).

    Args:
        path: the problem file (for messages).
        data: the problem, valid against its schema.
        force: accept estimates beyond :data:`MAX_SECONDS` (not beyond the memory).
        sections: the sections the command uses (None: all); the others are not bounded.

    Returns:
        The estimates, by section.

    Raises:
        ConfigError: naming the file, the field and the estimate.
    """
    found = estimates(data)
    memory = available_memory()
    for est in found.values():
        if sections is not None and est.field.split(".")[0] not in sections:
            continue
        why = refusal(est, force, memory)
        if why is not None:
            raise ConfigError(path, est.field, why)
    return found


def check_steps(what: str, duration: float, dt: float, *, force: bool = False) -> Estimate:
    """Refuse a command-line duration beyond the bounds; returns its estimate.

    Raises:
        MmstabError: naming the option and the estimate.
    """
    est = steps_estimate(what, duration, dt)
    why = refusal(est, force)
    if why is not None:
        raise MmstabError(f"{what}: {why}")
    return est


def announce(est: Estimate, stream: Any = None) -> None:
    """Show a long estimate (``ANNOUNCE_SECONDS`` or more) on stderr before the work."""
    if est.seconds >= ANNOUNCE_SECONDS:
        print(
            f"mmstab: {est.field}: {est.work}, about {human_seconds(est.seconds)} on this machine",
            file=stream if stream is not None else sys.stderr,
        )
