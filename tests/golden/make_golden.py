"""The ramp's golden numbers: what the library computes today, to pin a refactor.

Run once on the code to pin (``python tests/golden/make_golden.py``): it writes
``tests/golden/ramp.json``. ``tests/golden/test_golden_ramp.py`` recomputes the same numbers with
:func:`compute` and compares them with the file (≤ 1e-9 where deterministic).

What is pinned (all on ``problems/ramp.yaml``, the workspace on a coarse grid so it builds in a
few seconds):

- Fig. 5 / Fig. 6 sweeps: μ over link0 at the roll pose and at the circle's 11 poses, their
  maxima, and μ stowed / arm removed.
- The plan: CMA-ES with today's planner settings written out (not the YAML's), on the 10 poses of
  the circle: CoM targets, μ, fitness, realising postures.
- A short tracking run (1.5 s, the example plan, interpreted qpOASES step): tracking errors,
  μ (reconfigured / stowed / arm removed), final state, task and reference at a few samples.
- The controller step (interpreted and generated C, qrqp) on fixed states.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
GOLDEN = HERE / "ramp.json"
sys.path.insert(0, str(HERE.parent))  # conftest's write_problem

#: The coarse workspace grid of the golden plan (the same for generation and test).
GRID = [10, 8, 8, 8]
#: Today's planner settings, written out (the planner's defaults may change).
PLANNER = {
    "w_stability": 0.9,
    "w_motion": 0.1,
    "poses": 10,
    "starts": [2.0, 5.0],
    "sigma0": 0.05,
    "popsize": 16,
    "max_iterations": 20,
    "tol_fitness": 1.0e-7,
    "tol_x": 1.0e-4,
    "max_resample": 3,
    "seed": 7,
    # the first release's search, explicit since the planner gained other searches
    "method": "cmaes",
    "seeding": "starts",
    "sigma0_unit": "m",
    "restarts": 0,
    "turret_window": None,
}
TRACK_SECONDS = 1.5  #: length of the pinned tracking run [s]
STEP_STATES = 12  #: fixed states the step is pinned on
SAMPLES = (0, 250, 700, 1000, 1499)  #: run samples whose task/reference are pinned


def golden_problem(tmp: Path) -> Any:
    """The default problem with the coarse workspace grid and today's planner settings."""
    from conftest import write_problem

    from mmstab.core.problem import load_problem

    def edit(p: dict[str, Any], r: dict[str, Any]) -> None:
        p["workspace"]["grid"] = list(GRID)
        p["planner"].update(PLANNER)

    return load_problem(write_problem(tmp, edit, "golden.yaml"))


def step_cases(robot: Any) -> tuple[np.ndarray, np.ndarray]:
    """Fixed (state, reference) pairs around the circle, within and at the joint limits."""
    rng = np.random.default_rng(20261123)
    lo, hi = robot.joint_lower, robot.joint_upper
    states, refs = [], []
    for k in range(STEP_STATES):
        q = rng.uniform(lo, hi)
        if k % 4 == 3:
            q[k % 4] = hi[k % 4]  # a joint on its limit: a bound is active
        state = np.r_[rng.uniform(-2, 2, 2), rng.uniform(-np.pi, np.pi), rng.uniform(-9, 9, 2), q]
        xi_des = np.r_[state[:2] + rng.normal(0, 0.2, 2), rng.uniform(-np.pi, np.pi)]
        xi_des = np.r_[xi_des, rng.uniform(-1, 1, 3)]
        ref = np.r_[xi_des, rng.normal(0, 0.3, 6), rng.uniform(lo, hi), rng.normal(0, 1.0, 4)]
        states.append(state)
        refs.append(ref)
    return np.array(states), np.array(refs)


def compute_sweeps(problem: Any) -> dict[str, Any]:
    """Fig. 5 and Fig. 6: μ over the link0 sweep, maxima, stowed and arm removed."""
    from experiments.common import circular_extrema
    from experiments.sweeps import link0_sweep

    cfg = problem.section("sweep")
    out: dict[str, Any] = {}
    for name, poses in (
        ("fig5", np.array([cfg["roll_pose"]], dtype=float)),
        ("fig6", problem.circle.poses(cfg["poses"])),
    ):
        sw = link0_sweep(problem.robot, problem.terrain, poses, cfg["samples"])
        out[name] = {
            "poses": sw.poses,
            "mu": sw.mu,
            "mu_max": sw.mu.max(axis=1),
            "maxima_index": [circular_extrema(m)[0].tolist() for m in sw.mu],
            "mu_arm_removed": sw.mu_arm_removed,
            "mu_stowed": sw.mu_stowed,
        }
    return out


def compute_plan(problem: Any, cache: Path) -> dict[str, Any]:
    """The plan on the coarse workspace with today's planner settings, written out."""
    from mmstab.planner import plan_path
    from mmstab.workspace import load_or_build_workspace

    ws = load_or_build_workspace(problem, progress=False, cache_dir=cache)
    plan = plan_path(problem, ws)
    return {
        "poses": plan.poses,
        "target_com": plan.target_com,
        "mu": [t.mu for t in plan.targets],
        "fitness": [t.fitness for t in plan.targets],
        "postures": plan.postures,
    }


def compute_tracking(problem: Any) -> dict[str, Any]:
    """A short tracking run with the example plan (interpreted step)."""
    from mmstab.runs.rollout import example_plan
    from mmstab.runs.tracking import simulate

    run = simulate(problem, example_plan(problem.robot), duration=TRACK_SECONDS, progress=False)
    k = list(SAMPLES)
    return {
        "steps": run.steps,
        "failures": len(run.failures),
        "final_state": run.state[-1],
        "states": run.state[k],
        "xi": run.xi[k],
        "xi_des": run.xi_des[k],
        "xi_dot_ref": run.xi_dot_ref[k],
        "q_ref": run.q_ref[k],
        "qdot": run.qdot[[min(i, run.steps - 1) for i in k]],
        "base_error_max": float(run.base_error.max()),
        "arm_com_error_max": float(run.arm_com_error.max()),
        "heading_error_max": float(np.abs(run.heading_error).max()),
        "base_error": run.base_error[k],
        "arm_com_error": run.arm_com_error[k],
        "mu_reconfigured": run.mu.reconfigured[k],
        "mu_stowed": run.mu.stowed[k],
        "mu_arm_removed": run.mu.arm_removed[k],
        "mu_min": {n: float(v.min()) for n, v in run.mu._asdict().items()},
    }


def full_reference(problem: Any, state: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """The step's reference vector from the pinned (ξ_des, ξ̇_ref, q_ref, q̇_ref) (20,).

    Since the terrain interface the step also takes the local ground of the pose (zero on
    the ramp), appended after the pinned 20 numbers.
    """
    from mmstab.control.controller import StepReference

    if "ground" not in StepReference._fields:
        return np.asarray(ref)
    return np.r_[ref, problem.terrain.local_ground(np.asarray(state)[:3])[0]]


def compute_step(problem: Any) -> dict[str, Any]:
    """The interpreted controller step (qrqp) on fixed states."""
    import dataclasses

    from mmstab.control.controller import ControllerSettings, build_controller, quiet_stdout

    settings = ControllerSettings.from_section(problem.section("controller"))
    ctrl = build_controller(problem.robot, dataclasses.replace(settings, plugin="qrqp"))
    states, refs = step_cases(problem.robot)
    p = ctrl.params.pack()
    qdot, status, objective = [], [], []
    with quiet_stdout():
        for s, r in zip(states, refs, strict=True):
            a, b, c = (
                np.asarray(v).ravel() for v in ctrl.step(s, full_reference(problem, s, r), p)
            )
            qdot.append(a)
            status.append(float(b[0]))
            objective.append(float(c[0]))
    return {"states": states, "refs": refs, "qdot": qdot, "status": status, "objective": objective}


def compute(tmp: Path) -> dict[str, Any]:
    """Every golden number (``tmp``: a scratch folder for the problem copy and caches)."""
    problem = golden_problem(tmp)
    return {
        "sweeps": compute_sweeps(problem),
        "plan": compute_plan(problem, tmp / "cache"),
        "tracking": compute_tracking(problem),
        "step": compute_step(problem),
    }


def to_json(value: Any) -> Any:
    """Arrays and NumPy scalars as plain lists and floats (full precision)."""
    if isinstance(value, dict):
        return {k: to_json(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [to_json(v) for v in value]
    if isinstance(value, np.ndarray):
        return to_json(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    return value


def main() -> None:
    """Compute the golden numbers and write ``tests/golden/ramp.json``."""
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        data = to_json(compute(Path(tmp)))
    GOLDEN.write_text(json.dumps(data, indent=1) + "\n")
    print(f"wrote {GOLDEN}")


if __name__ == "__main__":
    main()
