"""The UR5e's kinematics, for the rehearsal's controller
(:mod:`heapgrasp.sim.rehearsal.controller`).

A real UR controller answers ``getForwardKinematics`` and ``getInverseKinematics`` from
its own model; the rehearsal answers them from the UR5e's nominal Denavit–Hartenberg
parameters (Universal Robots' published table), so that ``[arm] park``, the reach check
(``isPoseWithinSafetyLimits``) and the joint-speed check of every camera path
(:meth:`heapgrasp.robot.ur.URArm.plan_path`) behave as on the arm. The inverse is
numerical — Levenberg–Marquardt on the geometric Jacobian from ``qnear`` (the
controller's convention: the solution nearest the given joints) — not the controller's
closed form; a pose it cannot reach within :data:`IK_ITERATIONS` has no solution.

Frames: the base frame is the controller's (z up through the shoulder), poses are
``(4, 4)``; the TCP is the flange frame times the ``setTcp`` offset.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

__all__ = ["DH_A", "DH_ALPHA", "DH_D", "IK_ITERATIONS", "UR5e"]

F64 = npt.NDArray[np.float64]
#: Six joint angles (rad), as a list or an array.
Joints = Sequence[float] | npt.NDArray[np.float64]

#: UR5e's DH parameters (m, rad): link lengths ``a``, offsets ``d``, twists ``alpha``.
DH_A = (0.0, -0.425, -0.3922, 0.0, 0.0, 0.0)
DH_D = (0.1625, 0.0, 0.0, 0.1333, 0.0997, 0.0996)
DH_ALPHA = (math.pi / 2, 0.0, 0.0, math.pi / 2, -math.pi / 2, 0.0)

#: Iterations of the numerical inverse before a pose counts as out of reach.
IK_ITERATIONS = 100
#: When an inverse has converged: position (m) and rotation (rad) errors.
IK_TOLERANCE = (1e-5, 1e-4)
#: The joints the inverse starts from when the caller gives none: elbow up, wrist down.
HOME = (0.0, -1.5708, 1.5708, -1.5708, -1.5708, 0.0)


def _dh(theta: float, d: float, a: float, alpha: float) -> F64:
    ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
    return np.array(
        [
            [ct, -st * ca, st * sa, a * ct],
            [st, ct * ca, -ct * sa, a * st],
            [0.0, sa, ca, d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def _rotvec(r: F64) -> F64:
    """The rotation vector (axis times angle) of a rotation matrix: the logarithm map in
    closed form, with the half-turn case taken from the symmetric part."""
    skew = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    angle = math.atan2(0.5 * float(np.linalg.norm(skew)), (r[0, 0] + r[1, 1] + r[2, 2] - 1.0) / 2.0)
    if angle < 1e-6:
        return 0.5 * skew
    if math.pi - angle > 1e-4:
        return angle / (2.0 * math.sin(angle)) * skew
    # near a half turn: the axis is the largest column of the symmetric part of (R + I) / 2
    sym = ((r + r.T) / 2.0 + np.eye(3)) / 2.0
    axis = sym[:, int(np.argmax(np.diag(sym)))]
    axis = axis / np.linalg.norm(axis)
    if skew @ axis < 0:
        axis = -axis
    return angle * axis


class UR5e:
    """Forward and inverse kinematics of a UR5e carrying a TCP ``tcp`` (``(4, 4)`` in the
    flange frame)."""

    def __init__(self, tcp: F64 | None = None) -> None:
        self.tcp: F64 = np.eye(4) if tcp is None else np.asarray(tcp, dtype=np.float64)

    def frames(self, q: Joints) -> list[F64]:
        """The base frame and each joint's frame after it (seven ``(4, 4)`` poses; the
        last is the flange)."""
        if len(q) != 6:
            raise ValueError(f"a UR5e has 6 joints, got {len(q)}")
        out = [np.eye(4)]
        for i in range(6):
            out.append(out[-1] @ _dh(float(q[i]), DH_D[i], DH_A[i], DH_ALPHA[i]))
        return out

    def forward(self, q: Joints) -> F64:
        """The TCP pose (base frame) at joints ``q``."""
        return self.frames(q)[-1] @ self.tcp

    def jacobian(self, q: Joints) -> F64:
        """The ``(6, 6)`` geometric Jacobian of the TCP (linear rows, then angular)."""
        frames = self.frames(q)
        p = (frames[-1] @ self.tcp)[:3, 3]
        jac = np.zeros((6, 6))
        for i in range(6):
            z, o = frames[i][:3, 2], frames[i][:3, 3]
            jac[:3, i] = np.cross(z, p - o)
            jac[3:, i] = z
        return jac

    def _error(self, q: F64, goal: F64) -> F64:
        pose = self.forward(q)
        dp = goal[:3, 3] - pose[:3, 3]
        dr = _rotvec(goal[:3, :3] @ pose[:3, :3].T)
        return np.concatenate([dp, dr])

    def inverse(self, target: F64, qnear: Joints | None = None) -> F64 | None:
        """Joints putting the TCP at ``target`` (base frame), found from ``qnear`` (default
        :data:`HOME`) by Levenberg–Marquardt (damped least squares whose damping falls
        after a step that helps and rises after one that does not); None where it does not
        converge within :data:`IK_ITERATIONS` (out of reach)."""
        q = np.array(qnear if qnear is not None and len(qnear) == 6 else HOME, dtype=np.float64)
        goal = np.asarray(target, dtype=np.float64)
        err = self._error(q, goal)
        cost = float(err @ err)
        damping = 1e-3
        for _ in range(IK_ITERATIONS):
            if (
                np.linalg.norm(err[:3]) < IK_TOLERANCE[0]
                and np.linalg.norm(err[3:]) < IK_TOLERANCE[1]
            ):
                # each joint within a turn of zero (the controller's ±2π range)
                return np.asarray((q + np.pi) % (2 * np.pi) - np.pi, dtype=np.float64)
            jac = self.jacobian(q)
            step = jac.T @ np.linalg.solve(jac @ jac.T + damping * np.eye(6), err)
            norm = float(np.linalg.norm(step))
            if norm > 0.5:  # keep each step in the linear region
                step *= 0.5 / norm
            trial = q + step
            trial_err = self._error(trial, goal)
            trial_cost = float(trial_err @ trial_err)
            if trial_cost < cost:
                q, err, cost = trial, trial_err, trial_cost
                damping = max(damping * 0.3, 1e-9)
            else:
                damping = min(damping * 10.0, 1e3)
        return None
