"""Arm kinematics: link frames and arm CoM, symbolic (CasADi) and batched (NumPy).

Two independent implementations of the same DH chain: the CasADi ``SX`` one gives the
functions and Jacobians the planner, controller and code generator use; the NumPy one
evaluates many postures at once (the workspace grid). Tests check one against the other.

Naming: ``B_T_R[i]`` is the pose of link frame R_i in the body frame B.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from mmstab.model import frames as frames_c

if TYPE_CHECKING:
    from mmstab.model.parts import ArmLink, FloatArray


def dh_sx(theta: ca.SX, a: float, alpha: float, d: float) -> ca.SX:
    """Standard DH transform ``Rz(theta) Tz(d) Tx(a) Rx(alpha)`` as a 4x4 SX."""
    ct, st = ca.cos(theta), ca.sin(theta)
    ca_, sa = np.cos(alpha), np.sin(alpha)
    return ca.vertcat(
        ca.horzcat(ct, -st * ca_, st * sa, a * ct),
        ca.horzcat(st, ct * ca_, -ct * sa, a * st),
        ca.horzcat(0, sa, ca_, d),
        ca.horzcat(0, 0, 0, 1),
    )


#: :meth:`ArmKinematics.link_frames` of at most this many postures computes every link's DH
#: transform in one go (fewer NumPy calls); of more, link after link (fewer cache misses).
FEW_POSTURES = 1024


def dh_np(theta: FloatArray, a: float, alpha: float, d: float) -> FloatArray:
    """Batched standard DH transforms: theta (N,) [rad] -> (N, 4, 4)."""
    n = theta.shape[0]
    ct, st = np.cos(theta), np.sin(theta)
    ca_, sa = np.cos(alpha), np.sin(alpha)
    T = np.zeros((n, 4, 4))
    T[:, 0, 0], T[:, 0, 1], T[:, 0, 2], T[:, 0, 3] = ct, -st * ca_, st * sa, a * ct
    T[:, 1, 0], T[:, 1, 1], T[:, 1, 2], T[:, 1, 3] = st, ct * ca_, -ct * sa, a * st
    T[:, 2, 1], T[:, 2, 2], T[:, 2, 3] = sa, ca_, d
    T[:, 3, 3] = 1.0
    return T


class ArmKinematics:
    """Kinematics of a robot's arm in the body frame B, built once per robot.

    Attributes:
        q: the symbolic joint vector (4,) used by every ``ca.Function`` here.
        B_T_R: symbolic link frames, list of four 4x4 SX.
        com_body: symbolic arm CoM g_a(q) in B (3,) [m] (Eq. 1 without G_T_B).
        f_link_frames: ``ca.Function`` q -> four 4x4 B_T_R[i].
        f_arm_com: ``ca.Function`` q -> g_a (3,) [m].
        f_arm_com_jac: ``ca.Function`` q -> d g_a / d q (3x4) [m/rad].
    """

    def __init__(self, links: Sequence[ArmLink], mount_T: ArrayLike):
        """Build the arm's functions.

        Args:
            links: the arm links in chain order (link 0 = turret).
            mount_T: pose of the arm's mounting frame in the body frame (4x4) [m].
        """
        self.links = tuple(links)
        self.mount_T = np.asarray(mount_T, dtype=float)
        self._masses = np.array([link.mass for link in self.links])
        self._coms = np.array([link.com for link in self.links])  # (n, 3) in R_i
        self.q = ca.SX.sym("q", len(self.links))
        # link_frames' DH transforms: entries 0-7 = (cos, sin)[_dh_trig] * _dh_gain, 8-15 rest
        self._theta_offset = np.array([link.theta_offset for link in self.links])
        self._dh_trig = np.array([0, 1, 1, 0, 1, 0, 0, 1])
        ca_, sa = np.cos([lk.alpha for lk in self.links]), np.sin([lk.alpha for lk in self.links])
        a = np.array([link.a for link in self.links])
        one = np.ones(len(self.links))
        self._dh_gain = np.stack([one, -ca_, sa, a, one, ca_, -sa, a], axis=1)
        zero, d = np.zeros(len(self.links)), np.array([link.d for link in self.links])
        self._dh_rest = np.stack([zero, sa, ca_, d, zero, zero, zero, one], axis=1)
        self._fast: bool | None = None  # link_frames in C: not yet checked
        T = ca.SX(self.mount_T)
        self.B_T_R: list[ca.SX] = []
        for i, link in enumerate(self.links):
            T = T @ dh_sx(self.q[i] + link.theta_offset, link.a, link.alpha, link.d)
            self.B_T_R.append(T)
        weighted = sum(
            link.mass * (T[:3, :3] @ ca.DM(link.com) + T[:3, 3])
            for link, T in zip(self.links, self.B_T_R, strict=True)
        )
        self.com_body = weighted / float(self._masses.sum())
        self.f_link_frames = ca.Function(
            "link_frames",
            [self.q],
            self.B_T_R,
            ["q"],
            [f"B_T_R{i}" for i in range(len(self.links))],
        )
        self.f_arm_com = ca.Function("arm_com", [self.q], [self.com_body], ["q"], ["com_body"])
        self.f_arm_com_jac = ca.Function(
            "arm_com_jac", [self.q], [ca.jacobian(self.com_body, self.q)], ["q"], ["J"]
        )

    # ------------------------------------------------------------------------- NumPy, batched
    def link_frames(self, q: ArrayLike) -> FloatArray:
        """Link frames B_T_R_i for many postures at once.

        In C where it gives NumPy's numbers bit for bit on this machine
        (:mod:`mmstab.model.frames`, checked once per kinematics), else NumPy's products.

        Args:
            q: joint angles (N, 4) or (4,) [rad].

        Returns:
            (N, 4, 4, 4): ``out[n, i]`` is B_T_R_i at posture n (or (4, 4, 4) for one posture).
        """
        qa = np.asarray(q, dtype=float)
        single = qa.ndim == 1
        qa = np.ascontiguousarray(np.atleast_2d(qa))  # a transposed array: its trig too (C)
        if self._fast is None:
            sample = frames_c.sample_postures(len(self.links))
            key = b"".join(x.tobytes() for x in (self._dh_gain, self._dh_rest, self.mount_T))
            self._fast = frames_c.agrees(
                b"frames" + key, lambda: self._frames_c(sample), lambda: self._frames_np(sample)
            )
        out = self._frames_c(qa) if self._fast else None
        if out is None:
            out = self._frames_np(qa)
        return out[0] if single else out

    def _trig(self, qa: FloatArray) -> FloatArray:
        """Each joint's (cos, sin) of its angle plus offset (n, links, 2)."""
        theta = qa[:, : len(self.links)] + self._theta_offset
        return np.stack((np.cos(theta), np.sin(theta)), axis=2)

    def _frames_c(self, qa: FloatArray) -> FloatArray | None:
        """:meth:`link_frames` of (n, 4) postures in C; None: no kernel."""
        return frames_c.link_frames(self._trig(qa), self._dh_gain, self._dh_rest, self.mount_T)

    def _frames_np(self, qa: FloatArray) -> FloatArray:
        """:meth:`link_frames` of (n, 4) postures with NumPy's batched products (n, 4, 4, 4)."""
        n, links = qa.shape[0], len(self.links)
        if n > FEW_POSTURES:  # link after link: contiguous arrays, fewer cache misses
            T = np.broadcast_to(self.mount_T, (n, 4, 4))
            frames = []
            for i, link in enumerate(self.links):
                T = T @ dh_np(qa[:, i] + link.theta_offset, link.a, link.alpha, link.d)
                frames.append(T)
            return np.stack(frames, axis=1)
        # every link's DH transform at once, the same numbers as dh_np's: its first two rows
        # a cosine or sine times a constant, the last two constants
        trig = self._trig(qa)
        D = np.empty((n, links, 16))
        np.multiply(np.take(trig, self._dh_trig, axis=2), self._dh_gain, out=D[:, :, :8])
        D[:, :, 8:] = self._dh_rest
        D4 = D.reshape(n, links, 4, 4)
        out = np.empty((n, links, 4, 4))
        T = np.broadcast_to(self.mount_T, (n, 4, 4))
        for i in range(links):  # the same 4x4 products (BLAS's), written in place
            T = np.matmul(T, D4[:, i], out=out[:, i])
        return out

    def link_coms(self, q: ArrayLike) -> FloatArray:
        """Per-link CoMs in B: (N, 4, 3) or (4, 3) [m]."""
        frames = self.link_frames(q)
        return np.einsum("...ij,...j->...i", frames[..., :3, :3], self._coms) + frames[..., :3, 3]

    def arm_com(self, q: ArrayLike) -> FloatArray:
        """Arm CoM g_a in B for one (4,) or many (N, 4) postures [m] (Eq. 1)."""
        coms = self.link_coms(q)
        return np.einsum("i,...ij->...j", self._masses, coms) / self._masses.sum()

    def arm_com_jacobian(self, q: ArrayLike) -> FloatArray:
        """D g_a / d q at one posture (3, 4) [m/rad] (CasADi)."""
        return np.asarray(self.f_arm_com_jac(np.asarray(q, dtype=float)))
