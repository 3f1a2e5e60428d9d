"""The simulated grasping world: a PyBullet scene on a table, with ground truth.

Frames (see :class:`SimWorld`):

* **world frame** = the workspace frame Σw: the scene cube (side ``cube_size``, VGN's
  0.30 m) has its minimum corner at the origin, the table top is the plane z = 0;
* every object is a PyBullet body whose base frame is its mesh frame
  (``createMultiBody`` with a zero inertial offset), so ``obj2world`` from PyBullet
  maps the mesh file of :class:`~heapgrasp.sim.object_model.ObjectModel` into the world.

Ground truth on hot paths comes from the Rust core: silhouettes, labels and ideal
depth are rendered by :class:`heapgrasp.MeshScene` from the objects' meshes at the
simulator's poses (exact ray-through-pixel-centre semantics, ~0.1 ms a frame), and the
table's depth is the analytic plane z = 0. PyBullet's TinyRenderer (~30 ms a frame)
renders RGB only when asked. The simulated depth sensor is
:class:`~heapgrasp.sim.optics.DepthModel`.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from heapgrasp import MeshScene
from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.perception.frames import Capture, Frame
from heapgrasp.sim.bullet import pb
from heapgrasp.sim.mesh_files import load_mesh
from heapgrasp.sim.object_model import ObjectModel
from heapgrasp.sim.objects import ObjectLibrary
from heapgrasp.sim.optics import Category, DepthModel
from heapgrasp.sim.poses import pose_matrix, split_pose

if TYPE_CHECKING:
    from heapgrasp.geometry.motion import TimedPath

__all__ = ["CATEGORY_GROUPS", "CameraMount", "SimFrame", "SimObject", "SimWorld", "WorldConfig"]

Layout = Literal["pile", "packed"]
#: Scene groups of HEAPGrasp §VI-C.
CATEGORY_GROUPS = ("transparent", "specular", "opaque", "mixed")

_COLORS = {
    Category.TRANSPARENT: (0.80, 0.90, 1.00, 0.30),
    Category.SPECULAR: (0.78, 0.78, 0.82, 1.00),
}


@dataclass(frozen=True)
class WorldConfig:
    """Physical set-up of the world.

    Parameters
    ----------
    cube_size
        Side of the scene cube (the grid's cube), metres.
    time_step
        Physics step, seconds.
    drop_height
        Height above the table from which pile objects are dropped, metres.
    pile_box
        Inner side of the temporary box that keeps a pile together, metres.
    settle_seconds
        Upper bound on the simulated time allowed for a scene to come to rest.
    friction
        Lateral friction of objects and table.
    """

    cube_size: float = 0.30
    time_step: float = 1.0 / 240.0
    drop_height: float = 0.20
    pile_box: float = 0.20
    settle_seconds: float = 4.0
    friction: float = 1.0

    def __post_init__(self) -> None:
        if not self.cube_size > 0:
            raise ValueError(f"cube_size must be > 0, got {self.cube_size}")
        if not 0 < self.time_step <= 0.05:
            raise ValueError(f"time_step must be in (0, 0.05] s, got {self.time_step}")


@dataclass
class SimObject:
    """An object in the world."""

    id: int
    """World id (>= 1); equals the id of its mesh in :attr:`SimWorld.object_scene`."""
    body: int
    """PyBullet body unique id."""
    model: ObjectModel
    category: Category


@dataclass(kw_only=True)
class SimFrame(Frame):
    """A simulated frame: a :class:`~heapgrasp.perception.frames.Frame` plus the ground
    truth that only the simulator has (read by the loop only through
    :class:`heapgrasp.sim.truth.SimTruth`)."""

    mask: npt.NDArray[np.bool_]
    """Ideal segmentation: True where the pixel-centre ray hits an object first."""
    labels: npt.NDArray[np.int32]
    """World id of the object seen at each pixel, 0 for background."""
    depth_ideal: npt.NDArray[np.float32] | None = None
    """Exact depth (m) of the nearest surface, table included (:attr:`depth` is the
    sensor's, after :class:`DepthModel`)."""


@runtime_checkable
class CameraMount(Protocol):
    """Something that can place the hand-eye camera."""

    def move_camera(self, cam2world: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """Moves so the camera is at ``cam2world`` (OpenCV axes) as closely as it can;
        returns the ``cam2world`` actually reached."""
        ...


@dataclass
class _Meshes:
    vertices: npt.NDArray[np.float64]
    faces: npt.NDArray[np.int64]


@dataclass
class SimWorld:
    """A PyBullet world with a table, the scene cube, objects and exact ground truth.

    Use as a context manager (or call :meth:`close`) to release the PyBullet client.
    ``seed`` seeds every random choice of the world (scenes, sensor noise), so the same
    seed and the same calls give the same scenes and frames.
    """

    library: ObjectLibrary
    config: WorldConfig = field(default_factory=WorldConfig)
    depth_model: DepthModel = field(default_factory=DepthModel)
    gui: bool = False
    seed: int = 0

    def __post_init__(self) -> None:
        self.client = pb.connect(pb.GUI if self.gui else pb.DIRECT)
        self.rng = np.random.default_rng(self.seed)
        self.object_scene = MeshScene()
        self.opaque_scene = MeshScene()
        self.objects: dict[int, SimObject] = {}
        self._opaque_ids: dict[int, int] = {}
        self._mesh_cache: dict[str, _Meshes] = {}
        self._ray_cache: dict[CameraSpec, npt.NDArray[np.float64]] = {}
        self.scene_info: dict[str, Any] = {}
        self.time = 0.0
        """Simulated clock (s): advanced by every physics step and camera motion."""
        self._reset_physics()

    # ------------------------------------------------------------------ lifecycle
    def close(self) -> None:
        """Disconnects from PyBullet."""
        if self.client >= 0 and pb.isConnected(self.client):
            pb.disconnect(self.client)
        self.client = -1

    def __enter__(self) -> SimWorld:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _reset_physics(self) -> None:
        pb.resetSimulation(physicsClientId=self.client)
        pb.setGravity(0, 0, -9.81, physicsClientId=self.client)
        pb.setTimeStep(self.config.time_step, physicsClientId=self.client)
        half = 1.0
        shape = pb.createCollisionShape(
            pb.GEOM_BOX, halfExtents=[half, half, 0.01], physicsClientId=self.client
        )
        visual = pb.createVisualShape(
            pb.GEOM_BOX,
            halfExtents=[half, half, 0.01],
            rgbaColor=[0.55, 0.45, 0.35, 1.0],
            physicsClientId=self.client,
        )
        c = self.config.cube_size / 2
        self.table = pb.createMultiBody(
            0.0, shape, visual, [c, c, -0.01], physicsClientId=self.client
        )
        pb.changeDynamics(
            self.table, -1, lateralFriction=self.config.friction, physicsClientId=self.client
        )
        self.object_scene = MeshScene()
        self.opaque_scene = MeshScene()
        self.objects = {}
        self._opaque_ids = {}

    # ------------------------------------------------------------------ scenes
    def reset(
        self,
        *,
        layout: Layout = "pile",
        n_objects: int = 5,
        category: str = "mixed",
        seed: int | None = None,
        split: Literal["train", "test"] = "test",
        models: Sequence[ObjectModel] | None = None,
    ) -> list[SimObject]:
        """Builds a new scene and lets it settle.

        Parameters
        ----------
        layout
            ``"pile"`` (dropped into a temporary box, which is then removed) or
            ``"packed"`` (upright, random yaw, rejected on collision), as in VGN.
        n_objects
            Number of objects to place (some may end outside the cube and be removed).
        category
            Scene group: ``"transparent"``, ``"specular"``, ``"opaque"`` or ``"mixed"``
            (each category at least once when ``n_objects >= 3``).
        seed
            Reseeds the world's generator first, so the scene depends on it alone.
        split
            Object subset to draw from (``"test"`` = objects unseen in training).
        models
            Explicit models to place instead of sampling the library.
        """
        if layout not in ("pile", "packed"):
            raise ValueError(f"layout must be 'pile' or 'packed', got {layout!r}")
        if category not in CATEGORY_GROUPS:
            raise ValueError(f"category must be one of {CATEGORY_GROUPS}, got {category!r}")
        if n_objects < 0:
            raise ValueError(f"n_objects must be >= 0, got {n_objects}")
        if seed is not None:
            self.rng = np.random.default_rng(seed)
        self._reset_physics()
        chosen = (
            list(models)
            if models is not None
            else self.library.sample(self.rng, n_objects, split=split)
        )
        cats = self._categories(category, len(chosen))
        if layout == "pile":
            self._place_pile(chosen, cats)
        else:
            self._place_packed(chosen, cats)
        self._remove_outside()
        self.scene_info = {"layout": layout, "category": category, "seed": seed, "split": split}
        self.time = 0.0  # the task's clock starts once the scene has settled
        return list(self.objects.values())

    def _categories(self, group: str, n: int) -> list[Category]:
        if group != "mixed":
            return [Category(group)] * n
        base = [list(Category)[i % 3] for i in range(n)]
        order = self.rng.permutation(n)
        return [base[i] for i in order]

    def _place_pile(self, models: Sequence[ObjectModel], cats: Sequence[Category]) -> None:
        c = self.config.cube_size / 2
        inner = self.config.pile_box / 2
        walls = []
        for dx, dy, hx, hy in (
            (inner + 0.01, 0.0, 0.01, inner + 0.02),
            (-inner - 0.01, 0.0, 0.01, inner + 0.02),
            (0.0, inner + 0.01, inner + 0.02, 0.01),
            (0.0, -inner - 0.01, inner + 0.02, 0.01),
        ):
            shape = pb.createCollisionShape(
                pb.GEOM_BOX, halfExtents=[hx, hy, 0.15], physicsClientId=self.client
            )
            walls.append(
                pb.createMultiBody(
                    0.0, shape, -1, [c + dx, c + dy, 0.15], physicsClientId=self.client
                )
            )
        for model, cat in zip(models, cats, strict=True):
            xy = c + self.rng.uniform(-inner / 2, inner / 2, size=2)
            quat = _random_quaternion(self.rng)
            pos = [float(xy[0]), float(xy[1]), self.config.drop_height]
            self.spawn(model, pose_matrix(pos, quat), cat)
            self._simulate(0.5)
        self._settle()
        for w in walls:
            pb.removeBody(w, physicsClientId=self.client)
        self._settle()

    def _place_packed(self, models: Sequence[ObjectModel], cats: Sequence[Category]) -> None:
        c = self.config.cube_size / 2
        for model, cat in zip(models, cats, strict=True):
            for _ in range(20):
                yaw = self.rng.uniform(0, 2 * np.pi)
                xy = c + self.rng.uniform(-0.09, 0.09, size=2)
                z = model.extents[2] / 2 + 0.002
                quat = pb.getQuaternionFromEuler([0.0, 0.0, yaw])
                obj = self.spawn(model, pose_matrix([xy[0], xy[1], z], quat), cat)
                pb.performCollisionDetection(physicsClientId=self.client)
                touching = [
                    o
                    for o in self.objects.values()
                    if o.id != obj.id
                    and pb.getClosestPoints(
                        obj.body, o.body, distance=0.0, physicsClientId=self.client
                    )
                ]
                if not touching:
                    break
                self.remove(obj.id)
        self._settle()

    def _remove_outside(self) -> list[SimObject]:
        s = self.config.cube_size
        removed = []
        for obj in list(self.objects.values()):
            x, y, z = self.object_pose(obj.id)[:3, 3]
            if not (0.0 <= x <= s and 0.0 <= y <= s and -0.01 <= z <= s):
                removed.append(self.remove(obj.id))
        return removed

    def settle(self) -> list[SimObject]:
        """Lets the objects come to rest (at most ``settle_seconds`` of physics) and takes
        out of the world those whose origin then lies outside the scene cube, as VGN's
        simulation does after every grasp; returns the objects taken out."""
        self._settle()
        return self._remove_outside()

    # ------------------------------------------------------------------ objects
    def _mesh(self, model: ObjectModel) -> _Meshes:
        key = str(model.visual_mesh)
        if key not in self._mesh_cache:
            v, f = load_mesh(model.visual_mesh)
            self._mesh_cache[key] = _Meshes(v, f)
        return self._mesh_cache[key]

    def spawn(
        self, model: ObjectModel, obj2world: npt.NDArray[np.float64], category: Category
    ) -> SimObject:
        """Adds an object at ``obj2world`` and returns it."""
        cid = self.client
        parts = [str(p) for p in model.collision_meshes]
        if len(parts) == 1:
            collision = pb.createCollisionShape(
                pb.GEOM_MESH, fileName=parts[0], physicsClientId=cid
            )
        else:
            collision = pb.createCollisionShapeArray(
                shapeTypes=[pb.GEOM_MESH] * len(parts), fileNames=parts, physicsClientId=cid
            )
        color = _COLORS.get(category)
        if color is None:
            color = (*self.rng.uniform(0.15, 0.95, size=3).tolist(), 1.0)
        visual = pb.createVisualShape(
            pb.GEOM_MESH,
            fileName=str(model.visual_mesh),
            rgbaColor=list(color),
            physicsClientId=cid,
        )
        pos, quat = split_pose(obj2world)
        body = pb.createMultiBody(
            model.mass,
            collision,
            visual,
            pos,
            quat,
            baseInertialFramePosition=[0.0, 0.0, 0.0],
            physicsClientId=cid,
        )
        pb.changeDynamics(
            body,
            -1,
            lateralFriction=self.config.friction,
            rollingFriction=0.001,
            spinningFriction=0.001,
            physicsClientId=cid,
        )
        mesh = self._mesh(model)
        oid = self.object_scene.add_mesh(mesh.vertices, mesh.faces, obj2world)
        if category != Category.TRANSPARENT:
            self._opaque_ids[oid] = self.opaque_scene.add_mesh(mesh.vertices, mesh.faces, obj2world)
        obj = SimObject(oid, body, model, category)
        self.objects[oid] = obj
        return obj

    def remove(self, object_id: int) -> SimObject:
        """Removes an object from the world (and from the ground-truth scenes)."""
        obj = self._get(object_id)
        pb.removeBody(obj.body, physicsClientId=self.client)
        self.object_scene.remove(object_id)
        if object_id in self._opaque_ids:
            self.opaque_scene.remove(self._opaque_ids.pop(object_id))
        del self.objects[object_id]
        return obj

    def _get(self, object_id: int) -> SimObject:
        try:
            return self.objects[object_id]
        except KeyError:
            raise KeyError(
                f"no object with id {object_id} in the world (ids: {sorted(self.objects)})"
            ) from None

    def object_vertices(self, object_id: int) -> npt.NDArray[np.float64]:
        """``(V, 3)`` vertices of an object's mesh in its own frame (m)."""
        return self._mesh(self._get(object_id).model).vertices

    def object_pose(self, object_id: int) -> npt.NDArray[np.float64]:
        """``obj2world`` of an object, from PyBullet."""
        obj = self._get(object_id)
        pos, quat = pb.getBasePositionAndOrientation(obj.body, physicsClientId=self.client)
        return pose_matrix(pos, quat)

    def sync(self) -> None:
        """Copies the simulator's object poses into the ground-truth mesh scenes."""
        for oid in self.objects:
            pose = self.object_pose(oid)
            self.object_scene.set_pose(oid, pose)
            if oid in self._opaque_ids:
                self.opaque_scene.set_pose(self._opaque_ids[oid], pose)

    # ------------------------------------------------------------------ physics
    def step_physics(self, n: int = 1) -> None:
        """Runs ``n`` physics steps and advances :attr:`time` by ``n * time_step``."""
        for _ in range(n):
            pb.stepSimulation(physicsClientId=self.client)
        self.time += n * self.config.time_step

    def _simulate(self, seconds: float) -> None:
        self.step_physics(round(seconds / self.config.time_step))

    def _settle(self) -> None:
        steps = int(self.config.settle_seconds / self.config.time_step)
        for k in range(steps):
            self.step_physics()
            if k % 24 == 23 and self._at_rest():
                break

    def _at_rest(self) -> bool:
        for obj in self.objects.values():
            lin, ang = pb.getBaseVelocity(obj.body, physicsClientId=self.client)
            if np.linalg.norm(lin) > 0.005 or np.linalg.norm(ang) > 0.05:
                return False
        return True

    def step(self, seconds: float) -> None:
        """Advances the physics (and :attr:`time`) by ``seconds``."""
        if not (math.isfinite(seconds) and seconds >= 0):
            raise ValueError(f"seconds must be finite and >= 0, got {seconds}")
        self._simulate(seconds)

    # ------------------------------------------------------------------ sensing
    def _rays(self, camera: CameraSpec) -> npt.NDArray[np.float64]:
        if camera not in self._ray_cache:
            u, v = np.meshgrid(np.arange(camera.width), np.arange(camera.height))
            d = np.stack(
                [(u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, np.ones(u.shape)], -1
            )
            self._ray_cache[camera] = d
        return self._ray_cache[camera]

    def _table_depth(
        self, camera: CameraSpec, cam2world: npt.NDArray[np.float64]
    ) -> npt.NDArray[np.float32]:
        d_world = self._rays(camera) @ cam2world[:3, :3].T
        oz = cam2world[2, 3]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = -oz / d_world[..., 2]
        return np.where((t > 0) & np.isfinite(t), t, 0.0).astype(np.float32)

    def capture(
        self,
        cam2world: npt.NDArray[np.float64],
        camera: CameraSpec | None = None,
        *,
        depth: bool = True,
        rgb: bool = False,
    ) -> SimFrame:
        """Captures one frame from ``cam2world`` (OpenCV axes), stamped :attr:`time`."""
        cam = camera or CameraSpec.continuous()
        pose = np.ascontiguousarray(cam2world, dtype=np.float64)
        core = cam.core()
        self.sync()
        labels = self.object_scene.render_labels(core, pose).astype(np.int32)
        frame = SimFrame(cam2world=pose, camera=cam, time=self.time, mask=labels > 0, labels=labels)
        if depth:
            table = self._table_depth(cam, pose)
            obj_depth = self.object_scene.render_depth(core, pose)
            ideal = _nearest(obj_depth, table)
            background = _nearest(self.opaque_scene.render_depth(core, pose), table)
            category_map = np.full(labels.shape, -1, dtype=np.int8)
            cats = list(Category)
            for oid, obj in self.objects.items():
                category_map[labels == oid] = cats.index(obj.category)
            frame.depth_ideal = ideal
            frame.depth = self.depth_model.apply(self.rng, ideal, background, category_map)
        if rgb:
            frame.rgb = self.render_rgb(pose, cam)[0]
        return frame

    def follow(
        self,
        path: TimedPath,
        camera: CameraSpec | None = None,
        *,
        fps: float | None = None,
        mount: CameraMount | None = None,
        depth: bool = False,
        rgb: bool = False,
    ) -> Capture:
        """Moves the hand-eye camera along a timed path, capturing at the camera rate.

        Frames are taken at ``path.frame_times(fps)`` (``t = 0, 1/fps, ...`` and the
        resting end frame), each stamped with the simulated clock :attr:`time` at the
        start plus ``t``; the clock then advances by ``path.duration``. The objects are
        at rest while the camera moves, so the physics is not stepped.

        Parameters
        ----------
        path
            Timed camera path (``cam2world`` poses), e.g. from
            :func:`heapgrasp.geometry.motion.plan_waypoints`.
        camera
            Intrinsics; default :meth:`CameraSpec.continuous` (320×240).
        fps
            Frame rate (Hz); default ``path.fps``.
        mount
            What carries the camera (:class:`CameraMount`): the arm moves so its camera
            reaches each pose and the frame is taken from the pose it actually reached;
            default a free-flying camera at exactly the path's poses.
        depth, rgb
            Also render sensor depth / PyBullet RGB for every frame (slower).
        """
        times, poses = path.sample(fps)
        start = self.time
        frames: list[Frame] = []
        for t, pose in zip(times, poses, strict=True):
            reached = pose if mount is None else mount.move_camera(pose)
            self.time = start + float(t)
            frames.append(self.capture(reached, camera, depth=depth, rgb=rgb))
        self.time = start + path.duration
        return Capture(times=start + times, frames=frames, duration=path.duration)

    def render_rgb(
        self, cam2world: npt.NDArray[np.float64], camera: CameraSpec | None = None
    ) -> tuple[npt.NDArray[np.uint8], npt.NDArray[np.int32]]:
        """PyBullet TinyRenderer image and its body-id segmentation (-1 = none)."""
        cam = camera or CameraSpec.continuous()
        _, _, rgba, _, seg = pb.getCameraImage(
            cam.width,
            cam.height,
            viewMatrix=cam.gl_view(cam2world),
            projectionMatrix=cam.gl_projection(),
            renderer=pb.ER_TINY_RENDERER,
            physicsClientId=self.client,
        )
        rgb = np.asarray(rgba, dtype=np.uint8).reshape(cam.height, cam.width, 4)[..., :3]
        seg_arr = np.asarray(seg, dtype=np.int32).reshape(cam.height, cam.width)
        return np.ascontiguousarray(rgb), seg_arr

    # ------------------------------------------------------------------ export
    def to_dict(self) -> dict[str, Any]:
        """The scene as plain data: workspace, and per object its id, model, category,
        ``obj2world`` and the path of its mesh file (object frame, metres)."""
        return {
            "workspace": {"origin": [0.0, 0.0, 0.0], "size": self.config.cube_size},
            **self.scene_info,
            "objects": [
                {
                    "id": obj.id,
                    "name": obj.model.name,
                    "source": obj.model.source,
                    "split": obj.model.split,
                    "category": obj.category.value,
                    "obj2world": self.object_pose(obj.id).tolist(),
                    "mesh": str(obj.model.visual_mesh),
                }
                for obj in self.objects.values()
            ],
        }

    def export_scene(self, path: Path) -> None:
        """Writes :meth:`to_dict` as JSON."""
        Path(path).write_text(json.dumps(self.to_dict(), indent=2))


def _nearest(a: npt.NDArray[np.float32], b: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
    """Per-pixel nearest of two depth images where 0 means "nothing"."""
    inf = np.float32(np.inf)
    out = np.minimum(np.where(a > 0, a, inf), np.where(b > 0, b, inf))
    return np.where(np.isfinite(out), out, 0.0).astype(np.float32)


def _random_quaternion(rng: np.random.Generator) -> tuple[float, float, float, float]:
    q = rng.standard_normal(4)
    q /= np.linalg.norm(q)
    return (float(q[0]), float(q[1]), float(q[2]), float(q[3]))
