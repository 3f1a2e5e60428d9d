"""Seed 001's world on our renderer: one object on a table, a depth camera on the
viewsphere, and whether the views seen so far yield a grasp.

The object's meshes (world frame, resting on the table top at ``z = 0``) and a table
slab are rendered by the Rust core's rasteriser (:class:`heapgrasp.MeshScene`, ideal
depth as in the paper) with seed 001's camera (:data:`SEED001_CAMERA`: 640 × 480,
horizontal field of view 1.047 rad) from the poses of a
:class:`~heapgrasp.geometry.viewsphere.DiscreteViewsphere` centred on the table's centre.
For a set of views :meth:`ViewsphereWorld.grasp` runs the benchmark's perception
(:mod:`heapgrasp.perception.clouds`: fusion at 7.5 mm, the table, the object's points in
±0.15 m × ±0.15 m × 0.01–0.30 m around the centre, the unexplored region grown from
what the first view shows) and its grasp synthesis (:mod:`heapgrasp.planning.synthesis`)
and returns the first collision-free grasp. Depth and points are cached per view, so a
search over sets of views (:func:`~heapgrasp.planning.viewsphere_policies.breadth_first`)
renders each view once.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from heapgrasp import MeshScene
from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.geometry.viewsphere import START, DiscreteViewsphere, SpherePose
from heapgrasp.perception.clouds import UnexploredRegion, backproject, fit_table, voxel_downsample
from heapgrasp.planning.synthesis import (
    estimate_normals,
    first_free_grasp,
    grasp_pairs,
    rank_grasps,
    usable_contacts,
)
from heapgrasp.planning.viewsphere_policies import PoseKey, pose_key

__all__ = ["SEED001_CAMERA", "FoundGrasp", "ViewsphereWorld"]

F64 = npt.NDArray[np.float64]

#: Seed 001's depth camera: 640 × 480, fx = fy = 554.2547, principal point (320.5, 240.5).
SEED001_CAMERA = CameraSpec(width=640, height=480, fx=554.2547, fy=554.2547, cx=320.5, cy=240.5)

#: The fusion's voxel (m).
VOXEL = 0.0075
#: Where the object's points are looked for around the centre (m): x, y half widths and
#: the height range above the table.
OBJECT_BOX = (0.15, 0.15, 0.01, 0.30)
#: The table slab: half width and thickness (m).
_TABLE = (0.5, 0.02)


@dataclass(frozen=True)
class FoundGrasp:
    """A grasp the synthesis found: the TCP pose, the contacts and the quality (deg)."""

    pose: F64
    contacts: tuple[F64, F64]
    quality: float
    width: float


def _table_mesh() -> tuple[F64, npt.NDArray[np.int64]]:
    h, t = _TABLE
    v = np.array([[x, y, z] for x in (-h, h) for y in (-h, h) for z in (-t, 0.0)])
    faces = np.array(
        [
            [0, 2, 3], [0, 3, 1], [4, 5, 7], [4, 7, 6], [0, 1, 5], [0, 5, 4],
            [2, 6, 7], [2, 7, 3], [0, 4, 6], [0, 6, 2], [1, 3, 7], [1, 7, 5],
        ]
    )  # fmt: skip
    return v, faces


class ViewsphereWorld:
    """One object (its meshes in the world frame) on the table, seen from the
    viewsphere (module doc)."""

    def __init__(
        self,
        meshes: Sequence[tuple[npt.ArrayLike, npt.ArrayLike]],
        *,
        sphere: DiscreteViewsphere | None = None,
        camera: CameraSpec = SEED001_CAMERA,
        start: SpherePose = START,
    ) -> None:
        if not meshes:
            raise ValueError("the world needs at least one mesh")
        self.sphere = DiscreteViewsphere() if sphere is None else sphere
        self.camera = camera
        self.start = start
        self._scene = MeshScene()
        for k, (vertices, faces) in enumerate(meshes):
            v = np.ascontiguousarray(vertices, dtype=np.float64)
            f = np.ascontiguousarray(faces, dtype=np.int64)
            if v.ndim != 2 or v.shape[1] != 3 or not np.isfinite(v).all():
                raise ValueError(f"meshes[{k}]: vertices must be finite (V, 3)")
            self._scene.add_mesh(v, f, np.eye(4))
        tv, tf = _table_mesh()
        self._scene.add_mesh(tv, tf, np.eye(4))
        self._core_camera = camera.core()
        self._points: dict[PoseKey, F64] = {}
        self._depth: dict[PoseKey, npt.NDArray[np.float32]] = {}
        self._first: dict[PoseKey, F64] = {}

    def depth(self, pose: SpherePose) -> npt.NDArray[np.float32]:
        """The ideal depth image from ``pose`` (camera z, m; 0 where nothing is hit)."""
        key = pose_key(pose)
        if key not in self._depth:
            cam2world = self.sphere.camera_pose(pose)
            self._depth[key] = self._scene.render_depth(self._core_camera, cam2world)
        return self._depth[key]

    def points(self, pose: SpherePose) -> F64:
        """The view's world points (the sensor's range), down-sampled to the voxel."""
        key = pose_key(pose)
        if key not in self._points:
            cloud = backproject(self.depth(pose), self.camera, self.sphere.camera_pose(pose))
            self._points[key] = voxel_downsample(cloud, VOXEL)
        return self._points[key]

    def object_points(self, poses: Iterable[SpherePose]) -> tuple[F64, float]:
        """The fused object points of ``poses`` and the table's height."""
        fused = voxel_downsample(np.vstack([self.points(p) for p in poses]), VOXEL)
        if len(fused) < 3:
            return np.zeros((0, 3)), 0.0
        try:
            table = fit_table(fused)
        except ValueError:
            return np.zeros((0, 3)), 0.0
        table_z = float(table.offset / table.normal[2])
        c = np.asarray(self.sphere.centre)
        hx, hy, z0, z1 = OBJECT_BOX
        height = table.height(fused)
        keep = (
            (np.abs(fused[:, 0] - c[0]) <= hx)
            & (np.abs(fused[:, 1] - c[1]) <= hy)
            & (height >= z0)
            & (height <= z1)
        )
        return fused[keep], table_z

    def _first_object(self, pose: SpherePose) -> F64:
        """The object points one view shows (what the unexplored region grows from),
        cached: every set of views a search asks about starts with the same pose."""
        key = pose_key(pose)
        if key not in self._first:
            self._first[key] = self.object_points([pose])[0]
        return self._first[key]

    def grasp(self, poses: Sequence[SpherePose]) -> FoundGrasp | None:
        """The first collision-free grasp on what ``poses`` show (the first pose is the
        one the unexplored region grows from), or None."""
        if not poses:
            raise ValueError("grasp needs at least one view")
        obj, table_z = self.object_points(poses)
        first = self._first_object(poses[0])
        if len(obj) < 10 or len(first) == 0:
            return None
        region = UnexploredRegion.around(first, table_z, spacing=VOXEL)
        for p in poses:
            region.update(self.depth(p), self.camera, self.sphere.camera_pose(p))
        normals, curvature = estimate_normals(obj)
        usable = usable_contacts(obj, normals, curvature)
        pairs = grasp_pairs(obj, normals, usable, voxel=VOXEL)
        if len(pairs) == 0:
            return None
        centre = np.vstack([obj, region.points[_inside(region.points, obj)]]).mean(axis=0)
        order = rank_grasps(obj, pairs, centre)
        found = first_free_grasp(obj, region.points, pairs, order)
        if found is None:
            return None
        k, pose = found
        return FoundGrasp(
            pose=pose,
            contacts=(obj[pairs.first[k]], obj[pairs.second[k]]),
            quality=float(pairs.quality[k]),
            width=float(pairs.width[k]),
        )

    def grasp_found(self, keys: frozenset[PoseKey]) -> bool:
        """:func:`breadth_first`'s question for a set of pose keys (the start pose,
        which every set holds, first)."""
        start = pose_key(self.start)
        ordered = [start, *sorted(k for k in keys if k != start)]
        poses = [SpherePose(a, p) for a, p in ordered]
        return self.grasp(poses) is not None


def _inside(points: F64, obj: F64) -> npt.NDArray[np.bool_]:
    """The points within the object's bounding box (the public code's centroid counts
    the unexplored points there, the object's hidden part)."""
    lo, hi = obj.min(axis=0), obj.max(axis=0)
    inside: npt.NDArray[np.bool_] = np.all((points >= lo) & (points <= hi), axis=1)
    return inside
