"""A robot without a simulator: frames rendered by the core's :class:`MeshScene`.

It implements the robot seam (:mod:`heapgrasp.robot.interfaces`) the way a hardware
driver would — RGB frames, a clock, timed camera paths, a TCP and a gripper — over a
scene of boxes on the table, so the loop's tests need neither PyBullet nor PyTorch
(``test_robot_seam.py`` runs them with both blocked). The boxes are rendered red on a
grey table; :class:`RedSegmenter` segments the RGB image, as a learned segmenter would.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
import trimesh
from heapgrasp import MeshScene
from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.geometry.gripper import PANDA_HAND, GripperGeometry
from heapgrasp.geometry.motion import TimedPath
from heapgrasp.perception.frames import Capture, Frame
from heapgrasp.robot.interfaces import Contact

F64 = npt.NDArray[np.float64]
Box = tuple[tuple[float, float, float], tuple[float, float, float]]

RED = np.array([200, 30, 30], dtype=np.uint8)
GREY = np.array([120, 120, 120], dtype=np.uint8)


@dataclass(kw_only=True)
class MaskedFrame(Frame):
    """A frame that carries its exact silhouette (tests of perception)."""

    mask: npt.NDArray[np.bool_]


class FrameMasks:
    """The exact silhouettes :class:`MaskedFrame` carries (a ``MaskSource``)."""

    def silhouette(self, frame: Frame) -> npt.NDArray[np.bool_]:
        assert isinstance(frame, MaskedFrame)
        return frame.mask


class RedSegmenter:
    """Segments the rendered RGB image: red pixels are objects."""

    name = "red"

    def segment(self, frame: Frame) -> npt.NDArray[np.bool_]:
        assert frame.rgb is not None, "the fake camera always delivers RGB"
        rgb = frame.rgb.astype(np.int16)
        return np.asarray((rgb[..., 0] > 150) & (rgb[..., 1] < 80))


@dataclass
class FakeScene:
    """Boxes ``(centre, extents)`` standing on the table, as meshes."""

    boxes: Sequence[Box]
    meshes: MeshScene = field(default_factory=MeshScene)
    ids: dict[int, Box] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for centre, extents in self.boxes:
            mesh = trimesh.creation.box(extents=extents)
            pose = np.eye(4)
            pose[:3, 3] = centre
            oid = self.meshes.add_mesh(np.asarray(mesh.vertices), np.asarray(mesh.faces), pose)
            self.ids[oid] = (centre, extents)

    def under(self, tcp: F64) -> int | None:
        """The box whose top the fingertips reach around (within its footprint)."""
        p = tcp[:3, 3]
        for oid, (centre, extents) in self.ids.items():
            half = 0.5 * np.asarray(extents)
            inside = np.abs(p[:2] - np.asarray(centre[:2])) <= half[:2] + 0.005
            if inside.all() and p[2] <= centre[2] + half[2] + 0.01:
                return oid
        return None


@dataclass
class FakeCamera:
    spec: CameraSpec = field(default_factory=CameraSpec.continuous)
    depth: bool = False


class FakeArm:
    """Moves exactly where told, instantly for the grasp sequence, on the path's timing
    for the camera."""

    def __init__(self, scene: FakeScene, camera: FakeCamera | None = None) -> None:
        self.scene = scene
        self._camera = camera or FakeCamera()
        self._clock = 0.0
        self._tcp = np.eye(4)
        self.looks = 0
        self.paths: list[TimedPath] = []

    @property
    def camera(self) -> FakeCamera:
        return self._camera

    @property
    def clock(self) -> float:
        return self._clock

    @property
    def tcp(self) -> F64:
        return self._tcp

    def park(self) -> None:
        self._tcp = np.eye(4)
        self._tcp[:3, 3] = (-0.5, -0.5, 1.0)

    def _frame(self, cam2world: F64) -> Frame:
        spec = self._camera.spec
        pose = np.ascontiguousarray(cam2world, dtype=np.float64)
        labels = self.scene.meshes.render_labels(spec.core(), pose)
        rgb = np.where((labels > 0)[..., None], RED, GREY).astype(np.uint8)
        return Frame(cam2world=pose, camera=spec, time=self._clock, rgb=rgb)

    def look(self, cam2world: F64) -> Frame:
        self.looks += 1
        return self._frame(cam2world)

    def follow(self, path: TimedPath) -> Capture:
        self.paths.append(path)
        times, poses = path.sample()
        start = self._clock
        frames = []
        for t, pose in zip(times, poses, strict=True):
            self._clock = start + float(t)
            frames.append(self._frame(pose))
        self._clock = start + path.duration
        return Capture(times=start + times, frames=frames, duration=path.duration)

    def move_to(self, tcp: F64, *, opening: float) -> None:
        self._tcp = np.asarray(tcp, dtype=np.float64).copy()
        self._clock += 1.0

    def move_linear(self, tcp: F64, *, speed: float = 0.1, stop_on_contact: bool = False) -> bool:
        dist = float(np.linalg.norm(np.asarray(tcp)[:3, 3] - self._tcp[:3, 3]))
        self._tcp = np.asarray(tcp, dtype=np.float64).copy()
        self._clock += dist / speed
        return True

    def contact(self) -> Contact | None:
        return None


class FakeGripper:
    geometry: GripperGeometry = PANDA_HAND

    def __init__(self, arm: FakeArm) -> None:
        self.arm = arm
        self.held: int | None = None
        self.closed_at: list[F64] = []

    def open(self) -> None:
        self.held = None

    def close(self, width: float | None = None) -> None:
        self.closed_at.append(self.arm.tcp.copy())
        self.held = self.arm.scene.under(self.arm.tcp)

    def holding(self) -> bool:
        return self.held is not None


class FakeRobot:
    def __init__(self, scene: FakeScene) -> None:
        self.arm = FakeArm(scene)
        self.gripper = FakeGripper(self.arm)


class FakeTruth:
    """Scene truth of a :class:`FakeScene` (what a simulator would know)."""

    def __init__(self, scene: FakeScene, robot: FakeRobot) -> None:
        self.scene = scene
        self.robot = robot
        self.placed_ids: list[int] = []

    def silhouette(self, frame: Frame) -> npt.NDArray[np.bool_]:
        labels = self.scene.meshes.render_labels(frame.camera.core(), frame.cam2world)
        return np.asarray(labels > 0)

    def meshes(self) -> MeshScene:
        return self.scene.meshes

    def objects_left(self) -> int:
        return len(self.scene.ids)

    def object_near(self, point: F64, within: float = 0.03) -> int | None:
        tcp = np.eye(4)
        tcp[:3, 3] = point
        return self.scene.under(tcp)

    def held_object(self) -> int | None:
        return self.robot.gripper.held

    def category(self, object_id: int | None) -> str | None:
        return None if object_id is None else "opaque"

    def touched(self, contact: Contact, target: int | None) -> list[str]:
        return []

    def placed(self, object_id: int) -> None:
        self.placed_ids.append(object_id)
        self.scene.meshes.remove(object_id)
        del self.scene.ids[object_id]

    def settle(self) -> dict[int, str | None]:
        return {}
