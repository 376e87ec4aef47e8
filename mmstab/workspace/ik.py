"""Arm posture that realises a target arm CoM (after the planner; not inside CMA-ES).

An NLP per target, built once: stay close to a reference posture (the previous one, so
the arm moves little between poses) subject to g_a(q) = target and the joint limits,
solved by IPOPT from several seeds (the previous posture, then the postures of the
nearest valid workspace CoMs). The first collision-free solution with the CoM matched
wins; if none is collision-free the best one is returned and flagged.
"""

from __future__ import annotations

import functools
from typing import Any, NamedTuple

import casadi as ca
import numpy as np
from scipy.spatial import cKDTree

from mmstab.core.pool import raise_if_interrupted, run_interruptibly
from mmstab.model.robot import FloatArray, Robot

#: A posture "realises" a target when its CoM is this close [m].
COM_TOLERANCE = 1e-4


class PostureResult(NamedTuple):
    """A realising posture: ``q`` [rad], its CoM error [m], and whether it is collision-free."""

    q: FloatArray
    com_error: float
    collision_free: bool


class PostureSolver:
    """Inverse kinematics for the arm CoM (IPOPT via CasADi), with collision checks.

    Args:
        robot: the robot.
        workspace: the workspace (``valid_q``, ``valid_com``) that supplies seeds; None: no
            workspace seeds (only the given ones).
        seeds: how many nearest valid postures to try after the previous posture.
    """

    def __init__(self, robot: Robot, workspace: Any, seeds: int = 6):
        from mmstab.model.collision import CollisionChecker

        self.robot = robot
        self.checker = CollisionChecker(robot)
        self.valid_q = (
            np.empty((0, robot.arm_joints)) if workspace is None else np.asarray(workspace.valid_q)
        )
        self._valid_com = np.asarray(workspace.valid_com) if len(self.valid_q) else None
        self.n_seeds = seeds

    # Built at the first solve: a plan whose postures are the roadmap's nodes solves none
    # (the k-d tree over V's CoMs alone took 65 ms of every such plan).
    @functools.cached_property
    def _tree(self) -> cKDTree | None:
        if self._valid_com is None:
            return None
        return run_interruptibly(cKDTree, self._valid_com)

    @functools.cached_property
    def _nlp(self) -> Any:
        kin = self.robot.kinematics
        target, q_ref = ca.SX.sym("target", 3), ca.SX.sym("q_ref", self.robot.arm_joints)
        nlp = {
            "x": kin.q,
            "p": ca.vertcat(target, q_ref),
            "f": 0.5 * ca.sumsqr(kin.q - q_ref),
            "g": kin.com_body - target,
        }
        opts: dict[str, Any] = {
            "print_time": False,
            "ipopt": {"print_level": 0, "sb": "yes", "tol": 1e-12, "max_iter": 200},
        }
        return ca.nlpsol("arm_com_ik", "ipopt", nlp, opts)

    def solve(self, target_com: FloatArray, seed: FloatArray, q_ref: FloatArray) -> FloatArray:
        """One IPOPT solve from ``seed`` (n,) staying near ``q_ref`` (n,) [rad]."""
        try:
            sol = self._nlp(
                x0=seed,
                p=np.concatenate([target_com, q_ref]),
                lbg=0.0,
                ubg=0.0,
                lbx=self.robot.joint_lower,
                ubx=self.robot.joint_upper,
            )
            raise_if_interrupted()  # CasADi's IPOPT interface swallows a Ctrl-C
            return np.asarray(sol["x"]).ravel()
        except (RuntimeError, SystemError):
            # a Ctrl-C that lands outside IPOPT's own callback comes back as CasADi's
            # RuntimeError ("... KeyboardInterrupt"), or inside a SWIG call as a
            # SystemError around it: it is still the user's Ctrl-C
            raise_if_interrupted()
            raise

    def seeds(self, target_com: FloatArray, previous_q: FloatArray) -> list[FloatArray]:
        """The previous posture, then the postures of the nearest valid workspace CoMs."""
        out = [np.asarray(previous_q, dtype=float)]
        if self._tree is not None:
            k = min(self.n_seeds, len(self.valid_q))
            _, idx = self._tree.query(target_com, k=k)
            out.extend(self.valid_q[np.atleast_1d(idx)])
        return out

    def posture(self, target_com: FloatArray, previous_q: FloatArray) -> PostureResult:
        """A collision-free posture whose CoM is ``target_com`` (body frame, [m]), if found."""
        target = np.asarray(target_com, dtype=float)
        best: PostureResult | None = None
        for seed in self.seeds(target, previous_q):
            q = np.clip(
                self.solve(target, seed, seed), self.robot.joint_lower, self.robot.joint_upper
            )
            err = float(np.linalg.norm(self.robot.arm_com(q) - target))
            free = not bool(np.asarray(self.checker.collides(q[None, :]))[0])
            result = PostureResult(q=q, com_error=err, collision_free=free)
            if free and err <= COM_TOLERANCE:
                return result
            if best is None or (free, -err) > (best.collision_free, -best.com_error):
                best = result
        assert best is not None
        return best

    def realise(self, target_com: FloatArray, previous_q: FloatArray) -> tuple[FloatArray, bool]:
        """``(posture, collision_free)`` for :func:`mmstab.planner.solve_path`."""
        r = self.posture(target_com, previous_q)
        return r.q, r.collision_free
