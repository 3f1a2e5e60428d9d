"""What carries the hand-eye camera and the gripper in simulation: two embodiments, and
the robot seam (:mod:`heapgrasp.robot.interfaces`) implemented over them.

* :class:`heapgrasp.sim.gripper.PandaHand` — a free-flying Panda hand and a free camera
  (VGN's simulation): fast, for experiments where arm kinematics are not the question;
* :class:`heapgrasp.sim.arm.PandaArm` — the Franka Panda arm of ``pybullet_data`` with the
  camera on its hand (configurable hand-to-camera extrinsic), moved by inverse kinematics
  within its joint limits.

Both satisfy :class:`Robot` (the simulator's own, physics-shaped protocol).
:class:`SimRobot` wraps either as the loop's :class:`heapgrasp.robot.interfaces.Robot`:
:class:`SimArm` moves the camera along timed paths capturing with the world's renderer,
:class:`SimGripper` drives the fingers.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.geometry.gripper import PANDA_HAND, GripperGeometry
from heapgrasp.geometry.motion import TimedPath
from heapgrasp.perception.frames import Capture
from heapgrasp.robot.grasping import HandPart
from heapgrasp.robot.interfaces import Contact, UnreachableError
from heapgrasp.sim.arm import PandaArm
from heapgrasp.sim.arm_timing import JointPathError, retime_for_arm
from heapgrasp.sim.world import CameraMount, SimFrame, SimWorld

__all__ = ["Robot", "SimArm", "SimCamera", "SimGripper", "SimRobot"]

FloatArray = npt.NDArray[np.float64]


@runtime_checkable
class Robot(CameraMount, Protocol):
    """A gripper (and camera) in a :class:`~heapgrasp.sim.world.SimWorld`.

    The TCP frame is ``panda_grasptarget``: z = approach direction, fingers close along y.
    """

    world: SimWorld
    tcp: FloatArray
    """Current commanded TCP pose (world)."""

    @property
    def time(self) -> float:
        """The world's simulated clock (s)."""
        ...

    def reset(self, tcp: FloatArray, width: float = ...) -> None:
        """Teleports the TCP to ``tcp`` with the fingers opened to ``width``."""
        ...

    def park(self) -> None:
        """Moves out of the way of the scene (and of the camera's view)."""
        ...

    def step(self, n: int = 1) -> None:
        """Runs ``n`` physics steps."""
        ...

    def move_linear(
        self, target: FloatArray, *, speed: float = ..., abort_on_contact: bool = ...
    ) -> bool:
        """Straight-line TCP motion; False if it stopped on a contact."""
        ...

    def close(self, seconds: float = ..., width: float = ...) -> None:
        """Closes the fingers (force-limited)."""
        ...

    def open(self, seconds: float = ...) -> None:
        """Opens the fingers fully."""
        ...

    def width(self) -> float:
        """Current finger opening (m)."""
        ...

    def contacts(self) -> set[int]:
        """PyBullet ids of the bodies the gripper touches."""
        ...

    def touching_parts(self) -> set[HandPart]:
        """Which parts of the robot touch another body (``"palm"``, ``"finger"``,
        ``"arm"``)."""
        ...

    def held_object(self) -> int | None:
        """World id of the object held between the fingers, if any."""
        ...


@dataclass(frozen=True)
class SimCamera:
    """The simulated hand-eye camera (:class:`heapgrasp.robot.interfaces.Camera`)."""

    spec: CameraSpec = field(default_factory=CameraSpec.continuous)
    depth: bool = False
    """Render sensor depth for every frame (the VGN baseline)."""
    rgb: bool = False
    """Render a colour image for every frame (PyBullet's TinyRenderer, ~30 ms a frame)."""


class SimArm:
    """:class:`heapgrasp.robot.interfaces.Arm` over a simulated hand or arm."""

    def __init__(self, body: Robot, camera: SimCamera | None = None) -> None:
        self.body = body
        self.world = body.world
        self._camera = camera if camera is not None else SimCamera()

    @property
    def camera(self) -> SimCamera:
        """The camera it carries."""
        return self._camera

    @property
    def clock(self) -> float:
        """The world's simulated clock (s)."""
        return self.world.time

    @property
    def tcp(self) -> FloatArray:
        """The TCP pose last commanded."""
        return self.body.tcp

    def park(self) -> None:
        """Moves out of the camera's view."""
        self.body.park()

    def look(self, cam2world: FloatArray) -> SimFrame:
        """Puts the camera at ``cam2world`` (as closely as the body can) and captures."""
        reached = self.body.move_camera(cam2world)
        cam = self._camera
        return self.world.capture(reached, cam.spec, depth=cam.depth, rgb=cam.rgb)

    def follow(self, path: TimedPath) -> Capture:
        """Moves the camera along ``path`` capturing at its rate. The Panda arm first slows
        the path until its joint limits hold (where it cannot, it follows the path at the
        Cartesian timing and :attr:`Capture.timing_kept` is False). An unreachable pose
        raises :class:`~heapgrasp.robot.interfaces.UnreachableError` with the clock and
        the camera back at the path's start."""
        kept = True
        if isinstance(self.body, PandaArm):
            try:
                path = retime_for_arm(path, self.body)
            except JointPathError:
                kept = False
        clock = self.world.time
        try:
            cam = self._camera
            cap = self.world.follow(path, cam.spec, mount=self.body, depth=cam.depth, rgb=cam.rgb)
        except UnreachableError:
            self.world.time = clock
            self.body.move_camera(path.poses[0])
            raise
        cap.timing_kept = kept
        return cap

    def move_to(self, tcp: FloatArray, *, opening: float) -> None:
        """The simulator places the hand at ``tcp`` directly (VGN's simulation) and lets
        the contacts settle for two physics steps."""
        self.body.reset(tcp, opening)
        self.body.step(2)

    def move_linear(
        self, tcp: FloatArray, *, speed: float = 0.1, stop_on_contact: bool = False
    ) -> bool:
        """Straight-line TCP motion in physics."""
        return self.body.move_linear(tcp, speed=speed, abort_on_contact=stop_on_contact)

    def contact(self) -> Contact | None:
        """The bodies and parts touching the robot now, or None."""
        bodies = self.body.contacts()
        if not bodies:
            return None
        return Contact(frozenset(bodies), frozenset(self.body.touching_parts()))


class SimGripper:
    """:class:`heapgrasp.robot.interfaces.Gripper` over the Panda's simulated fingers."""

    geometry: GripperGeometry = PANDA_HAND

    def __init__(self, body: Robot) -> None:
        self.body = body

    def open(self) -> None:
        """Opens fully."""
        self.body.open()

    def close(self, width: float | None = None) -> None:
        """Closes toward ``width`` (None: shut), force-limited."""
        if width is None:
            self.body.close()
        else:
            self.body.close(width=width)

    def holding(self) -> bool:
        """Whether both fingers touch one object."""
        return self.body.held_object() is not None


class SimRobot:
    """A simulated hand or arm as the loop's :class:`heapgrasp.robot.interfaces.Robot`."""

    def __init__(self, body: Robot, camera: SimCamera | None = None) -> None:
        self.body = body
        self.arm = SimArm(body, camera)
        self.gripper = SimGripper(body)
