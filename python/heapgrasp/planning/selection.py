"""Next-pose selection of HEAPGrasp §IV-B (eq. 16-19).

At each view waypoint the target grasp is the candidate of ``P_grasp,ε`` (eq. 15)
closest to the previous target under the pose distance of eq. 17 (eq. 16), and the next
view waypoint is the candidate maximising its view score plus ``γ2`` times the rate at
which it brings the camera closer to the target grasp (eq. 18-19).

Poses are ``(4, 4)`` matrices; eq. 17 reads them as ``[t, q]`` with the quaternion of
the rotation part (``min(|q_a + q_b|, |q_a - q_b|)`` makes the sign of ``q`` irrelevant).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from heapgrasp.planning.volumes import GraspCandidate

__all__ = [
    "detour",
    "pose_distance",
    "progress_rate",
    "select_next_waypoint",
    "select_target",
    "top_scoring",
]

F64 = npt.NDArray[np.float64]


def _quaternions(rot: npt.ArrayLike) -> F64:
    """Unit quaternions ``(..., 4)`` (x, y, z, w) of rotation matrices ``(..., 3, 3)``."""
    from scipy.spatial.transform import Rotation

    r = np.asarray(rot, dtype=np.float64)
    flat = Rotation.from_matrix(r.reshape(-1, 3, 3)).as_quat()
    return np.asarray(flat, dtype=np.float64).reshape((*r.shape[:-2], 4))


def _as_poses(name: str, poses: npt.ArrayLike) -> F64:
    p = np.asarray(poses, dtype=np.float64)
    if p.shape[-2:] != (4, 4):
        raise ValueError(f"{name}: must be (..., 4, 4) poses, got shape {p.shape}")
    if not np.isfinite(p).all():
        raise ValueError(f"{name}: holds NaN or infinity")
    return p


def pose_distance(a: npt.ArrayLike, b: npt.ArrayLike, gamma1: float = 0.2) -> F64:
    """Eq. 17: ``|t_a - t_b| + γ1 min(|q_a + q_b|, |q_a - q_b|)``.

    Broadcasts over leading axes of ``(..., 4, 4)`` poses.
    """
    if not (math.isfinite(gamma1) and gamma1 >= 0):
        raise ValueError(f"gamma1 must be finite and >= 0, got {gamma1}")
    pa, pb = _as_poses("a", a), _as_poses("b", b)
    qa, qb = _quaternions(pa[..., :3, :3]), _quaternions(pb[..., :3, :3])
    dt = np.linalg.norm(pa[..., :3, 3] - pb[..., :3, 3], axis=-1)
    dq = np.minimum(np.linalg.norm(qa + qb, axis=-1), np.linalg.norm(qa - qb, axis=-1))
    return np.asarray(dt + gamma1 * dq, dtype=np.float64)


def top_scoring(candidates: Sequence[GraspCandidate]) -> GraspCandidate | None:
    """The highest-scoring candidate (the baselines' rule), or None."""
    return max(candidates, key=lambda c: c.score, default=None)


def select_target(
    candidates: Sequence[GraspCandidate],
    previous: GraspCandidate | npt.ArrayLike | None,
    gamma1: float = 0.2,
) -> GraspCandidate | None:
    """Eq. 16: the candidate closest to the previous target grasp (eq. 17).

    With no previous target (the first waypoint) the highest-scoring candidate is
    taken. Returns None when there is no candidate. Ties keep the better score.
    """
    if not candidates:
        return None
    if previous is None:
        return top_scoring(candidates)
    prev = previous.pose if isinstance(previous, GraspCandidate) else previous
    poses = np.stack([c.pose for c in candidates])
    d = pose_distance(poses, np.asarray(prev, dtype=np.float64)[None], gamma1)
    order = np.lexsort((-np.array([c.score for c in candidates]), d))
    return candidates[int(order[0])]


def progress_rate(
    candidate_poses: npt.ArrayLike,
    current_pose: npt.ArrayLike,
    target_pose: npt.ArrayLike,
    gamma1: float = 0.2,
) -> F64:
    """Eq. 19: ``h = 1 - dist(candidate, target) / dist(current, target)``.

    ``candidate_poses`` is ``(..., 4, 4)``; the result has its leading shape. When the
    camera is already at the target (zero denominator) ``h`` is 0 everywhere.
    """
    cands = _as_poses("candidate_poses", candidate_poses)
    target = _as_poses("target_pose", target_pose)
    denom = float(pose_distance(_as_poses("current_pose", current_pose), target, gamma1))
    if denom <= 0.0:
        return np.zeros(cands.shape[:-2])
    return np.asarray(1.0 - pose_distance(cands, target, gamma1) / denom, dtype=np.float64)


def detour(
    candidate_poses: npt.ArrayLike, current_pose: npt.ArrayLike, target_pose: npt.ArrayLike
) -> F64:
    """The path a view waypoint adds on the way to the target grasp (m, straight lines):
    ``|c - x| + |g - c| - |g - x|`` for candidate position ``c``, current camera
    position ``x`` and grasp position ``g``; 0 on the segment from ``x`` to ``g``.

    ``candidate_poses`` is ``(..., 4, 4)``; the result has its leading shape. The
    linearised path term of the paper's eq. 7 (``α d_space``) for one more waypoint,
    where eq. 19's ``h`` only rewards getting closer to the grasp.
    """
    cands = _as_poses("candidate_poses", candidate_poses)[..., :3, 3]
    x = _as_poses("current_pose", current_pose)[:3, 3]
    g = _as_poses("target_pose", target_pose)[:3, 3]
    there = np.linalg.norm(cands - x, axis=-1)
    on = np.linalg.norm(g - cands, axis=-1)
    return np.asarray(there + on - np.linalg.norm(g - x), dtype=np.float64)


def select_next_waypoint(
    view_scores: npt.ArrayLike,
    candidate_poses: npt.ArrayLike,
    current_pose: npt.ArrayLike,
    target_pose: npt.ArrayLike | None,
    gamma2: float,
    gamma1: float = 0.2,
) -> tuple[int, int]:
    """Eq. 18: ``(u*, v*) = argmax s + γ2 h`` (0-based indices).

    Parameters
    ----------
    view_scores
        ``(U, V)`` scores ``s`` (eq. 13/14).
    candidate_poses
        ``(U, V, 4, 4)`` view-waypoint candidates (eq. 12).
    current_pose
        Camera pose at the current waypoint.
    target_pose
        Target grasp (eq. 16); None (no grasp yet) or ``gamma2 = 0`` drops the ``h`` term.
    gamma2
        Weight of the distance-reduction term.
    """
    s = np.asarray(view_scores, dtype=np.float64)
    cands = _as_poses("candidate_poses", candidate_poses)
    if s.ndim != 2 or cands.shape[:2] != s.shape:
        raise ValueError(
            f"view_scores {s.shape} and candidate_poses {cands.shape} must be (U, V) and "
            "(U, V, 4, 4)"
        )
    if not np.isfinite(s).all():
        raise ValueError("view_scores: holds NaN or infinity")
    if not (math.isfinite(gamma2) and gamma2 >= 0):
        raise ValueError(f"gamma2 must be finite and >= 0, got {gamma2}")
    objective = s.copy()
    if target_pose is not None and gamma2 > 0:
        objective += gamma2 * progress_rate(cands, current_pose, target_pose, gamma1)
    u, v = np.unravel_index(int(np.argmax(objective)), s.shape)
    return int(u), int(v)
