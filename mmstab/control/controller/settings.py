"""The ``controller:`` section of a problem file (its checks: :mod:`mmstab.core.setting_checks`)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from mmstab.core.defaults import SECTION_DEFAULTS
from mmstab.core.setting_checks import CODEGEN_PLUGINS as CODEGEN_PLUGINS  # re-exported
from mmstab.core.setting_checks import PLUGINS as PLUGINS
from mmstab.core.setting_checks import check_controller


@dataclass(frozen=True)
class OsqpSettings:
    """OSQP options: tolerances (absolute [rad/s], relative [-]), iterations, polishing."""

    eps_abs: float
    eps_rel: float
    max_iter: int
    polish: bool


def _optional(value: Any) -> float | None:
    return None if value is None else float(value)


_VECTORS = ("kp", "w_a", "w_b", "posture_gain", "posture_weight")


@dataclass(frozen=True)
class ControllerSettings:
    """The ``controller:`` section of a problem file.

    Attributes:
        dt: control period and integration step [s].
        lap_time: time for one lap of the base circle [s] (sets the reference speed).
        duration: simulated time [s].
        kp: proportional gains K_p, one per task row (6,) [1/s].
        w_a: task weights W_A (6,) [-].
        w_b: joint-velocity weights W_B (6,), > 0 [-].
        posture_gain: posture gains K_q, one per arm joint (4,) [1/s].
        posture_weight: posture weights W_q, one per arm joint (4,) [-].
        plugin: QP plugin, one of :data:`PLUGINS`.
        feedforward: add ξ̇_ref to ξ̇_des and q̇_ref to q̇_post.
        base_offset: base control point ahead of the body origin d [m].
        approach_time: length of the arm's start-up reference [s] (:mod:`mmstab.control.approach`;
            0: the lap's references from t = 0).
        kkt_tol: tolerance of the in-graph solution certificate [rad/s].
        osqp: OSQP options.
        arm_com_frame: the frame of the arm-CoM task, ``map`` (M, paper Eq. 7: task
            ``arm_com``) or ``body`` (B: task ``arm_com_body``, its references g_a^B(q_ref))
            (:func:`mmstab.control.tasks.controller_task_names`); default ``body``.
        dynamic_fraction: the arm's time law: along the reference the dynamic μ keeps this
            share of the static μ (:mod:`mmstab.control.timing`); None: off.
    """

    dt: float
    lap_time: float
    duration: float
    kp: tuple[float, ...]
    w_a: tuple[float, ...]
    w_b: tuple[float, ...]
    posture_gain: tuple[float, ...]
    posture_weight: tuple[float, ...]
    plugin: str
    feedforward: bool
    base_offset: float
    approach_time: float
    kkt_tol: float
    osqp: OsqpSettings
    arm_com_frame: str = SECTION_DEFAULTS["controller"]["arm_com_frame"]
    dynamic_fraction: float | None = SECTION_DEFAULTS["controller"]["dynamic_fraction"]

    @classmethod
    def from_section(cls, section: Mapping[str, Any]) -> ControllerSettings:
        """Build from a validated ``controller:`` section."""
        vecs = {k: tuple(float(v) for v in section[k]) for k in _VECTORS}
        o = section["osqp"]
        return cls(
            dt=float(section["dt"]),
            lap_time=float(section["lap_time"]),
            duration=float(section["duration"]),
            plugin=str(section["plugin"]),
            feedforward=bool(section["feedforward"]),
            base_offset=float(section["base_offset"]),
            approach_time=float(section["approach_time"]),
            kkt_tol=float(section["kkt_tol"]),
            arm_com_frame=str(section.get("arm_com_frame", cls.arm_com_frame)),
            dynamic_fraction=_optional(section.get("dynamic_fraction", cls.dynamic_fraction)),
            osqp=OsqpSettings(
                float(o["eps_abs"]), float(o["eps_rel"]), int(o["max_iter"]), bool(o["polish"])
            ),
            **vecs,
        )


#: The ``controller:`` check of the settings registry
#: (:func:`mmstab.core.setting_checks.check_controller`).
check_settings = check_controller
