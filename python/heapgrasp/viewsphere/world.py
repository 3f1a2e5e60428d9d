"""Natarajan et al.'s world on our renderer: one object on a table, a depth camera on the
viewsphere.

The object's meshes (world frame, resting on the table top at ``z = 0``) and a table
slab are rendered by the Rust core's rasteriser (:class:`heapgrasp.MeshScene`; ideal depth as
in the paper, or through our depth sensor's model for a transparent, specular or opaque
object) with Natarajan et al.'s camera
(:data:`~heapgrasp.viewsphere.grasps.VIEWSPHERE_CAMERA`) from the poses of a
:class:`~heapgrasp.viewsphere.sphere.DiscreteViewsphere` centred on the table's centre.
Whether a set of views yields a grasp is :class:`~heapgrasp.viewsphere.grasps.ViewsphereGrasps`'
answer on these depth images (the same code a real camera's images would go through);
the world holds one and forwards its questions.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from heapgrasp import MeshScene
from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.sim.optics import Category, DepthModel
from heapgrasp.viewsphere.grasps import (
    VIEWSPHERE_CAMERA,
    FoundGrasp,
    ViewsphereConfig,
    ViewsphereGrasps,
)
from heapgrasp.viewsphere.policies import PoseKey, pose_key
from heapgrasp.viewsphere.sphere import SpherePose

__all__ = ["VIEWSPHERE_CAMERA", "FoundGrasp", "ViewsphereWorld"]

F64 = npt.NDArray[np.float64]

#: The table slab: half width and thickness (m).
_TABLE = (0.5, 0.02)


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
        config: ViewsphereConfig | None = None,
        camera: CameraSpec = VIEWSPHERE_CAMERA,
        sensor: Category | None = None,
        depth_model: DepthModel | None = None,
        seed: int = 0,
        perception: str = "depth",
    ) -> None:
        if not meshes:
            raise ValueError("the world needs at least one mesh")
        self.sensor = sensor
        self.depth_model = DepthModel() if depth_model is None else depth_model
        self.seed = seed
        self.config = ViewsphereConfig() if config is None else config
        self.sphere = self.config.sphere()
        self.camera = camera
        self.start = self.config.start
        self._scene = MeshScene()
        self.objects_scene = MeshScene()
        """The object's meshes alone (its silhouettes; HEAPGrasp's oracle reads them)."""
        self._object_ids: list[int] = []
        for k, (vertices, faces) in enumerate(meshes):
            v = np.ascontiguousarray(vertices, dtype=np.float64)
            f = np.ascontiguousarray(faces, dtype=np.int64)
            if v.ndim != 2 or v.shape[1] != 3 or not np.isfinite(v).all():
                raise ValueError(f"meshes[{k}]: vertices must be finite (V, 3)")
            self._object_ids.append(self._scene.add_mesh(v, f, np.eye(4)))
            self.objects_scene.add_mesh(v, f, np.eye(4))
        tv, tf = _table_mesh()
        self._scene.add_mesh(tv, tf, np.eye(4))
        self._table = MeshScene()
        self._table.add_mesh(tv, tf, np.eye(4))
        self._core_camera = camera.core()
        self.grasps = ViewsphereGrasps(
            self.render,
            sphere=self.sphere,
            camera=camera,
            config=self.config,
            silhouette=self.silhouette,
            perception=perception,
        )

    def render(self, pose: SpherePose) -> npt.NDArray[np.float32]:
        """The depth image from ``pose`` (camera z, m; 0 where nothing is measured),
        rendered anew (:meth:`depth` caches): ideal, or through the depth sensor's model
        with the object of optical category ``sensor``
        (:class:`~heapgrasp.sim.optics.DepthModel`; its noise seeded by the world's seed
        and the pose)."""
        cam2world = self.sphere.camera_pose(pose)
        ideal = self._scene.render_depth(self._core_camera, cam2world)
        if self.sensor is None:
            return ideal
        labels = self._scene.render_labels(self._core_camera, cam2world)
        category = np.where(
            np.isin(labels, self._object_ids), list(Category).index(self.sensor), -1
        ).astype(np.int8)
        background = self._table.render_depth(self._core_camera, cam2world)
        key = pose_key(pose)
        rng = np.random.default_rng([self.seed, round(key[0] * 1e6), round(key[1] * 1e6)])
        return self.depth_model.apply(rng, ideal, background, category)

    def silhouette(self, pose: SpherePose) -> npt.NDArray[np.bool_]:
        """The object's silhouette from ``pose`` (ideal segmentation: every optical
        category segments alike, HEAPGrasp's premise)."""
        return self.objects_scene.render_mask(self._core_camera, self.sphere.camera_pose(pose))

    def depth(self, pose: SpherePose) -> npt.NDArray[np.float32]:
        """The view's depth image (rendered once)."""
        return self.grasps.depth(pose)

    def object_points(self, poses: Sequence[SpherePose]) -> tuple[F64, float]:
        """The fused object points of ``poses`` and the table's height."""
        return self.grasps.object_points(poses)

    def grasp(self, poses: Sequence[SpherePose]) -> FoundGrasp | None:
        """The first collision-free grasp on what ``poses`` show (the first pose is the
        one the unexplored region grows from), or None."""
        return self.grasps.grasp(poses)

    def grasp_found(self, keys: frozenset[PoseKey]) -> bool:
        """:func:`breadth_first`'s question for a set of pose keys (the start pose,
        which every set holds, first)."""
        return self.grasps.grasp_found(keys)
