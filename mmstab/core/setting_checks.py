"""The one registry of a problem's settings checks beyond the JSON schema (inputs layer).

:func:`check_problem` runs, at load time, every check of :data:`SECTION_CHECKS` (semantic
checks the schema cannot express: weights that must sum to 1, gains that make the discrete
loop overshoot, a QP plugin CasADi cannot generate C for) and then the size bounds of
:mod:`mmstab.core.sizes`, for every command (``rest`` and ``terrain export``: those of the
sections they use). The registry is a plain, explicit
table: importing a stage never adds or changes a check, so what is validated does not
depend on which modules a command happened to import.

This module imports nothing above the inputs layer (:mod:`mmstab.core.files`,
:mod:`mmstab.core.sizes`); the stages read their constants (:data:`PLUGINS`,
:data:`CODEGEN_PLUGINS`) from here.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection, Mapping
from pathlib import Path
from types import MappingProxyType
from typing import Any

from mmstab.core.files import ConfigError, MmstabError
from mmstab.core.sizes import Estimate, check_sizes, check_steps

#: QP plugins of the tracking controller (CasADi ``conic`` plugins, and ``box``: mmstab's own
#: box-QP solver, :mod:`mmstab.control.controller.boxqp`).
PLUGINS = ("qpoases", "osqp", "qrqp", "daqp", "box")
#: Plugins CasADi can generate C for (qpOASES emits ``#error``).
CODEGEN_PLUGINS = ("qrqp", "daqp", "osqp", "box")
#: Why ``codegen`` refuses qpOASES.
QPOASES_MESSAGE = "CasADi cannot generate C for qpOASES; use box, qrqp, daqp or osqp"
#: Tolerance of ``w_stability + w_motion = 1``.
WEIGHT_SUM_TOL = 1e-9

#: A semantic check of one section: (problem path, validated section) -> None, or raise.
SectionCheck = Callable[[Path, Mapping[str, Any]], None]


def check_planner(path: Path, section: Mapping[str, Any]) -> None:
    """``planner:``: the weights of Eq. 6 sum to 1.

    Raises:
        ConfigError: naming ``planner.w_motion``.
    """
    if abs(section["w_stability"] + section["w_motion"] - 1.0) > WEIGHT_SUM_TOL:
        raise ConfigError(path, "planner.w_motion", "w_stability + w_motion must equal 1")


def check_controller(path: Path, section: Mapping[str, Any]) -> None:
    """``controller:``: a duration of at least one period; gains the discrete loop can follow.

    Raises:
        ConfigError: naming the field (``controller.duration``, ``controller.kp``,
            ``controller.posture_gain``).
    """
    dt = float(section["dt"])
    if float(section["duration"]) < dt:
        raise ConfigError(path, "controller.duration", f"must be at least dt = {dt} s")
    for gain in ("kp", "posture_gain"):
        if max(section[gain]) * dt >= 1.0:
            raise ConfigError(
                path,
                f"controller.{gain}",
                f"{gain} * dt must stay below 1 (the discrete loop overshoots); dt = {dt} s",
            )


#: Most postures a joint grid may have: they are numbered by 64-bit integers
#: (``numpy.random.Generator.choice`` draws the sampled ones among them).
MAX_GRID_POSTURES = 2**62


def check_workspace(path: Path, section: Mapping[str, Any]) -> None:
    """``workspace:``: a sampled joint grid whose postures 64-bit integers can number.

    (A grid labelled whole is bounded by the memory it needs: :mod:`mmstab.core.sizes`.)

    Raises:
        ConfigError: naming ``workspace.grid``.
    """
    full = math.prod(int(k) for k in section["grid"])
    if section.get("samples") is not None and full > MAX_GRID_POSTURES:
        raise ConfigError(
            path, "workspace.grid", f"has {float(full):.3g} postures; at most 2**62 can be numbered"
        )


def check_arm_joints(
    path: Path, data: Mapping[str, Any], n: int, sections: Collection[str] | None = None
) -> None:
    """Per-joint settings sized for the robot's arm of ``n`` joints; every mismatch at once.

    ``controller.w_b`` has 2 + n weights (sprockets, then the arm), ``controller.posture_gain``
    and ``controller.posture_weight`` n, ``workspace.grid`` n sample counts. A key the file
    leaves out takes its per-joint default (:func:`mmstab.core.defaults.joint_defaults`).
    ``sections``: the sections the command uses (None: all); the others are not checked.

    Raises:
        ConfigError: naming the first field of the wrong length, and the others after it.
    """
    wanted = {
        "controller.w_b": 2 + n,
        "controller.posture_gain": n,
        "controller.posture_weight": n,
        "workspace.grid": n,
    }
    wrong = []
    for field, size in wanted.items():
        section, key = field.split(".")
        if sections is not None and section not in sections:
            continue
        got = len(data[section][key])
        if got != size:
            wrong.append((field, got, size))
    if not wrong:
        return
    parts = [f"{field}: has {got} entries, needs {size}" for field, got, size in wrong]
    msg = (
        f"{parts[0].split(': ', 1)[1]} for the robot's {n}-joint arm"
        + "".join(f"; {p}" for p in parts[1:])
        + " (left out, a per-joint key takes its default for the robot's joints)"
    )
    raise ConfigError(path, wrong[0][0], msg)


def check_plugin(plugin: str) -> None:
    """Raise :class:`MmstabError` unless CasADi can generate C for ``plugin``."""
    if plugin == "qpoases":
        raise MmstabError(QPOASES_MESSAGE)
    if plugin not in CODEGEN_PLUGINS:
        raise MmstabError(f"unknown QP plugin {plugin!r}; choose one of {CODEGEN_PLUGINS}")


def check_codegen(path: Path, section: Mapping[str, Any]) -> None:
    """``codegen:``: a plugin CasADi can generate C for.

    Raises:
        ConfigError: naming ``codegen.plugin``.
    """
    try:
        check_plugin(str(section["plugin"]))
    except MmstabError as exc:
        raise ConfigError(path, "codegen.plugin", str(exc)) from None


#: Every semantic check, by section. Explicit: nothing registers itself on import.
def check_physics(path: Path, section: Mapping[str, Any]) -> None:
    """``physics:``: the reference governor stops beyond the error it slows from.

    Raises:
        ConfigError: naming ``physics.governor.stop``.
    """
    g = section["governor"]
    if g is not None and not g["stop"] > g["slow"]:
        raise ConfigError(
            path, "physics.governor.stop", f"must exceed governor.slow = {g['slow']} m"
        )


SECTION_CHECKS: Mapping[str, SectionCheck] = MappingProxyType(
    {
        "planner": check_planner,
        "controller": check_controller,
        "codegen": check_codegen,
        "physics": check_physics,
        "workspace": check_workspace,
    }
)


def check_problem(
    path: Path,
    data: Mapping[str, Any],
    *,
    force_size: bool = False,
    sections: Collection[str] | None = None,
) -> dict[str, Estimate]:
    """Every check of a schema-valid problem: the registry, then the size bounds.

    Args:
        path: the problem file (for messages).
        data: its content, already valid against :func:`mmstab.core.schema.problem_schema`.
        force_size: accept sizes whose time estimate exceeds the bound (``--force-size``);
            memory bounds hold regardless.
        sections: the sections the command uses (None: every section); the checks and bounds
            of the others are skipped (their schema still holds).

    Returns:
        The size estimates by field (:func:`mmstab.core.sizes.check_sizes`).

    Raises:
        ConfigError: naming the file and the first field at fault.
    """
    for name, check in SECTION_CHECKS.items():
        if sections is None or name in sections:
            check(path, data[name])
    return check_sizes(path, data, force=force_size, sections=sections)


def check_duration(
    duration: float, dt: float, *, what: str = "--duration", force_size: bool = False
) -> None:
    """A simulated time given on the command line: finite, at least dt, within the bounds.

    Args:
        duration: simulated time [s].
        dt: control period [s].
        what: the option's name, for the message.
        force_size: accept a duration whose time estimate exceeds the bound.

    Raises:
        MmstabError: one line naming the option.
    """
    if not math.isfinite(duration) or duration < dt:
        raise MmstabError(f"{what}: {duration} s must be a finite time of at least dt = {dt} s")
    check_steps(what, duration, dt, force=force_size)
