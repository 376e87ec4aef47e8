"""The control loop of a tracking run: ``advance`` on buffers bound once (:func:`run_loop`)."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from mmstab.control.controller import quiet_stdout
from mmstab.core.files import MmstabError
from mmstab.model.robot import FloatArray
from mmstab.runs.tracking.run import state_names

PROGRESS_CHUNK = 500  #: steps between progress-bar updates (and tipping checks)


def describe_nonfinite(state: FloatArray) -> str:
    """The names of the state's non-finite components (``"none"`` if all are finite)."""
    names = state_names(len(state) - 5)
    bad = [names[i] for i in np.flatnonzero(~np.isfinite(state))]
    return ", ".join(bad) if bad else "none"


def run_loop(
    advance: ca.Function,
    state0: FloatArray,
    reference: FloatArray,
    params: FloatArray,
    steps: int,
    dt: float,
    progress: bool,
    first_tip: Callable[[FloatArray], int | None] | None = None,
) -> tuple[FloatArray, FloatArray, NDArray[np.int8], float]:
    """The control loop: ``steps`` calls of ``advance`` on buffers bound once.

    Args:
        advance: from :func:`build_advance`.
        state0: initial state (5 + n,), n the arm's joints (9 for the 4-DoF arm).
        reference: packed :class:`~mmstab.control.layout.StepReference` per sample
            (steps+1, 15 + 2n); row k is used in period k.
        params: packed controller parameters (18 + 6n,).
        steps: number of control periods.
        dt: control period [s] (for messages).
        progress: show a progress bar.
        first_tip: states (m, 5 + n) -> index of the sample where the robot tips over, or
            None; called on every chunk of steps in order (< 0: a sample of an earlier
            chunk): the run stops at that sample (shorter arrays).

    Returns:
        (states (m+1, 5 + n), applied q̇ (m, 2 + n) [rad/s], statuses (m,), wall time [s]), m = steps
        unless the robot tipped.

    Raises:
        MmstabError: the state became non-finite.
    """
    from tqdm import tqdm

    n_state, n_joints = advance.size1_in(0), advance.size1_out(1)
    states = np.empty((steps + 1, n_state))
    qdots = np.empty((steps, n_joints))
    statuses = np.empty(steps, dtype=np.int8)
    states[0] = state0
    s_buf, r_buf, p_buf = state0.copy(), np.zeros(advance.size1_in(1)), params.copy()
    nxt, qd, st, fin = np.zeros(n_state), np.zeros(n_joints), np.zeros(1), np.zeros(1)
    bar = tqdm(total=steps, desc="tracking", unit="step", disable=not progress, leave=False)
    # C-level stdout silenced: the plugin's banner when its memory is set up (qpOASES), and
    # OSQP's polish line
    with quiet_stdout():
        buffer: Any
        buffer, evaluate = advance.buffer()
        for i, a in enumerate((s_buf, r_buf, p_buf)):
            buffer.set_arg(i, memoryview(a))  # type: ignore[arg-type]
        for i, a in enumerate((nxt, qd, st, fin)):
            buffer.set_res(i, memoryview(a))  # type: ignore[arg-type]
        start = time.perf_counter()
        for k0 in range(0, steps, PROGRESS_CHUNK):
            k1 = min(k0 + PROGRESS_CHUNK, steps)
            for k in range(k0, k1):
                r_buf[:] = reference[k]
                evaluate()
                if not fin[0]:
                    bar.close()
                    raise MmstabError(
                        f"the state became non-finite at t = {(k + 1) * dt:.6g} s (step {k + 1}: "
                        f"{describe_nonfinite(nxt)}); stopping the run"
                    )
                statuses[k] = st[0]
                qdots[k] = qd
                states[k + 1] = nxt
                s_buf[:] = nxt
            bar.update(k1 - k0)
            tip = None if first_tip is None else first_tip(states[k0 + 1 : k1 + 1])
            if tip is not None:
                m = k0 + 1 + tip  # the sample where it tips: the run's last
                states, qdots, statuses = states[: m + 1], qdots[:m], statuses[:m]
                break
    wall = time.perf_counter() - start
    bar.close()
    return states, qdots, statuses, wall
