"""Benchmark: µs per controller step, interpreted vs generated vs pure C vs mink (not a test).

All measured side by side in one run on this machine, on the same closed loop: the default
problem's ramp circle (the default 30 s run at 1 ms = 30 000 steps), the example plan's
arm reference (:func:`mmstab.runs.rollout.example_plan`), start 5 cm off the path with the arm
stowed (so the first second saturates joint speeds). Every per-step timing replays states of
that one trajectory:

(a) interpreted: ``Controller.solve`` per QP plugin (and the bare ``Function.buffer`` call);
(b) generated library called from Python: ``casadi.external`` through ``Function.buffer``;
(c) generated step in a pure C loop (``embedded/bench.c``): median of batches of 100 calls;
(d) peer: ``mink.solve_ik`` (daqp via qpsolvers) with a ComTask, a base FrameTask,
    configuration and velocity limits, on a 7-DoF MuJoCo model of the same robot (planar
    base: slide x, slide y, hinge yaw; the 4 arm hinges with the same DH geometry and masses).

Also the whole default run's wall time per :func:`mmstab.runs.rollout.rollout` backend and for the
C loop; the time split of the default plugin's step (``embedded/bench.c``: the task Jacobian,
the QP assembly, the solver alone, the rest = glue) and the step's operation count with the
time it would take at two scalar floating-point operations per clock cycle (the limit).
Medians; the machine is shared, so expect noise.

Usage: python benchmarks/bench_codegen.py [PROBLEM.yaml] [-o JSON] [--calls N]
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.metadata
import json
import os
import subprocess
import time
from typing import Any

import casadi as ca
import numpy as np
from common import machine_info

from mmstab.codegen import CODEGEN_PLUGINS, EMBEDDED_DIR, STEP_NAME, build_programs, generate
from mmstab.control.controller import (
    PARAMS_SIZE,
    PLUGINS,
    REFERENCE_SIZE,
    STATE_SIZE,
    StepReference,
    build_controller,
    quiet_stdout,
)
from mmstab.control.controller.certificate import build_guard_and_certificate
from mmstab.control.reference import initial_state
from mmstab.core.files import write_json
from mmstab.core.problem import Problem, load_problem
from mmstab.model.robot import Robot
from mmstab.model.urdf import arm_link_inertia, dh_constant_T, rot_z_T, solid_box_inertia
from mmstab.runs.rollout import (
    BACKENDS,
    RunInputs,
    controller_settings,
    example_plan,
    rollout,
    run_file_path,
    run_inputs,
    write_run_file,
)


def _us(samples: list[float] | np.ndarray) -> float:
    return float(np.median(samples) * 1e6)


def _replay_indices(steps: int, calls: int) -> np.ndarray:
    return np.linspace(0, steps - 1, min(calls, steps)).round().astype(int)


def bench_interpreted(problem: Problem, inputs: RunInputs, states: np.ndarray, idx) -> dict:
    """(a) ``Controller.solve`` and the bare buffer call, per plugin, on replayed states."""
    out = {}
    ref = inputs.reference
    for plugin in PLUGINS:
        ctrl = build_controller(problem.robot, controller_settings(problem, plugin))
        solve_t = []
        with quiet_stdout() if plugin == "osqp" else contextlib.nullcontext():  # OSQP polish
            for k in idx:
                ref_k = StepReference.unpack(ref[k])
                t = time.perf_counter()
                ctrl.solve(states[k], *ref_k)
                solve_t.append(time.perf_counter() - t)
            call = bench_external(ctrl.step, inputs, states, idx)
        out[plugin] = {"solve_us": _us(solve_t), **call}
    return out


def bench_external(f: ca.Function, inputs: RunInputs, states: np.ndarray, idx) -> dict:
    """(b) A generated library's step through ``Function.buffer`` on replayed states."""
    state, ref, p = np.zeros(STATE_SIZE), np.zeros(REFERENCE_SIZE), np.array(inputs.params)
    assert p.size == PARAMS_SIZE
    qdot, status, objective = np.zeros(6), np.zeros(1), np.zeros(1)
    buf, ev = f.buffer()
    for i, a in enumerate((state, ref, p)):
        buf.set_arg(i, memoryview(a))
    for i, a in enumerate((qdot, status, objective)):
        buf.set_res(i, memoryview(a))
    times = []
    for k in idx:
        state[:], ref[:] = states[k], inputs.reference[k]
        t = time.perf_counter()
        ev()
        times.append(time.perf_counter() - t)
    return {"buffer_call_us": _us(times)}


# ------------------------------------------------------------------------------------- mink
def mjcf(robot: Robot) -> str:
    """A MuJoCo model of the robot on a planar base: slide x, slide y, hinge yaw + 4 arm hinges.

    Same arm DH geometry, link masses and CoMs (inertias as :mod:`mmstab.model.urdf`: solid shapes);
    the base is one body with the base mass at its CoM (solid-box inertia of the body box).
    """

    def vec(v: Any) -> str:
        return " ".join(f"{float(x):.12g}" for x in np.ravel(v))

    def quat(T: np.ndarray) -> str:
        import mujoco

        q = np.zeros(4)
        mujoco.mju_mat2Quat(q, np.ascontiguousarray(T[:3, :3]).ravel())
        return vec(q)

    def inertial(mass: float, T: np.ndarray, tensor: np.ndarray) -> str:
        R = T[:3, :3]
        full = R @ tensor @ R.T
        fi = [full[0, 0], full[1, 1], full[2, 2], full[0, 1], full[0, 2], full[1, 2]]
        return f'<inertial pos="{vec(T[:3, 3])}" mass="{mass:.12g}" fullinertia="{vec(fi)}"/>'

    base = robot.base
    box = solid_box_inertia(base.mass, base.body.size)
    body = [
        '<body name="base">',
        '<joint name="base_x" type="slide" axis="1 0 0"/>',
        '<joint name="base_y" type="slide" axis="0 1 0"/>',
        '<joint name="base_yaw" type="hinge" axis="0 0 1"/>',
        inertial(base.mass, np.block([[np.eye(3), base.com[:, None]], [0, 0, 0, 1]]), box),
        f'<body name="arm_mount" pos="{vec(robot.mount_T[:3, 3])}" quat="{quat(robot.mount_T)}">',
    ]
    close = ["</body>", "</body>"]
    prev_C = np.eye(4)
    for i, link in enumerate(robot.links):
        T = prev_C @ rot_z_T(link.theta_offset)
        inertia = arm_link_inertia(link)
        C = dh_constant_T(link)
        body += [
            f'<body name="arm_link_{i}" pos="{vec(T[:3, 3])}" quat="{quat(T)}">',
            f'<joint name="arm_joint_{i}" type="hinge" axis="0 0 1" limited="true" '
            f'range="{link.lower:.12g} {link.upper:.12g}"/>',
            inertial(inertia.mass, C @ inertia.frame_T_com, inertia.tensor),
        ]
        close.append("</body>")
        prev_C = C
    return (
        f'<mujoco model="{robot.name}_planar"><compiler angle="radian"/>'
        f"<option gravity='0 0 -9.81'/><worldbody>{''.join(body)}{''.join(close)}"
        "</worldbody></mujoco>"
    )


def bench_mink(problem: Problem, inputs: RunInputs, steps: int) -> dict:
    """(d) mink's differential-IK step on the same circle, ``steps`` closed-loop steps."""
    import mink
    import mujoco

    robot = problem.robot
    model = mujoco.MjModel.from_xml_string(mjcf(robot))
    scratch = mujoco.MjData(model)
    plan = example_plan(robot)
    cfg = mink.Configuration(model)
    base_task = mink.FrameTask("base", "body", position_cost=1.0, orientation_cost=0.01)
    com_task = mink.ComTask(cost=1.0)
    vmax = {"base_x": 2.0, "base_y": 2.0, "base_yaw": 2.0}
    vmax |= {f"arm_joint_{i}": link.velocity for i, link in enumerate(robot.links)}
    limits = [mink.ConfigurationLimit(model), mink.VelocityLimit(model, vmax)]
    dt, lap = inputs.dt, controller_settings(problem).lap_time
    poses = problem.circle.pose_at(np.arange(steps + 1) * dt / lap)
    fr = np.r_[plan.fractions, 1.0]
    posture = np.stack(
        [
            np.interp(
                np.arange(steps + 1) * dt / lap % 1.0,
                fr,
                np.r_[plan.postures[:, j], plan.postures[0, j]],
            )
            for j in range(4)
        ],
        axis=1,
    )
    q = np.r_[inputs.state0[:3], inputs.state0[5:]]
    cfg.update(q)
    solve_t, update_t = [], []
    for k in range(steps):
        x, y, yaw = poses[k]
        scratch.qpos[:] = np.r_[x, y, yaw, posture[k]]
        mujoco.mj_kinematics(model, scratch)
        mujoco.mj_comPos(model, scratch)
        com_task.set_target(scratch.subtree_com[1].copy())
        base_task.set_target(
            mink.SE3.from_rotation_and_translation(mink.SO3.from_z_radians(yaw), np.r_[x, y, 0.0])
        )
        t = time.perf_counter()
        v = mink.solve_ik(cfg, [base_task, com_task], dt, "daqp", damping=1e-6, limits=limits)
        solve_t.append(time.perf_counter() - t)
        q = cfg.integrate(v, dt)
        t = time.perf_counter()
        cfg.update(q)
        update_t.append(time.perf_counter() - t)
    final_base = float(np.hypot(*(cfg.data.qpos[:2] - poses[steps, :2])))
    return {
        "solve_ik_us": _us(solve_t),
        "update_us": _us(update_t),
        "steps": steps,
        "dof": model.nv,
        "final_base_error_m": final_base,
        "mink": importlib.metadata.version("mink"),
    }


# ------------------------------------------------------------------------------------- main
def _run_c(prog: str, run_file: str, passes: int) -> dict:
    proc = subprocess.run([prog, run_file, str(passes)], capture_output=True, text=True, check=True)
    line = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")][-1]
    return json.loads(line)


def heap_allocations_per_step(loop: str, problem: Problem, plan: Any, work: str) -> float:
    """Heap allocations per closed-loop step of the C example (``embedded/malloc_count.c``)."""
    counter = f"{work}/malloc_count.so"
    src = EMBEDDED_DIR / "malloc_count.c"
    subprocess.run(["cc", "-O2", "-fPIC", "-shared", str(src), "-o", counter, "-ldl"], check=True)
    counts = []
    for steps in (10, 1010):
        run = write_run_file(f"{work}/alloc_{steps}.bin", run_inputs(problem, plan, steps=steps))
        proc = subprocess.run(
            [loop, str(run)],
            capture_output=True,
            text=True,
            check=True,
            env={"LD_PRELOAD": counter},
        )
        line = [ln for ln in proc.stderr.splitlines() if ln.startswith("heap_allocations:")][-1]
        counts.append(int(line.split()[1]))
    return (counts[1] - counts[0]) / 1000


def step_operations(problem: Problem, plugin: str) -> dict:
    """Operations of one step: CasADi's instructions of its SX parts + the box solver's flops.

    The solver's count is its unconstrained path (one 6 × 6 LDLᵀ solve: factorisation n³/3 +
    triangular solves 2n² + the bound check), what almost every step of the run takes.
    """
    ctrl = build_controller(problem.robot, controller_settings(problem, plugin))
    sx_parts = [ctrl.qp]  # J, H, g, bounds, pre-solve checks
    _, certificate = build_guard_and_certificate(ctrl.settings.kkt_tol, ctrl.layout.joints)
    sx_parts.append(certificate)
    counted = {f.name(): f.n_instructions() - f.nnz_in() - f.nnz_out() for f in sx_parts}
    n = 6
    counted["solver (unconstrained path)"] = n**3 // 3 + 2 * n**2 + 2 * n if plugin == "box" else 0
    ops = sum(counted.values())
    mhz = _cpu_mhz()
    return {
        "operations": ops,
        "parts": counted,
        "cpu_mhz": mhz,
        "limit_us": ops / (2 * mhz) if mhz else None,
        "limit_note": "operations / (2 scalar FP operations per cycle at cpu_mhz): no SIMD",
    }


def _cpu_mhz() -> float | None:
    try:
        text = open("/proc/cpuinfo").read()
    except OSError:
        return None
    rates = [float(ln.split(":")[1]) for ln in text.splitlines() if ln.startswith("cpu MHz")]
    return max(rates) if rates else None


def time_split(c: dict) -> dict:
    """Fractions of the C step's median in the Jacobian, the QP (assembly, solver) and glue."""
    step, split = c["median_us"], c["split_us"]
    solver = max(split["solver"], 0.0)
    parts = {
        "jacobian": split["jacobian"],
        "qp_assembly": split["qp_data"] - split["jacobian"],
        "qp_solver": solver,
        "glue": step - split["qp_data"] - solver,
    }
    return {
        "step_us": step,
        "us": parts,
        "fraction": {k: v / step for k, v in parts.items()},
        "method": "manual split (embedded/bench.c): controller_jacobian, controller_qp_data "
        "(J + assembly + pre-solve checks) and mmstab_boxqp on the recorded QPs timed alone in "
        "the same batches; glue = step - qp_data - solver (the certificate, CasADi's copies)",
    }


def main() -> None:
    """Measure everything and write the JSON summary."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("problem", nargs="?", default="problems/ramp.yaml")
    ap.add_argument("-o", "--out", default="results/bench/bench.json")
    ap.add_argument("--calls", type=int, default=3000, help="replayed steps for (a), (b)")
    ap.add_argument("--mink-steps", type=int, default=3000)
    ap.add_argument("--passes", type=int, default=5, help="passes over the run for (c)")
    ap.add_argument("--work", default="results/codegen/bench", help="generated code folder")
    args = ap.parse_args()
    load_start = [round(x, 2) for x in os.getloadavg()]
    problem = load_problem(args.problem)
    plan = example_plan(problem.robot)
    state0 = initial_state(problem.circle, problem.robot.stowed, lateral_offset=0.05)
    inputs = run_inputs(problem, plan, state0=state0)
    default_plugin = controller_settings(problem).plugin
    traj = rollout(
        problem, plan, backend="generated", inputs=inputs, out_dir=f"{args.work}/{default_plugin}"
    )
    states = traj.states
    idx = _replay_indices(inputs.steps, args.calls)
    print(f"closed loop: {inputs.steps} steps, failures {traj.failures}")

    result: dict[str, Any] = {"interpreted": bench_interpreted(problem, inputs, states, idx)}
    for plugin, r in result["interpreted"].items():
        print(
            f"(a) interpreted {plugin:8s} solve {r['solve_us']:7.2f} us, "
            f"call {r['buffer_call_us']:7.2f} us"
        )
    result["generated_python"], result["generated_c"] = {}, {}
    for plugin in CODEGEN_PLUGINS:
        gen = generate(problem, f"{args.work}/{plugin}", plugin)
        with quiet_stdout() if plugin == "osqp" else contextlib.nullcontext():
            result["generated_python"][plugin] = bench_external(
                gen.load(STEP_NAME), inputs, states, idx
            )
        progs = build_programs(gen)
        run_file = write_run_file(run_file_path(gen.directory), inputs)
        result["generated_c"][plugin] = _run_c(str(progs.bench), str(run_file), args.passes)
        result["generated_c"][plugin]["heap_allocations_per_step"] = heap_allocations_per_step(
            str(progs.loop), problem, plan, str(gen.directory)
        )
        rp, rc = result["generated_python"][plugin], result["generated_c"][plugin]
        print(
            f"(b) generated {plugin:5s} from Python {rp['buffer_call_us']:6.2f} us; "
            f"(c) pure C median {rc['median_us']:6.3f} us (p99 single {rc['single_p99_us']:.2f}), "
            f"C whole run {rc['loop_s']:.4f} s, "
            f"{rc['heap_allocations_per_step']:g} heap allocations per step"
        )
    # the opt-in -march=native build of the default plugin, same run file
    gen = generate(problem, f"{args.work}/{default_plugin}_native", default_plugin, native=True)
    progs = build_programs(gen)
    run_file = write_run_file(run_file_path(gen.directory), inputs)
    result["generated_c_native"] = {
        default_plugin: _run_c(str(progs.bench), str(run_file), args.passes)
    }
    rn = result["generated_c_native"][default_plugin]
    print(f"(c) pure C {default_plugin} -march=native median {rn['median_us']:6.3f} us")
    try:
        result["mink"] = bench_mink(problem, inputs, args.mink_steps)
        print(
            f"(d) mink solve_ik {result['mink']['solve_ik_us']:.1f} us "
            f"(+ update {result['mink']['update_us']:.1f} us)"
        )
    except ImportError as exc:
        result["mink"] = {"skipped": f"optional dependency missing: {exc}"}
        print(f"(d) mink skipped: {exc}")
    runs = {}
    for backend in BACKENDS:
        repeats = 1 if backend == "python" else 3
        walls = []
        for _ in range(repeats):
            t = time.perf_counter()
            r = rollout(
                problem,
                plan,
                backend=backend,
                inputs=inputs,
                out_dir=f"{args.work}/{default_plugin}",
            )
            walls.append(time.perf_counter() - t)
        runs[backend] = {
            "wall_s": float(np.median(walls)),
            "repeats": repeats,
            "failures": r.failures,
        }
        print(
            f"whole run ({inputs.steps} steps) backend {backend:9s}: "
            f"{runs[backend]['wall_s']:.3f} s"
        )
    runs["c_loop"] = {
        "wall_s": result["generated_c"][default_plugin]["loop_s"],
        "plugin": default_plugin,
    }
    result["whole_run"] = runs
    c_med = result["generated_c"][default_plugin]["median_us"]
    if "solve_ik_us" in result["mink"]:
        result["speedup_c_vs_mink"] = result["mink"]["solve_ik_us"] / c_med
    if default_plugin == "box":
        result["time_split"] = time_split(result["generated_c"][default_plugin])
        print("time split of the C step:", result["time_split"]["fraction"])
    result["limit"] = step_operations(problem, default_plugin)
    print(f"step operations {result['limit']['operations']}, limit {result['limit']['limit_us']}")
    write_json(
        args.out,
        {
            "what": "µs per controller step (medians) and whole-run wall time, one run",
            "note": "shared 2-core machine: noisy; (a)/(b) replay the same closed-loop states",
            "problem": str(args.problem),
            "steps": inputs.steps,
            "replayed_calls": len(idx),
            "default_codegen_plugin": default_plugin,
            "machine": machine_info(
                load_average_start=load_start,
                cc=subprocess.run(
                    ["cc", "--version"], capture_output=True, text=True
                ).stdout.splitlines()[0],
            ),
            **result,
        },
    )
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
