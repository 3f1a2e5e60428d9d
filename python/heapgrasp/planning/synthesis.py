"""Natarajan et al.'s grasp synthesis on a fused object point cloud (§3.3), NumPy reference.

The active-vision benchmark of seed ``001_95c7dd5c6a7c3646.txt`` looks for a two-finger
grasp on the object's points (:mod:`heapgrasp.perception.clouds`):

1. **Normals and curvature** from the ``k = 10`` nearest points (PCL's
   ``NormalEstimation``: the covariance's smallest eigenvector; curvature
   ``λ0 / (λ0 + λ1 + λ2)``), oriented away from the object's centroid
   (:func:`estimate_normals`).
2. **Usable contacts** (:func:`usable_contacts`): curvature at most twice the object's
   mean; not within 1 cm of the object's lowest point; a **contact patch** large enough
   for a finger pad: the points within ±5 mm along the normal and ±30 mm across it,
   projected onto the tangent plane at 1 px/mm, their convex hull masked by a disc of
   18 px radius, must hold a point 13.68 px (26 / 1.9) from its edge (a distance
   transform; the public code's ``isContactPatchOk``).
3. **Pairs** (:func:`grasp_pairs`): two usable points whose distance plus a voxel fits the
   opening (≤ 8 cm); ``A`` and ``B`` the angles between the contact line and each normal
   (either way along the line), quality ``180° − (A + B)`` at least 150°.
4. **Order** (:func:`rank_grasps`, the public code's "approach 2" as a lexicographic key):
   nearer the vertical line through the object's centroid first (1 cm bands), then
   higher (6 cm bands), then nearer the centroid (1 cm bands), then better quality.

5. **Collision check** (:func:`first_free_grasp`): in that order, the first grasp whose
   hand holds none of the object's and the unexplored region's points
   (:func:`heapgrasp.first_free_pose`, the Rust core) at the contacts' midpoint, the
   fingers closing along the contact line, with the approach turned about that line
   through the public code's 8 pitches (from above first, then 45° and 135° off, ...).

Steps 1–3 run in the Rust core (``heapgrasp._core.point_normals``, ``contact_patches``,
``antipodal_pairs``); the NumPy implementation they replaced is the tests' reference.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from heapgrasp import antipodal_pairs, contact_patches, first_free_pose, point_normals
from heapgrasp.geometry.gripper import PANDA_HAND, GripperGeometry

__all__ = [
    "PITCHES_DEG",
    "GraspPairs",
    "candidate_contacts",
    "estimate_normals",
    "first_free_grasp",
    "grasp_pairs",
    "grasp_pose",
    "grasp_poses",
    "patched_pairs",
    "rank_grasps",
    "usable_contacts",
]

#: The collision check's index cell (m): coarse cells find a point inside a colliding
#: hand after few lookups (4 cm: 4-20x faster than 1 cm on the benchmark's clouds).
_COLLISION_CELL = 0.04

F64 = npt.NDArray[np.float64]
Bool = npt.NDArray[np.bool_]
I64 = npt.NDArray[np.int64]

#: The approach's turns about the contact line, in the order tried (degrees; 90: from
#: above), as the public code's ``collisionCheck``.
PITCHES_DEG = (90, 45, 135, 270, 225, 315, 0, 180)


def _cloud(points: npt.ArrayLike, what: str = "points") -> F64:
    pts = np.ascontiguousarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"{what} must be (N, 3), got shape {pts.shape}")
    if not np.isfinite(pts).all():
        raise ValueError(f"{what} hold NaN or infinity")
    return pts


def estimate_normals(points: npt.ArrayLike, k: int = 10) -> tuple[F64, F64]:
    """``(N, 3)`` unit normals (away from the centroid) and ``(N,)`` curvatures from each
    point's ``k`` nearest points, itself included (the core's ``point_normals``)."""
    pts = _cloud(points)
    if not (isinstance(k, int) and k >= 3):
        raise ValueError(f"k must be an int >= 3, got {k!r}")
    if len(pts) < k:
        raise ValueError(f"normals from {k} neighbours need at least {k} points, got {len(pts)}")
    return point_normals(pts, k=k)


def candidate_contacts(
    points: npt.ArrayLike,
    curvature: npt.ArrayLike,
    *,
    factor: float = 2.0,
    min_height: float = 0.01,
) -> Bool:
    """``(N,)`` True for the points flat enough (curvature at most ``factor`` times the
    mean) and high enough (``min_height`` above the lowest point) to touch (module doc,
    step 2, before the contact patch)."""
    pts = _cloud(points)
    curv = np.asarray(curvature, dtype=np.float64)
    if curv.shape != (len(pts),):
        raise ValueError(f"curvature must be ({len(pts)},), got shape {curv.shape}")
    if len(pts) == 0:
        return np.zeros(0, dtype=bool)
    ok: Bool = (curv <= factor * float(curv.mean())) & (
        pts[:, 2] >= float(pts[:, 2].min()) + min_height
    )
    return ok


def usable_contacts(
    points: npt.ArrayLike, normals: npt.ArrayLike, curvature: npt.ArrayLike
) -> Bool:
    """``(N,)`` True for the points a finger may touch (module doc, step 2)."""
    pts = _cloud(points)
    return contact_patches(pts, _cloud(normals, "normals"), candidate_contacts(pts, curvature))


@dataclass(frozen=True)
class GraspPairs:
    """Contact pairs ``(i, j)`` of the object's points, their quality (degrees) and the
    opening they need (m)."""

    first: I64
    second: I64
    quality: F64
    width: F64

    def __len__(self) -> int:
        return len(self.first)


def grasp_pairs(
    points: npt.ArrayLike,
    normals: npt.ArrayLike,
    usable: npt.ArrayLike,
    *,
    voxel: float = 0.0075,
    max_width: float = 0.08,
    min_quality: float = 150.0,
) -> GraspPairs:
    """Every pair of usable points that fits the opening with quality at least
    ``min_quality`` (module doc, step 3), ``i < j``, in index order."""
    first, second, quality, width = antipodal_pairs(
        _cloud(points),
        _cloud(normals, "normals"),
        np.ascontiguousarray(usable, dtype=bool),
        voxel=voxel,
        max_width=max_width,
        min_quality=min_quality,
    )
    return GraspPairs(first, second, quality, width)


def patched_pairs(
    points: npt.ArrayLike,
    normals: npt.ArrayLike,
    candidates: npt.ArrayLike,
    *,
    voxel: float = 0.0075,
    max_width: float = 0.08,
    min_quality: float = 150.0,
) -> GraspPairs:
    """:func:`grasp_pairs` of :func:`usable_contacts`, with the contact patch checked
    only at the points some pair of ``candidates`` touches (the same pairs, for a
    fraction of the patch tests)."""
    pts = _cloud(points)
    nrm = _cloud(normals, "normals")
    pairs = grasp_pairs(
        pts, nrm, candidates, voxel=voxel, max_width=max_width, min_quality=min_quality
    )
    if len(pairs) == 0:
        return pairs
    touched = np.zeros(len(pts), dtype=bool)
    touched[pairs.first] = True
    touched[pairs.second] = True
    patch = contact_patches(pts, nrm, touched)
    keep = patch[pairs.first] & patch[pairs.second]
    return GraspPairs(pairs.first[keep], pairs.second[keep], pairs.quality[keep], pairs.width[keep])


def rank_grasps(points: npt.ArrayLike, pairs: GraspPairs, centroid: npt.ArrayLike) -> I64:
    """The order to try ``pairs`` in (module doc, step 4): indices into ``pairs``."""
    pts = _cloud(points)
    c = np.asarray(centroid, dtype=np.float64).reshape(3)
    mid = (pts[pairs.first] + pts[pairs.second]) / 2.0
    line = np.hypot(mid[:, 0] - c[0], mid[:, 1] - c[1])
    dist = np.linalg.norm(mid - c, axis=1)
    keys = (
        -pairs.quality,
        np.floor(dist / 0.01),
        -np.floor(mid[:, 2] / 0.06),
        np.floor(line / 0.01),
    )  # np.lexsort: the last key first
    order: I64 = np.lexsort(keys).astype(np.int64)
    return order


def grasp_poses(p1: npt.ArrayLike, p2: npt.ArrayLike, pitch: npt.ArrayLike) -> F64:
    """``(N, 4, 4)`` TCP poses at the midpoints of contacts ``p1[i]``, ``p2[i]``
    (``(N, 3)`` each): fingers closing along the contact line (TCP y), the approach
    (TCP z) horizontal at ``pitch = 0`` and turned by ``pitch[i]`` (radians) about the
    contact line; ``π/2`` comes from above when the line is level."""
    a = np.asarray(p1, dtype=np.float64).reshape(-1, 3)
    b = np.asarray(p2, dtype=np.float64).reshape(-1, 3)
    t = np.broadcast_to(np.asarray(pitch, dtype=np.float64), (len(a),))
    y = a - b
    y /= np.linalg.norm(y, axis=1, keepdims=True)
    z0 = np.column_stack([y[:, 1], -y[:, 0], np.zeros(len(y))])  # y × (0, 0, 1)
    vertical = np.linalg.norm(z0, axis=1) < 1e-9
    if vertical.any():  # a vertical contact line: any horizontal approach, y × (1, 0, 0)
        yv = y[vertical]
        z0[vertical] = np.column_stack([np.zeros(len(yv)), yv[:, 2], -yv[:, 1]])
    z0 /= np.linalg.norm(z0, axis=1, keepdims=True)
    x0 = np.cross(y, z0)
    # Turning z0 toward x0 = y × z0 = -(down) for a level line: pitch π/2 is from above.
    z = np.cos(t)[:, None] * z0 + np.sin(t)[:, None] * x0
    poses = np.zeros((len(a), 4, 4))
    poses[:, :3, 0] = np.cross(y, z)
    poses[:, :3, 1] = y
    poses[:, :3, 2] = z
    poses[:, :3, 3] = (a + b) / 2.0
    poses[:, 3, 3] = 1.0
    return poses


def grasp_pose(p1: npt.ArrayLike, p2: npt.ArrayLike, pitch: float) -> F64:
    """One pose of :func:`grasp_poses`: ``(4, 4)``."""
    out: F64 = grasp_poses(p1, p2, pitch)[0]
    return out


def first_free_grasp(
    points: npt.ArrayLike,
    unexplored: npt.ArrayLike,
    pairs: GraspPairs,
    order: npt.ArrayLike,
    *,
    gripper: GripperGeometry = PANDA_HAND,
    batch: int = 8192,
) -> tuple[int, F64] | None:
    """The first pair of ``order`` (and its TCP pose) at which, for one of
    :data:`PITCHES_DEG` in turn, the hand holds none of ``points`` and ``unexplored``
    (the core's ``first_free_pose``, ``batch`` pairs a call); None when every one
    collides. The fingers are ``pairs.width`` apart (at most the hand's opening)."""
    pts = _cloud(points)
    obstacles = np.vstack([pts, _cloud(unexplored, "unexplored").reshape(-1, 3)])
    ranked = np.asarray(order, dtype=np.int64)
    hand = dataclasses.asdict(gripper)
    pitches = np.radians(np.asarray(PITCHES_DEG, dtype=np.float64))
    for start in range(0, len(ranked), batch):
        chunk = ranked[start : start + batch]
        first = np.repeat(pts[pairs.first[chunk]], len(pitches), axis=0)
        second = np.repeat(pts[pairs.second[chunk]], len(pitches), axis=0)
        poses = grasp_poses(first, second, np.tile(pitches, len(chunk)))
        widths = np.repeat(np.minimum(pairs.width[chunk], gripper.max_opening), len(pitches))
        free = first_free_pose(hand, poses, widths, obstacles, cell=_COLLISION_CELL)
        if free is not None:
            return int(chunk[free // len(pitches)]), poses[free]
    return None
