"""The whole real robot faked: a UR controller (``fake_ur``), a Robotiq URCap server on
127.0.0.1 (``fake_robotiq``) and the RealSense driver over a fake ``pyrealsense2``
(``fake_realsense``) rendering a scene of boxes on the controller's clock, assembled
into :class:`~heapgrasp.robot.hardware.Drivers`, with a ``robot.toml``
and a tiny segmentation network (a 1 × 1 convolution that calls red pixels opaque) in
the format ``heapgrasp seg train`` writes. ``test_robot_run.py`` runs ``heapgrasp robot
run`` (dry and executed), ``replay``, ``check`` and ``calibrate`` on it.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import onnx
from fake_realsense import FakeRealSense
from fake_robot import GREY, RED, FakeScene
from fake_robotiq import FakeRobotiq
from fake_ur import (
    ClockCamera,
    FakeControl,
    FakeController,
    FakeReceive,
    set_world_pose,
    world_pose,
)
from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.inference import (
    FORMAT_VERSION,
    META_HPARAMS,
    META_KIND,
    META_PROVENANCE,
    META_VERSION,
    seal,
)
from heapgrasp.perception.segnet import CLASSES, SEG_KIND
from heapgrasp.robot.config import RobotConfig
from heapgrasp.robot.hardware import Drivers
from heapgrasp.robot.realsense import CameraFrame, RealSenseCamera, RealSenseSettings
from heapgrasp.robot.robotiq import Robotiq2F140
from heapgrasp.robot.ur import pose_to_rtde
from onnx import TensorProto, helper
from scipy.spatial.transform import Rotation

F64 = npt.NDArray[np.float64]

#: The world (the scene cube's corner) in the base frame: turned 90° and offset.
WORLD2BASE = np.eye(4)
WORLD2BASE[:3, :3] = Rotation.from_euler("z", 90, degrees=True).as_matrix()
WORLD2BASE[:3, 3] = (0.45, -0.15, 0.02)
#: The camera 8 cm beside and 12 cm behind the TCP, looking along its z.
CAM2TCP = np.eye(4)
CAM2TCP[:3, :3] = Rotation.from_euler("z", 3, degrees=True).as_matrix()
CAM2TCP[:3, 3] = (0.0, 0.08, -0.12)
SPEC = CameraSpec(width=160, height=120, fx=135.0, fy=135.0, cx=79.5, cy=59.5)
BOXES = [((0.11, 0.15, 0.035), (0.05, 0.04, 0.07)), ((0.20, 0.14, 0.03), (0.04, 0.04, 0.06))]

#: Where the arm parks (world): beside the scene, pointing down.
PARK = np.diag([1.0, -1.0, -1.0, 1.0])
PARK[:3, 3] = (0.15, -0.4, 0.5)


def red_network() -> bytes:
    """A segmentation network file: a 1 × 1 convolution scoring red pixels opaque."""
    w = np.zeros((4, 3, 1, 1), np.float32)
    b = np.zeros(4, np.float32)
    w[3, :, 0, 0] = (4.0, -4.0, 0.0)  # opaque: 4 (r - g) - 1
    b[3] = -1.0
    b[1] = b[2] = -10.0
    graph = helper.make_graph(
        [helper.make_node("Conv", ["image", "w", "b"], ["logits"])],
        "red",
        [helper.make_tensor_value_info("image", TensorProto.FLOAT, ["B", 3, "H", "W"])],
        [helper.make_tensor_value_info("logits", TensorProto.FLOAT, ["B", 4, "H", "W"])],
        [onnx.numpy_helper.from_array(w, "w"), onnx.numpy_helper.from_array(b, "b")],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    hparams = {
        "classes": list(CLASSES),
        "mean": [0.0, 0.0, 0.0],
        "std": [1.0, 1.0, 1.0],
        "encoder": "test-1x1",
        "pad_multiple": 1,
        "input_size": [SPEC.height, SPEC.width],
    }
    for key, value in (
        (META_KIND, SEG_KIND),
        (META_VERSION, str(FORMAT_VERSION)),
        (META_HPARAMS, json.dumps(hparams)),
        (META_PROVENANCE, json.dumps({"made_by": "tests/fake_hardware.py"})),
    ):
        entry = model.metadata_props.add()
        entry.key, entry.value = key, value
    return seal(model.SerializeToString())


class SceneCamera(ClockCamera):
    """A camera with the RealSense driver's life cycle, rendering the boxes red on grey."""

    def __init__(self, ctl: FakeController, scene: FakeScene, spec: CameraSpec = SPEC) -> None:
        self.scene = scene

        def render(cam2world: F64) -> npt.NDArray[np.uint8]:
            pose = np.ascontiguousarray(cam2world, dtype=np.float64)
            labels = scene.meshes.render_labels(spec.core(), pose)
            return np.where((labels > 0)[..., None], RED, GREY).astype(np.uint8)

        super().__init__(ctl, WORLD2BASE, CAM2TCP, render, spec)
        self.started = False
        self.distortion = np.zeros(5)

    def start(self) -> None:
        self.started = True

    def stop(self) -> None:
        self.started = False

    def describe(self) -> dict[str, Any]:
        return {"name": "fake camera", "serial": "0000"}


class ClockedRealSense(RealSenseCamera):
    """The RealSense driver over the fake ``pyrealsense2`` (``fake_realsense``), its frames
    rendered on the fake controller's clock: before the driver reads its queue, every
    frame due since the last read (one per ``1/fps`` s of controller time) is delivered
    through the fake pipeline's callback, rendered where the camera is then."""

    def __init__(self, ctl: FakeController, scene: FakeScene) -> None:
        self.ctl, self.scene = ctl, scene
        self.fake = FakeRealSense(self._render, clock=lambda: ctl.clock, auto=False)
        super().__init__(RealSenseSettings(320, 240, 30), rs=self.fake, clock=lambda: ctl.clock)
        self._due = ctl.clock

    def _render(self, t: float) -> tuple[npt.NDArray[np.uint8], None]:
        pose = world_pose(self.ctl, WORLD2BASE) @ CAM2TCP
        labels = self.scene.meshes.render_labels(self.spec.core(), np.ascontiguousarray(pose))
        return np.where((labels > 0)[..., None], RED, GREY).astype(np.uint8), None

    def _emit_due(self) -> None:
        if self._due <= self.ctl.clock:
            self.fake.emit()
            while self._due <= self.ctl.clock:
                self._due += 1.0 / 30

    def poll(self) -> list[CameraFrame]:
        self._emit_due()
        return super().poll()

    def wait(self, timeout: float | None = None) -> CameraFrame:
        self.ctl.advance(max(0.0, self._due - self.ctl.clock))
        self._emit_due()
        return super().wait(timeout)


@dataclass
class Rig:
    """Everything faked, and what happened to it."""

    ctl: FakeController
    scene: FakeScene
    server: FakeRobotiq
    camera: Any
    picked: list[int] = field(default_factory=list)
    grippers: list[Robotiq2F140] = field(default_factory=list)

    def drivers(self) -> Drivers:
        rig = self

        class SceneGripper(Robotiq2F140):
            """The Robotiq driver; before it closes, the fake server learns whether a box
            is between the fingers, and a box let go over the bin leaves the scene."""

            held: int | None = None

            def close(self, width: float | None = None) -> None:
                tcp = world_pose(rig.ctl, WORLD2BASE)
                self.held = rig.scene.under(tcp)
                rig.server.object_at = 150 if self.held is not None else None
                super().close(width)

            def open(self) -> None:
                was = self.held if self.holding() else None
                super().open()
                if was is not None and world_pose(rig.ctl, WORLD2BASE)[2, 3] > 0.15:
                    rig.picked.append(was)
                    rig.scene.meshes.remove(was)
                    del rig.scene.ids[was]
                self.held = None
                rig.server.object_at = None

        def gripper(config: RobotConfig) -> Robotiq2F140:
            g = SceneGripper("127.0.0.1", rig.server.port, timeout=1.0)
            rig.grippers.append(g)
            return g

        return Drivers(
            arm=lambda host, tcp: (FakeControl(rig.ctl.connect()), FakeReceive(rig.ctl)),
            camera=lambda settings: rig.camera,
            gripper=gripper,
            clock=lambda: rig.ctl.clock,
            sleep=rig.ctl.advance,
        )

    def motions(self) -> list[str]:
        """The motion commands the controller received."""
        return [n for n in self.ctl.names() if n in ("moveL", "moveJ", "servoL")]


def make_rig(boxes: list[Any] | None = None) -> Rig:
    ctl = FakeController()
    set_world_pose(ctl, WORLD2BASE, PARK)
    scene = FakeScene(boxes if boxes is not None else BOXES)
    server = FakeRobotiq().start()
    return Rig(ctl, scene, server, ClockedRealSense(ctl, scene))


def robot_toml(
    tmp: Path, *, method: dict[str, Any] | None = None, extra: str = "", network: bool = True
) -> Path:
    """A ``robot.toml`` for the rig (calibrated), with the red network beside it."""
    if network:
        (tmp / "red.onnx").write_bytes(red_network())
    lines = [
        "[arm]",
        'host = "fake"',
        f"park = {pose_to_rtde(WORLD2BASE @ PARK)}",
        "[calibration]",
        f"cam2tcp = {CAM2TCP.tolist()}",
        f"world2base = {WORLD2BASE.tolist()}",
        "[networks]",
        f'segmentation = "{"red.onnx" if network else ""}"',
        "[method]",
    ]
    for key, value in (method or {}).items():
        lines.append(f"{key} = {json.dumps(value)}")
    path = tmp / "robot.toml"
    path.write_text("\n".join(lines) + "\n" + extra)
    return path


Hook = Callable[[Rig], None]
