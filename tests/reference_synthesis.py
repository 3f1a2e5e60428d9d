"""NumPy reference of seed 001's grasp synthesis (normals, contact patches, pairs).

This is ``heapgrasp.planning.synthesis``'s original NumPy implementation, before its hot
loops moved to the Rust core (``heapgrasp._core.point_normals``, ``contact_patches``,
``antipodal_pairs``), kept as the test oracle: scipy's k-d tree, ``numpy.linalg.eigh``,
scipy's convex hull and Euclidean distance transform.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy import ndimage
from scipy.spatial import ConvexHull, QhullError, cKDTree

F64 = npt.NDArray[np.float64]
Bool = npt.NDArray[np.bool_]
I64 = npt.NDArray[np.int64]

#: The patch image: 101 × 101 px at 1 px/mm, a pad of 26 px (the public code's values).
_PATCH_PX = 101
_PAD_PX = 26


def _cloud(points: npt.ArrayLike, what: str = "points") -> F64:
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"{what} must be (N, 3), got shape {pts.shape}")
    if not np.isfinite(pts).all():
        raise ValueError(f"{what} hold NaN or infinity")
    return pts


def estimate_normals(points: npt.ArrayLike, k: int = 10) -> tuple[F64, F64]:
    """``(N, 3)`` unit normals (away from the centroid) and ``(N,)`` curvatures from each
    point's ``k`` nearest points, itself included."""
    pts = _cloud(points)
    if not (isinstance(k, int) and k >= 3):
        raise ValueError(f"k must be an int >= 3, got {k!r}")
    if len(pts) < k:
        raise ValueError(f"normals from {k} neighbours need at least {k} points, got {len(pts)}")
    _, idx = cKDTree(pts).query(pts, k=k)
    nbrs = pts[idx]  # (N, k, 3)
    centred = nbrs - nbrs.mean(axis=1, keepdims=True)
    cov = np.einsum("nki,nkj->nij", centred, centred) / k
    values, vectors = np.linalg.eigh(cov)  # ascending
    normals = vectors[:, :, 0]
    outward = np.einsum("ni,ni->n", normals, pts - pts.mean(axis=0)) < 0
    normals[outward] *= -1.0
    total = values.sum(axis=1)
    curvature = np.where(total > 0, values[:, 0] / np.where(total > 0, total, 1.0), 0.0)
    return normals, curvature


def _tangent_frame(normal: F64) -> tuple[F64, F64]:
    """Two tangent axes at a normal, as the public code builds them (``y = n × z``)."""
    y = np.cross(normal, [0.0, 0.0, 1.0])
    if np.linalg.norm(y) < 1e-12:
        y = np.array([normal[0], 0.0, 0.0]) if abs(normal[0]) > 1e-12 else np.array([1.0, 0, 0])
    y /= np.linalg.norm(y)
    return y, np.cross(normal, y)


def contact_patch_ok(
    points: npt.ArrayLike, normals: npt.ArrayLike, index: int, tree: cKDTree | None = None
) -> bool:
    """Whether point ``index`` has a contact patch a finger pad fits on (module doc)."""
    pts = np.asarray(points, dtype=np.float64)
    n = np.asarray(normals, dtype=np.float64)[index]
    tree = cKDTree(pts) if tree is None else tree
    near = pts[tree.query_ball_point(pts[index], math.sqrt(0.005**2 + 2 * 0.03**2))]
    y, z = _tangent_frame(n)
    rel = near - pts[index]
    along, across_y, across_z = rel @ n, rel @ y, rel @ z
    keep = (np.abs(along) <= 0.005) & (np.abs(across_y) <= 0.03) & (np.abs(across_z) <= 0.03)
    half = _PATCH_PX // 2
    px = np.column_stack(
        [(across_y[keep] * 1000 + half).astype(np.int64), (across_z[keep] * 1000 + half)]
    ).astype(np.int64)
    if len(np.unique(px, axis=0)) < 3:
        return False
    try:
        hull = ConvexHull(px.astype(np.float64))
    except QhullError:  # collinear: no area
        return False
    grid = np.indices((_PATCH_PX, _PATCH_PX)).reshape(2, -1).T.astype(np.float64)
    inside = (grid @ hull.equations[:, :2].T + hull.equations[:, 2] <= 1e-9).all(axis=1)
    disc = ((grid - half) ** 2).sum(axis=1) <= int(_PAD_PX / 2 * math.sqrt(2)) ** 2
    surface = (inside & disc).reshape(_PATCH_PX, _PATCH_PX)
    depth = ndimage.distance_transform_edt(surface)
    return bool(float(depth.max()) >= _PAD_PX / 1.9)


def usable_contacts(
    points: npt.ArrayLike, normals: npt.ArrayLike, curvature: npt.ArrayLike
) -> Bool:
    """``(N,)`` True for the points a finger may touch (module doc, step 2)."""
    pts = _cloud(points)
    curv = np.asarray(curvature, dtype=np.float64)
    ok = curv <= 2.0 * float(curv.mean())
    ok &= pts[:, 2] >= float(pts[:, 2].min()) + 0.01
    tree = cKDTree(pts)
    for i in np.flatnonzero(ok):
        ok[i] = contact_patch_ok(pts, normals, int(i), tree)
    return ok


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
    pts = _cloud(points)
    nrm = np.asarray(normals, dtype=np.float64)
    idx = np.flatnonzero(np.asarray(usable, dtype=bool))
    firsts, seconds, qualities, widths = [], [], [], []
    for a in range(len(idx) - 1):
        i, js = idx[a], idx[a + 1 :]
        line = pts[js] - pts[i]
        dist = np.linalg.norm(line, axis=1)
        width = dist + voxel
        fit = (width <= max_width) & (dist > 0)
        if not fit.any():
            continue
        js, line, dist, width = js[fit], line[fit], dist[fit], width[fit]
        unit = line / dist[:, None]
        angle_a = np.degrees(np.arccos(np.clip(np.abs(unit @ nrm[i]), 0.0, 1.0)))
        angle_b = np.degrees(np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", unit, nrm[js])), 0, 1)))
        quality = 180.0 - (angle_a + angle_b)
        good = quality >= min_quality
        firsts.append(np.full(int(good.sum()), i))
        seconds.append(js[good])
        qualities.append(quality[good])
        widths.append(width[good])
    if not firsts:
        empty = np.zeros(0)
        return GraspPairs(empty.astype(np.int64), empty.astype(np.int64), empty, empty)
    return GraspPairs(
        np.concatenate(firsts).astype(np.int64),
        np.concatenate(seconds).astype(np.int64),
        np.concatenate(qualities),
        np.concatenate(widths),
    )
