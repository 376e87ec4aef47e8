"""Closed-loop trajectory tracking (paper Section II-E and III; ``docs/design.md``, "Controller").

:func:`simulate` drives the controller step (:mod:`mmstab.control.controller`, Eq. 7-8) around the
problem's circle while the arm CoM follows a plan's body-frame CoM targets and the posture task
holds the arm near the plan's postures (:func:`mmstab.control.reference.task_reference`; the posture
reference is checked for self-collision and repaired first, :mod:`mmstab.control.posture`), and
records
everything the paper's Fig. 9-12 show.

**Plant** (:mod:`mmstab.control.plant`). The base is the nonholonomic tracked vehicle: over one
control period dt the sprocket speeds are constant, so the base drives an exact arc in the
map frame's x-y plane (no sideways motion); the joints integrate q̇·dt. The plant is
kinematic, as the paper's: the commanded joint speeds are the actual ones (no slip, no
dynamics).

**One step = one CasADi call.** The controller step Function (state, reference, params) ->
(q̇, status, objective) and the integrator are composed into one ``advance`` Function, called
through ``Function.buffer()`` on preallocated arrays. The composition applies q̇ only when the
step reports SUCCESS (else q̇ = 0: hold still, whatever the backend returned) and flags a
non-finite next state. Any Function with :class:`StepBackend`'s signature can be the step: the
interpreted ``Controller.step`` (default) or the code-generated library loaded with
``casadi.external``.

**Failures.** A step that fails (status != SUCCESS: infeasible bounds, solver not certified)
holds still for that period; every such step is recorded (:attr:`TrackingRun.failures`). A
non-finite state stops the run with :class:`~mmstab.core.files.MmstabError`, naming the time and the
state components at fault.

**Initial state.** The base starts on the reference start pose (the circle at s = 0), sprocket
angles zero. The arm starts ``stowed`` by default (the robot arrives with its arm folded, as
the paper's Fig. 11(a) suggests) or at the plan's first posture (``initial_arm="planned"``).
For the first ``approach_time`` seconds the arm's references follow a collision-free path
from that posture onto the lap's (:class:`mmstab.control.approach.Approach`); with ``approach_time:
0``
they are the lap's from t = 0, a step the arm takes at saturated joint speeds, through the
body on the default problem.

**Stability.** After the loop, vectorised over every recorded sample: μ with the arm as it
moved (``reconfigured``), with the arm held stowed on the same base trajectory (``stowed``)
and with the arm removed (``arm_removed``, the base alone), gravity from each recorded pose
(:func:`mmstab.stability.support.stability_along`).

Modules: :mod:`~mmstab.runs.tracking.backend` (the step and one control period),
:mod:`~mmstab.runs.tracking.run` (what a run records), :mod:`~mmstab.runs.tracking.simulation`
(:func:`simulate`: set-up and record), :mod:`~mmstab.runs.tracking.loop` (the control loop),
:mod:`~mmstab.runs.tracking.summary` (:func:`summarize`).
"""

from mmstab.runs.tracking.backend import StepBackend, as_backend, build_advance
from mmstab.runs.tracking.run import (
    JOINT_NAMES,
    STATE_NAMES,
    TRANSIENT_FRACTION,
    Failure,
    InitialArm,
    Tipping,
    TrackingPlan,
    TrackingRun,
    check_plan,
    joint_names,
    state_names,
    task_batch,
)
from mmstab.runs.tracking.simulation import simulate
from mmstab.runs.tracking.summary import summarize, transient_end

__all__ = [
    "JOINT_NAMES",
    "STATE_NAMES",
    "joint_names",
    "state_names",
    "TRANSIENT_FRACTION",
    "Failure",
    "InitialArm",
    "StepBackend",
    "Tipping",
    "TrackingPlan",
    "TrackingRun",
    "as_backend",
    "build_advance",
    "check_plan",
    "simulate",
    "summarize",
    "task_batch",
    "transient_end",
]
