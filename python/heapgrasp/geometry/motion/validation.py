"""Checks of the motion functions' inputs (metres, radians, rigid ``(4, 4)`` poses): bad
input raises a :class:`heapgrasp.HeapgraspError` subclass naming the value."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from heapgrasp._core import InvalidValueError, NonFiniteError, NotRigidError, ShapeError

FloatArray = npt.NDArray[np.float64]
Vec3 = tuple[float, float, float]

#: Minimum eye-target distance accepted by :func:`look_at` (as in the Rust core).
MIN_DISTANCE = 1e-12
#: Below this ``|z x up|`` the viewing direction counts as parallel to ``up`` (Rust core).
PARALLEL = 1e-9
#: Tolerance of the rigidity check of input poses.
RIGID_TOLERANCE = 1e-6


def vec3(name: str, value: npt.ArrayLike) -> FloatArray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != (3,):
        raise ShapeError(f"{name}: expected shape (3,), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise NonFiniteError(f"{name}: must be finite, got {arr.tolist()}")
    return arr


def positive(name: str, value: float) -> float:
    v = float(value)
    if not (math.isfinite(v) and v > 0.0):
        raise InvalidValueError(f"{name}: must be finite and > 0, got {value!r}")
    return v


def as_poses(name: str, poses: npt.ArrayLike) -> FloatArray:
    arr = np.asarray(poses, dtype=np.float64)
    if arr.ndim != 3 or arr.shape[1:] != (4, 4) or arr.shape[0] < 1:
        raise ShapeError(f"{name}: expected shape (N, 4, 4) with N >= 1, got {arr.shape}")
    check_rigid(name, arr)
    return arr


def as_pose(name: str, pose: npt.ArrayLike) -> FloatArray:
    arr = np.asarray(pose, dtype=np.float64)
    if arr.shape != (4, 4):
        raise ShapeError(f"{name}: expected shape (4, 4), got {arr.shape}")
    check_rigid(name, arr[None])
    return arr


def check_rigid(name: str, arr: FloatArray) -> None:
    if not np.all(np.isfinite(arr)):
        raise NonFiniteError(f"{name}: must be finite")
    if not np.array_equal(arr[:, 3, :], np.broadcast_to([0.0, 0.0, 0.0, 1.0], arr[:, 3].shape)):
        raise NotRigidError(f"{name}: last row must be [0, 0, 0, 1]")
    rot = arr[:, :3, :3]
    ortho = np.abs(np.swapaxes(rot, 1, 2) @ rot - np.eye(3)).max()
    det = np.linalg.det(rot)
    if ortho > RIGID_TOLERANCE or np.abs(det - 1.0).max() > RIGID_TOLERANCE:
        raise NotRigidError(f"{name}: rotation block must be orthonormal with det +1")


def norm(v: FloatArray) -> FloatArray:
    """Euclidean norm along the last axis (one code path for single and batched input)."""
    return np.asarray(np.sqrt(np.sum(v * v, axis=-1)), dtype=np.float64)
