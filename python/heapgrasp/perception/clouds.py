"""Natarajan et al.'s point-cloud perception: fused depth, the table, the unexplored region.

The active-vision benchmark of seed ``001_95c7dd5c6a7c3646.txt`` (§3.2) sees the scene
with a depth camera on its viewsphere (:mod:`heapgrasp.viewsphere.sphere`):

- each depth image is back-projected to world points (:func:`backproject`; the sensor's
  range 0.10–3.0 m), and the views are fused by concatenating their points and
  down-sampling to one point per 7.5 mm voxel, the centroid of the points in it
  (:func:`voxel_downsample`, as PCL's ``VoxelGrid``; fusion is order-free);
- the table is the dominant plane within 10° of horizontal (:func:`fit_table`: RANSAC,
  inliers within 5 mm), the object the points above it;
- the **unexplored region** (:class:`UnexploredRegion`) is a 7.5 mm lattice over the
  object's box grown by ``max(extent, 0.30 m)`` in x and y and from 1 cm below the table
  to the object's top plus ``max(z extent, 0.25 m)``, from which every view removes the
  points it shows to be free.

A lattice point stays unexplored after a view unless the view shows the space there to
be empty: it lies in front of the camera, projects into the image, and the depth measured
at its pixel is missing (the ray met nothing) or beyond ``0.99 ×`` the point's own depth.
Points below the table stay. The public code also removed the points that project outside
the image, i.e. treated what the camera never looked at as seen; here they stay
unexplored.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from heapgrasp import seen_empty
from heapgrasp import voxel_downsample as core_voxel_downsample
from heapgrasp.geometry.camera import CameraSpec

__all__ = [
    "TablePlane",
    "UnexploredRegion",
    "backproject",
    "fit_table",
    "project",
    "voxel_downsample",
]

F64 = npt.NDArray[np.float64]

#: Natarajan et al.'s sensor range (m).
MIN_RANGE = 0.10
MAX_RANGE = 3.0
#: A point is behind the measured surface when its depth exceeds the measurement by 1 %.
OCCLUSION = 0.99


def _pose(name: str, cam2world: npt.ArrayLike) -> F64:
    pose = np.asarray(cam2world, dtype=np.float64)
    if pose.shape != (4, 4) or not np.isfinite(pose).all():
        raise ValueError(f"{name} must be a finite (4, 4) pose, got shape {pose.shape}")
    return pose


def _depth(depth: npt.ArrayLike, camera: CameraSpec) -> F64:
    d = np.asarray(depth, dtype=np.float64)
    if d.shape != (camera.height, camera.width):
        raise ValueError(
            f"depth must have the camera's shape {(camera.height, camera.width)}, got {d.shape}"
        )
    return d


def _valid(d: F64, min_range: float, max_range: float) -> npt.NDArray[np.bool_]:
    return np.isfinite(d) & (d >= min_range) & (d <= max_range)


def backproject(
    depth: npt.ArrayLike,
    camera: CameraSpec,
    cam2world: npt.ArrayLike,
    *,
    min_range: float = MIN_RANGE,
    max_range: float = MAX_RANGE,
) -> F64:
    """``(N, 3)`` world points of the pixels whose depth (along the optical axis, m) is in
    ``[min_range, max_range]``; ``cam2world`` in OpenCV axes (z forward, y down), pixel
    ``(u, v)`` on the ray ``((u − cx) / fx, (v − cy) / fy, 1)``."""
    d = _depth(depth, camera)
    pose = _pose("cam2world", cam2world)
    v, u = np.nonzero(_valid(d, min_range, max_range))
    z = d[v, u]
    cam = np.column_stack([(u - camera.cx) / camera.fx * z, (v - camera.cy) / camera.fy * z, z])
    out: F64 = cam @ pose[:3, :3].T + pose[:3, 3]
    return out


def project(
    points: npt.ArrayLike,
    camera: CameraSpec,
    cam2world: npt.ArrayLike,
    *,
    min_range: float = MIN_RANGE,
    max_range: float = MAX_RANGE,
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.bool_]]:
    """Where a camera sees world points: their pixels ``(u, v)`` (the core's convention,
    ``u = ⌊fx·x/z + cx + 0.5⌋``) and whether each is in view (in the image, its depth
    along the optical axis in ``[min_range, max_range]``). :func:`backproject`'s inverse;
    the pixels of points out of view are meaningless."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if not np.isfinite(pts).all():
        raise ValueError("points hold NaN or infinity")
    pose = _pose("cam2world", cam2world)
    cam = (pts - pose[:3, 3]) @ pose[:3, :3]
    z = cam[:, 2]
    in_range = (z >= min_range) & (z <= max_range) & (z > 0.0)
    safe = np.where(in_range, z, 1.0)
    u = np.floor(camera.fx * cam[:, 0] / safe + camera.cx + 0.5)
    v = np.floor(camera.fy * cam[:, 1] / safe + camera.cy + 0.5)
    inside = in_range & (u >= 0) & (u < camera.width) & (v >= 0) & (v < camera.height)
    u = np.where(inside, u, 0).astype(np.int64)
    v = np.where(inside, v, 0).astype(np.int64)
    return u, v, inside


def voxel_downsample(points: npt.ArrayLike, voxel: float) -> F64:
    """One point per occupied ``voxel``-sized cell (a lattice anchored at the origin): the
    centroid of the cell's points, cells in lexicographic order of their index (the Rust
    core's :func:`heapgrasp.voxel_downsample`; ValueError on a bad voxel or NaN)."""
    pts = np.ascontiguousarray(np.asarray(points, dtype=np.float64).reshape(-1, 3))
    out: F64 = core_voxel_downsample(pts, float(voxel))
    return out


@dataclass(frozen=True)
class TablePlane:
    """A plane ``normal · p = offset`` (unit normal pointing up) and its inlier points."""

    normal: F64
    offset: float
    inliers: npt.NDArray[np.bool_]

    def height(self, points: npt.ArrayLike) -> F64:
        """Signed distance of ``points`` above the plane (m)."""
        out: F64 = np.asarray(points, dtype=np.float64).reshape(-1, 3) @ self.normal - self.offset
        return out


def fit_table(
    points: npt.ArrayLike,
    *,
    threshold: float = 0.005,
    max_tilt: float = math.radians(10.0),
    iterations: int = 1000,
    seed: int = 0,
) -> TablePlane:
    """The plane with most points within ``threshold`` among planes tilted at most
    ``max_tilt`` from horizontal (RANSAC over ``iterations`` seeded triples), refitted to
    its inliers by least squares. ValueError when no such plane holds 3 points."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(pts) < 3:
        raise ValueError(f"a table needs at least 3 points, got {len(pts)}")
    rng = np.random.default_rng(seed)
    triples = rng.integers(0, len(pts), size=(iterations, 3))
    a, b, c = pts[triples[:, 0]], pts[triples[:, 1]], pts[triples[:, 2]]
    normals = np.cross(b - a, c - a)
    norms = np.linalg.norm(normals, axis=1)
    ok = norms > 1e-12
    normals[ok] /= norms[ok, None]
    normals *= np.where(normals[:, 2:3] < 0, -1.0, 1.0)
    ok &= normals[:, 2] >= math.cos(max_tilt)
    candidates = np.flatnonzero(ok)
    counts = np.zeros(len(candidates), dtype=np.int64)
    offsets = np.einsum("ij,ij->i", a, normals)
    for start in range(0, len(candidates), 64):  # bounded memory: 64 planes at a time
        k = candidates[start : start + 64]
        dist = np.abs(pts @ normals[k].T - offsets[k])
        counts[start : start + 64] = np.count_nonzero(dist <= threshold, axis=0)
    # The first plane with the most inliers (np.argmax keeps the first of ties).
    best = int(candidates[np.argmax(counts)]) if len(candidates) and counts.max() > 2 else -1
    if best < 0:
        raise ValueError(f"no plane within {math.degrees(max_tilt):.0f}° of horizontal found")
    inliers = np.abs((pts - a[best]) @ normals[best]) <= threshold
    centre = pts[inliers].mean(axis=0)
    _, _, vt = np.linalg.svd(pts[inliers] - centre, full_matrices=False)
    normal = vt[2] if vt[2, 2] >= 0 else -vt[2]
    if normal[2] < math.cos(max_tilt):  # the refit tilted too far: keep the sample's plane
        normal = normals[best]
    offset = float(centre @ normal)
    return TablePlane(normal, offset, np.abs(pts @ normal - offset) <= threshold)


class UnexploredRegion:
    """The lattice of points no view has shown to be empty (module doc)."""

    def __init__(self, points: npt.ArrayLike, table_z: float) -> None:
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if not np.isfinite(pts).all():
            raise ValueError("points hold NaN or infinity")
        if not math.isfinite(table_z):
            raise ValueError(f"table_z must be finite, got {table_z}")
        self.points = pts
        self.table_z = float(table_z)

    @classmethod
    def around(
        cls,
        object_points: npt.ArrayLike,
        table_z: float,
        *,
        spacing: float = 0.0075,
        grow_xy: float = 0.30,
        grow_z: float = 0.25,
    ) -> UnexploredRegion:
        """The lattice over the box of ``object_points`` grown by ``max(extent, grow_xy)``
        on each side in x and y, from ``table_z − 1 cm`` to the top plus
        ``max(z extent, grow_z)``, at ``spacing`` from the box's low corner."""
        obj = np.asarray(object_points, dtype=np.float64).reshape(-1, 3)
        if len(obj) == 0:
            raise ValueError("the unexplored region needs object points to grow from")
        if not (math.isfinite(spacing) and spacing > 0.0):
            raise ValueError(f"spacing must be finite and > 0, got {spacing}")
        lo, hi = obj.min(axis=0), obj.max(axis=0)
        extent = hi - lo
        grow = np.maximum(extent[:2], grow_xy)
        start = np.array([lo[0] - grow[0], lo[1] - grow[1], table_z - 0.01])
        stop = np.array([hi[0] + grow[0], hi[1] + grow[1], hi[2] + max(extent[2], grow_z)])
        axes = [np.arange(start[i], stop[i], spacing) for i in range(3)]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        return cls(grid, table_z)

    def __len__(self) -> int:
        return len(self.points)

    def seen(
        self,
        depth: npt.ArrayLike,
        camera: CameraSpec,
        cam2world: npt.ArrayLike,
        *,
        min_range: float = MIN_RANGE,
        max_range: float = MAX_RANGE,
    ) -> npt.NDArray[np.bool_]:
        """``(M,)`` True for the points the view shows to be empty (module doc; the
        core's ``seen_empty``, pixels by :class:`heapgrasp.PinholeCamera`'s rounding)."""
        d = _depth(depth, camera)
        pose = _pose("cam2world", cam2world)
        seen: npt.NDArray[np.bool_] = seen_empty(
            np.ascontiguousarray(self.points, dtype=np.float64),
            np.ascontiguousarray(d, dtype=np.float32),
            camera.core(),
            pose,
            min_range=min_range,
            max_range=max_range,
            occlusion=OCCLUSION,
            floor_z=self.table_z,
        )
        return seen

    def update(
        self,
        depth: npt.ArrayLike,
        camera: CameraSpec,
        cam2world: npt.ArrayLike,
        *,
        min_range: float = MIN_RANGE,
        max_range: float = MAX_RANGE,
    ) -> int:
        """Removes the points the view shows to be empty; returns how many."""
        seen = self.seen(depth, camera, cam2world, min_range=min_range, max_range=max_range)
        self.points = self.points[~seen]
        return int(seen.sum())
