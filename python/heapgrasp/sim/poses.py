"""Rigid poses (``(4, 4)`` matrices, metres, radians): to and from PyBullet's position and
quaternion, their distances, interpolation and turns about their own z axis.

Shared by the world (object poses), the free-flying hand and the arm (TCP and camera
poses); it depends on nothing else of the simulator.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from heapgrasp.sim.bullet import pb

__all__ = [
    "check_pose",
    "interpolate_pose",
    "pose_errors",
    "pose_matrix",
    "roll",
    "split_pose",
    "transport",
]

FloatArray = npt.NDArray[np.float64]


def pose_matrix(position: Sequence[float], quat_xyzw: Sequence[float]) -> npt.NDArray[np.float64]:
    """The ``(4, 4)`` pose of a PyBullet position and ``(x, y, z, w)`` quaternion."""
    m = np.eye(4)
    m[:3, :3] = np.asarray(pb.getMatrixFromQuaternion(quat_xyzw)).reshape(3, 3)
    m[:3, 3] = position
    return m


def split_pose(
    obj2world: npt.NDArray[np.float64],
) -> tuple[list[float], list[float]]:
    """A ``(4, 4)`` pose as PyBullet's position and ``(x, y, z, w)`` quaternion."""
    from scipy.spatial.transform import Rotation

    quat = Rotation.from_matrix(obj2world[:3, :3]).as_quat()  # x, y, z, w
    return [float(x) for x in obj2world[:3, 3]], [float(x) for x in quat]


def _angle_between(a: FloatArray, b: FloatArray) -> float:
    """Rotation angle (rad) between the rotation blocks of two poses (robust near 0)."""
    r = a[:3, :3].T @ b[:3, :3]
    c = 0.5 * (float(np.trace(r)) - 1.0)
    s = 0.5 * math.sqrt(
        float(r[2, 1] - r[1, 2]) ** 2
        + float(r[0, 2] - r[2, 0]) ** 2
        + float(r[1, 0] - r[0, 1]) ** 2
    )
    return math.atan2(s, c)


def pose_errors(a: FloatArray, b: FloatArray) -> tuple[float, float]:
    """Distance (m) and rotation angle (rad) between two poses."""
    return float(np.linalg.norm(a[:3, 3] - b[:3, 3])), _angle_between(a, b)


def interpolate_pose(a: FloatArray, b: FloatArray, s: float) -> FloatArray:
    """Pose at fraction ``s`` from ``a`` to ``b``: position linear, rotation slerped."""
    from scipy.spatial.transform import Rotation, Slerp

    slerp = Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([a[:3, :3], b[:3, :3]])))
    out = np.eye(4)
    out[:3, :3] = slerp([s]).as_matrix()[0]
    out[:3, 3] = (1.0 - s) * a[:3, 3] + s * b[:3, 3]
    return out


def _align(a: FloatArray, b: FloatArray) -> FloatArray:
    """Smallest rotation taking unit vector ``a`` to unit vector ``b``."""
    v = np.cross(a, b)
    c = float(np.dot(a, b))
    if c < -1.0 + 1e-12:  # opposite: half turn about any axis normal to a
        axis = np.cross(a, [1.0, 0.0, 0.0])
        if np.linalg.norm(axis) < 1e-6:
            axis = np.cross(a, [0.0, 1.0, 0.0])
        axis /= np.linalg.norm(axis)
        return np.asarray(2.0 * np.outer(axis, axis) - np.eye(3), dtype=np.float64)
    vx = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.asarray(np.eye(3) + vx + vx @ vx / (1.0 + c), dtype=np.float64)


def roll(pose: FloatArray, angle: float) -> FloatArray:
    """``pose`` turned by ``angle`` about its own z axis."""
    c, s = math.cos(angle), math.sin(angle)
    turn = np.eye(4)
    turn[:2, :2] = [[c, -s], [s, c]]
    return pose @ turn


def transport(reference: FloatArray, poses: FloatArray) -> FloatArray:
    """``poses`` with their rolls replaced by parallel transport of ``reference``'s
    rotation along their z axes: each rotation is the smallest turn of the previous one
    that aligns its z axis (positions and z axes unchanged)."""
    out = np.array(poses, dtype=np.float64)
    rot = reference[:3, :3]
    for k in range(out.shape[0]):
        rot = _align(rot[:, 2], out[k, :3, 2]) @ rot
        out[k, :3, :3] = rot
    return out


def check_pose(name: str, pose: npt.ArrayLike) -> FloatArray:
    """``pose`` as a float array; a ValueError naming ``name`` unless finite ``(4, 4)``."""
    m = np.asarray(pose, dtype=np.float64)
    if m.shape != (4, 4) or not np.isfinite(m).all():
        raise ValueError(f"{name} must be a finite (4, 4) pose, got shape {m.shape}")
    return m
