from __future__ import annotations

import dataclasses
import shutil
import subprocess
import sys

import casadi as ca
import numpy as np
import pytest
from conftest import write_problem

import mmstab.codegen as codegen
import mmstab.codegen.build as codegen_build
import mmstab.control.controller.step as controller_step_mod
from mmstab.cli import main
from mmstab.codegen import (
    CODEGEN_PLUGINS,
    PLANT_NAME,
    QPOASES_MESSAGE,
    ROLLOUT_CHUNK,
    STEP_NAME,
    TASK_NAME,
    build_programs,
    generate,
    load_step,
    postprocess,
)
from mmstab.control.controller import (
    PARAMS_SIZE,
    REFERENCE_SIZE,
    STATE_SIZE,
    ControllerParams,
    QPStatus,
    StepReference,
    build_controller,
    quiet_stdout,
)
from mmstab.control.limits import YawRateLimit
from mmstab.control.reference import initial_state
from mmstab.core.files import ConfigError, MmstabError
from mmstab.core.problem import load_problem
from mmstab.runs.rollout import (
    controller_settings,
    example_plan,
    rollout,
    run_inputs,
    write_run_file,
)

pytestmark = pytest.mark.slow  # compiles C; still part of `make test`


@pytest.fixture(scope="session")
def built(problem, tmp_path_factory):
    """A plugin's C generated and compiled once a session, its example programs on first use.

    The fixtures below share it: the same plugin's library and programs are built once.
    """
    made: dict = {}

    def get(plugin: str, programs: bool = False):
        if plugin not in made:
            made[plugin] = [generate(problem, tmp_path_factory.mktemp(f"codegen_{plugin}"), plugin)]
        if programs and len(made[plugin]) == 1:
            out = tmp_path_factory.mktemp(f"programs_{plugin}")
            made[plugin].append(build_programs(made[plugin][0], out))
        return made[plugin][0], (made[plugin][1] if programs else None)

    return get


@pytest.fixture(scope="session", params=CODEGEN_PLUGINS)
def generated(request, built):
    return built(request.param)[0]


@pytest.fixture(scope="session")
def generated_default(problem, built):
    """The problem's own plugin (codegen.plugin: box), found up to date in box's folder."""
    gen = generate(problem, built("box")[0].directory)
    assert gen.plugin == "box"
    return gen


@pytest.fixture(scope="session")
def programs(generated_default, built):
    return built(generated_default.plugin, programs=True)[1]


@pytest.fixture(scope="session", params=("box", "qrqp"))
def heap_free(request, built):
    """The plugins whose generated step must not touch the heap, with their programs."""
    return built(request.param, programs=True)


def random_cases(robot, rng: np.random.Generator, n: int):
    """States within and around the limits, random references; every 50th has a NaN."""
    lo, hi = robot.joint_lower, robot.joint_upper
    span = hi - lo
    for k in range(n):
        q = rng.uniform(lo - 0.05 * span, hi + 0.05 * span)
        state = np.r_[rng.uniform(-2, 2, 2), rng.uniform(-np.pi, np.pi), rng.uniform(-9, 9, 2), q]
        xi_des = np.r_[state[:2] + rng.normal(0, 0.2, 2), rng.uniform(-np.pi, np.pi)]
        xi_des = np.r_[xi_des, rng.uniform(-1, 1, 3)]
        q_ref = rng.uniform(lo - 0.05 * span, hi + 0.05 * span)
        ground = rng.normal(0, 0.2, 3)  # any local ground: the step is terrain-agnostic
        ref = np.r_[xi_des, rng.normal(0, 0.3, 6), q_ref, rng.normal(0, 1.0, 4), ground]
        if k % 50 == 49:
            bad = state if k % 100 == 49 else ref
            bad[rng.integers(0, bad.size)] = np.nan
        yield state, ref


# ------------------------------------------------------------------------ generated = interpreted
def test_generated_step_equals_interpreted_on_1000_states(generated, problem, rng):
    ext = generated.load(STEP_NAME)
    ctrl = build_controller(problem.robot, controller_settings(problem, generated.plugin))
    p = ctrl.params.pack()
    tracks = problem.robot.base.tracks
    worst, statuses, turn_bound = 0.0, [], 0
    with quiet_stdout():  # OSQP's polish line
        for state, ref in random_cases(problem.robot, rng, 1000):
            a = [np.asarray(v) for v in ctrl.step(state, ref, p)]
            b = [np.asarray(v) for v in ext(state, ref, p)]
            assert a[1].item() == b[1].item()
            worst = max(worst, max(float(np.max(np.abs(x - y))) for x, y in zip(a, b, strict=True)))
            statuses.append(int(b[1].item()))
            # the yaw-rate limit binds (ground of 6° or more): |ω| = |γ̇_ref| + margin
            yaw = tracks.sprocket_radius * (b[0][1] - b[0][0]) / tracks.separation
            at_bound = abs(abs(yaw) - abs(ref[8]) - YawRateLimit().margin) < 1e-6
            turn_bound += bool(b[1].item() == 0 and at_bound)
    assert worst <= 1e-10
    assert turn_bound > 50  # the generated step has the limit where the interpreted one does
    seen = set(statuses)  # the cases reach success and both pre-solve refusals
    assert {QPStatus.SUCCESS, QPStatus.INFEASIBLE, QPStatus.NONFINITE_INPUT} <= seen
    assert statuses.count(QPStatus.SUCCESS) > 500


def test_solver_failure_gives_the_same_status_generated(problem, tmp_path, monkeypatch, rng):
    # a QP solver allowed one iteration fails on most QPs: without the post-processing the
    # generated step would abort ("Evaluation failed") instead of reporting SOLVER_FAILED
    real = controller_step_mod._conic_options

    def one_iteration(settings):
        return {**real(settings), "max_iter": 1}

    monkeypatch.setattr(controller_step_mod, "_conic_options", one_iteration)
    settings = controller_settings(problem, "qrqp")
    gen = generate((problem.robot, settings), tmp_path)
    ext, ctrl = gen.load(), build_controller(problem.robot, settings)
    p, statuses = ctrl.params.pack(), []
    for state, ref in random_cases(problem.robot, rng, 200):
        a = [np.asarray(v) for v in ctrl.step(state, ref, p)]
        b = [np.asarray(v) for v in ext(state, ref, p)]
        assert a[1].item() == b[1].item()
        for x, y in zip(a, b, strict=True):
            np.testing.assert_allclose(x, y, rtol=0, atol=1e-10)
        statuses.append(int(b[1].item()))
        if b[1].item() == QPStatus.SOLVER_FAILED:
            assert np.all(np.asarray(b[0]) == 0)  # the safe action
    assert statuses.count(QPStatus.SOLVER_FAILED) > 50


# ----------------------------------------------------------------------------------- compiling
def test_c_compiles_without_any_warning(generated):
    assert generated.rebuilt
    assert generated.compiler_stderr == ""
    # and again, by hand, with the flags the brief names
    cflags, ldflags = codegen.plugin_flags(generated.plugin)
    cmd = ["cc", "-O3", "-std=c99", "-Wall", "-Wextra", "-Werror", "-fPIC", "-shared", *cflags]
    lib = generated.directory / "again.so"
    proc = subprocess.run(
        [*cmd, str(generated.source), "-o", str(lib), *ldflags], capture_output=True, text=True
    )
    assert proc.returncode == 0 and proc.stderr == "" and proc.stdout == ""
    text = generated.source.read_text()
    assert text.count("mmstab: the QP's own failure flag is ignored") == 1
    assert "#error" not in text


def test_heap_free_library_references_no_allocator(heap_free):
    nm = shutil.which("nm")
    if nm is None:
        pytest.skip("no nm")
    out = subprocess.run(
        [nm, "-D", "--undefined-only", str(heap_free[0].library)],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    symbols = {line.split()[-1].split("@")[0] for line in out.splitlines() if line.strip()}
    assert symbols, "nm listed nothing"
    assert not symbols & {"malloc", "calloc", "realloc", "free", "posix_memalign"}


def test_work_sizes_come_from_the_generated_work_function(generated_default):
    header = generated_default.header.read_text()
    sizes = codegen.work_sizes(generated_default.library)
    assert sizes.w > 0 and sizes.arg >= 3 and sizes.res >= 3
    for what, value in zip(("ARG", "RES", "IW", "W"), sizes, strict=True):
        assert f"#define {STEP_NAME}_SZ_{what} {value}\n" in header
    meta = (generated_default.directory / "build.json").read_text()
    assert f'"w": {sizes.w}' in meta


def test_layout_header_matches_the_python_layouts(generated_default):
    """controller_layout.h: the sizes and offsets C uses are the Python ones."""
    text = generated_default.layout.read_text()
    defines = [line.split() for line in text.splitlines() if line.startswith("#define MMSTAB_")]
    macros = {d[1]: d[2] for d in defines if len(d) == 3}
    expected = {"STATE": STATE_SIZE, "REFERENCE": REFERENCE_SIZE, "PARAMS": PARAMS_SIZE}
    for name, value in {**expected, "GROUND": 3, "ARM": 4}.items():
        assert int(macros[f"MMSTAB_N_{name}"]) == value, name
    for layout, prefix in ((StepReference, "REF"), (ControllerParams, "PARAM")):
        for field, sl in layout.offsets().items():
            assert int(macros[f"MMSTAB_{prefix}_{field.upper()}"]) == sl.start, field
    assert int(macros["MMSTAB_REF_Q_REF"]) == 12 and int(macros["MMSTAB_PARAM_DT"]) == 27


def test_postprocess_refuses_unexpected_code():
    with pytest.raises(RuntimeError, match="one call of controller_qp"):
        postprocess("/* generated */\nint main(void) { return 0; }\n", "controller_qp")
    twice = "/* g */\n/* #1: @1 = controller_qp(@0) */\n" + "if (flag) return 1;\n" * 2 + "/* #2 */"
    with pytest.raises(RuntimeError, match="one failure check"):
        postprocess(twice, "controller_qp")


# -------------------------------------------------------------------------------------- cache
def test_cache_rebuilds_only_when_the_generated_code_changes(problem, tmp_path):
    settings = controller_settings(problem, "qrqp")
    first = generate((problem.robot, settings), tmp_path)
    again = generate((problem.robot, settings), tmp_path)
    assert first.rebuilt and not again.rebuilt
    assert again.library == first.library and again.hash == first.hash
    # gains are run-time parameters: same code, no rebuild
    gains = generate((problem.robot, dataclasses.replace(settings, kp=(2.0,) * 6)), tmp_path)
    assert not gains.rebuilt and gains.hash == first.hash
    # the base offset is baked into the C: new key, new library, the old one removed
    moved = generate((problem.robot, dataclasses.replace(settings, base_offset=0.3)), tmp_path)
    assert moved.rebuilt and moved.hash != first.hash and moved.library.is_file()
    assert not first.library.exists()
    forced = generate((problem.robot, settings), tmp_path, force=True)
    assert forced.rebuilt


def test_load_step_uses_the_problem_codegen_section(tmp_path):
    def edit(prob, rob):
        prob["codegen"]["directory"] = str(tmp_path / "gen")

    problem = load_problem(write_problem(tmp_path, edit))
    step = load_step(problem)
    assert step.name() == STEP_NAME
    assert [step.size1_in(i) for i in range(3)] == [STATE_SIZE, REFERENCE_SIZE, PARAMS_SIZE]
    assert [step.size1_out(i) for i in range(3)] == [6, 1, 1]
    assert (tmp_path / "gen" / "box" / f"{STEP_NAME}.c").is_file()
    ctrl = build_controller(problem.robot, controller_settings(problem))
    state = np.r_[0.1, -1.4, 0.2, 0.0, 0.0, 2.0, 0.3, -0.5, 0.2]
    ref = np.r_[
        ctrl.model.task(state) + 0.01, np.zeros(6), state[5:] + 0.02, np.zeros(4), np.zeros(3)
    ]
    p = ctrl.params.pack()
    np.testing.assert_array_equal(
        np.asarray(step(state, ref, p)[0]), np.asarray(ctrl.step(state, ref, p)[0])
    )


# ---------------------------------------------------------------------------------- qpOASES
def test_qpoases_is_refused_before_casadi_is_called(problem, tmp_path, monkeypatch):
    def never(*args, **kwargs):
        raise AssertionError("CasADi was called")

    monkeypatch.setattr(codegen_build, "build_controller", never)
    monkeypatch.setattr(codegen_build.ca, "CodeGenerator", never)
    with pytest.raises(MmstabError, match="CasADi cannot generate C for qpOASES; use box, qrqp"):
        generate(problem, tmp_path / "out", "qpoases")
    with pytest.raises(MmstabError, match="unknown QP plugin"):
        generate(problem, tmp_path / "out", "gurobi")
    assert not (tmp_path / "out").exists()


def test_cli_qpoases_exits_2_with_the_message(tmp_path, capsys):
    path = write_problem(tmp_path)
    code = main(["codegen", str(path), "-o", str(tmp_path / "out"), "--plugin", "qpoases"])
    assert code == 2
    assert QPOASES_MESSAGE in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_problem_with_qpoases_codegen_plugin_is_a_config_error(tmp_path):
    def edit(prob, rob):
        prob["codegen"]["plugin"] = "qpoases"

    with pytest.raises(ConfigError, match="codegen.plugin: CasADi cannot generate C for qpOASES"):
        load_problem(write_problem(tmp_path, edit))


def test_cli_codegen_writes_and_then_reuses(tmp_path, capsys):
    path = write_problem(tmp_path)
    out = tmp_path / "out"
    assert main(["codegen", str(path), "-o", str(out)]) == 0
    assert "generated and compiled" in capsys.readouterr().out
    assert main(["codegen", str(path), "-o", str(out)]) == 0
    assert "up to date" in capsys.readouterr().out
    assert (out / f"{STEP_NAME}.h").is_file() and (out / "build.json").is_file()


# ------------------------------------------------------------------------ embedded example
def _parse(stdout: str, key: str) -> np.ndarray:
    line = next(ln for ln in stdout.splitlines() if ln.startswith(key + ":"))
    return np.array([float(x) for x in line.split(":", 1)[1].split()])


def test_embedded_example_matches_the_python_closed_loop(problem, programs, tmp_path):
    progs = programs
    assert progs.compiler_stderr == ""
    plan = example_plan(problem.robot)
    state0 = initial_state(problem.circle, problem.robot.stowed, lateral_offset=0.05)
    inputs = run_inputs(problem, plan, steps=2000, state0=state0)
    run_file = write_run_file(tmp_path / "run.bin", inputs)
    proc = subprocess.run(
        [str(progs.loop), str(run_file)], capture_output=True, text=True, check=True
    )
    assert proc.stderr == ""
    py = rollout(problem, plan, backend="python", inputs=inputs)
    np.testing.assert_allclose(_parse(proc.stdout, "final_state"), py.states[-1], atol=1e-6, rtol=0)
    np.testing.assert_allclose(_parse(proc.stdout, "final_error"), py.errors[-1], atol=1e-6, rtol=0)
    assert f"failures: {py.failures} of 2000" in proc.stdout
    # every answer passed the example's own KKT check (at the certificate's tolerance)
    ok = 2000 - py.failures
    assert f"kkt: {ok} of {ok} answers checked, 0 over tolerance 1e-06 rad/s" in proc.stdout
    # the run really converges from its 5 cm off the path; the arm starts on its approach
    # reference (from the stowed posture), so its CoM error at t = 0 is the base's offset
    assert np.hypot(*py.errors[0, :2]) == pytest.approx(0.05, rel=1e-9)
    np.testing.assert_allclose(py.errors[0, 3:], np.r_[py.errors[0, :2], 0.0], atol=1e-12)
    assert np.abs(py.errors[-1]).max() < 0.05
    assert np.abs(py.errors[-1, [0, 1, 3, 4, 5]]).max() < 2e-3


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="LD_PRELOAD counter: glibc")
def test_heap_free_closed_loop_allocates_nothing_per_step(problem, heap_free, tmp_path):
    counter = tmp_path / "malloc_count.so"
    src = codegen.EMBEDDED_DIR / "malloc_count.c"
    subprocess.run(
        ["cc", "-O2", "-fPIC", "-shared", str(src), "-o", str(counter), "-ldl"], check=True
    )
    plan = example_plan(problem.robot)
    counts = []
    for steps in (10, 1010):
        run_file = write_run_file(
            tmp_path / f"run{steps}.bin", run_inputs(problem, plan, steps=steps)
        )
        proc = subprocess.run(
            [str(heap_free[1].loop), str(run_file)],
            capture_output=True,
            text=True,
            check=True,
            env={"LD_PRELOAD": str(counter)},
        )
        counts.append(int(_parse(proc.stderr, "heap_allocations")[0]))
    assert counts[0] > 0  # the counter works (the run file is read into one block)
    assert counts[1] == counts[0]  # 1000 more steps, not one more allocation


def test_embedded_example_refuses_a_bad_run_file(programs, tmp_path):
    progs = programs
    bad = tmp_path / "bad.bin"
    sizes = [10, STATE_SIZE, REFERENCE_SIZE - 3, PARAMS_SIZE]  # the reference before the ground
    bad.write_bytes(b"MMSTRUN2" + np.array(sizes, "<i8").tobytes())
    proc = subprocess.run([str(progs.loop), str(bad)], capture_output=True, text=True)
    assert proc.returncode == 1 and "do not match the controller" in proc.stderr
    old = tmp_path / "old.bin"  # the format with the hand-written plant's track data
    old.write_bytes(b"MMSTRUN1" + np.array([*sizes, 3], "<i8").tobytes())
    proc = subprocess.run([str(progs.loop), str(old)], capture_output=True, text=True)
    assert proc.returncode == 1 and "not a run file" in proc.stderr


# ----------------------------------------------------------------------------------- rollout
def test_rollout_backends_equal_the_python_step_loop(problem, generated_default):
    plan = example_plan(problem.robot)
    state0 = initial_state(problem.circle, problem.robot.stowed, lateral_offset=0.05)
    steps = ROLLOUT_CHUNK + 250  # a full chunk and a padded one
    inputs = run_inputs(problem, plan, steps=steps, state0=state0)
    ref = rollout(problem, plan, backend="python", inputs=inputs)
    assert ref.states.shape == (steps + 1, 9) and ref.qdot.shape == (steps, 6)
    assert np.abs(ref.qdot).max() > 1.0  # the start transient moves the joints
    for backend in ("casadi", "generated"):
        r = rollout(
            problem, plan, backend=backend, inputs=inputs, out_dir=generated_default.directory
        )
        assert np.max(np.abs(r.states - ref.states)) <= 1e-9
        assert np.max(np.abs(r.qdot - ref.qdot)) <= 1e-9
        np.testing.assert_array_equal(r.status, ref.status)


def test_python_step_loop_is_controller_step_and_f_integrate(problem):
    plan = example_plan(problem.robot)
    inputs = run_inputs(problem, plan, steps=20)
    r = rollout(problem, plan, backend="python", inputs=inputs)
    ctrl = build_controller(problem.robot, controller_settings(problem))
    f_step, f_int = ctrl.step, ctrl.model.f_integrate
    s = inputs.state0
    for k in range(20):
        qdot = f_step(s, inputs.reference[k], inputs.params)[0]
        s = np.asarray(f_int(s, qdot, inputs.dt)).ravel()
        np.testing.assert_allclose(r.states[k + 1], s, atol=1e-12, rtol=0)
    assert r.times[-1] == pytest.approx(20 * inputs.dt)


def test_generated_plant_equals_the_simulation_plant(generated_default, problem, rng):
    """controller_plant (what the C example moves the robot with) is the Python plant."""
    plant = generated_default.load(PLANT_NAME)
    ctrl = build_controller(problem.robot, controller_settings(problem))
    r, b = problem.robot.base.tracks.sprocket_radius, problem.robot.base.tracks.separation
    for k in range(40):
        state = np.r_[rng.uniform(-2, 2, 3), rng.uniform(-9, 9, 6)]
        qdot = rng.uniform(-5, 5, 6)
        if k % 4 == 0:  # straight, and the series branch of sin(a)/a
            qdot[1] = qdot[0] + (0.0 if k % 8 == 0 else 1e-9)
        out = np.asarray(plant(state, qdot, 1e-3)).ravel()
        np.testing.assert_allclose(out, ctrl.model.integrate(state, qdot, 1e-3), atol=1e-14)
        # independently: the arc by hand (heading change ω dt, chord along the mid heading)
        v, w = r * (qdot[0] + qdot[1]) / 2, r * (qdot[1] - qdot[0]) / b
        assert out[2] == pytest.approx(state[2] + w * 1e-3, abs=1e-14)
        mid = state[2] + w * 1e-3 / 2
        chord = out[:2] - state[:2]
        assert abs(chord @ [-np.sin(mid), np.cos(mid)]) < 1e-14
        assert np.linalg.norm(chord) == pytest.approx(abs(v) * 1e-3, rel=1e-6, abs=1e-15)


def test_example_task_function_is_exported(generated_default, problem):
    task = generated_default.load(TASK_NAME)
    ctrl = build_controller(problem.robot, controller_settings(problem))
    state = np.r_[0.3, -1.2, 0.7, 1.0, 2.0, 2.2, 0.1, -0.3, 0.4]
    ground = np.array([0.1, 0.05, -0.2])
    np.testing.assert_allclose(
        np.asarray(task(state, ground)).ravel(), ctrl.model.task(state, ground), atol=1e-14
    )
    with pytest.raises(ValueError, match="not exported"):
        generated_default.load("nope")
    assert isinstance(task, ca.Function)


def test_rollout_rejects_bad_arguments(problem):
    plan = example_plan(problem.robot)
    with pytest.raises(ValueError, match="unknown backend"):
        rollout(problem, plan, backend="matlab", steps=5)
    with pytest.raises(ValueError, match=r"state0 must have shape \(9,\)"):
        run_inputs(problem, plan, steps=5, state0=np.zeros(8))
    with pytest.raises(ValueError, match="at least one step"):
        run_inputs(problem, plan, steps=0)
