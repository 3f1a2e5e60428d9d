"""What the closed loop needs from a robot (and, in simulation only, from the scene).

A robot is an :class:`Arm` carrying a hand-eye :class:`Camera` and a :class:`Gripper`.
The loop moves the camera along timed paths and gets back what the camera captured on
the way (:meth:`Arm.follow`), and grasps through :func:`heapgrasp.robot.grasping.
execute_grasp`, which uses nothing but these protocols. The simulator implements them
(:class:`heapgrasp.sim.robot.SimRobot`); a hardware driver implements the same ones.

:class:`SceneTruth` is what only a simulator knows — the true meshes (for the oracle view
scorer), the exact silhouettes (for the ideal and noisy segmenters) and which object a
grasp took (for the metrics). Everything that reads it is optional: on a real robot the
loop runs without it.

Frames: poses are ``(4, 4)`` world-frame rigid transforms (README "Poses"); the TCP
frame has z along the approach and the fingers closing along y.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from heapgrasp import HeapgraspError, MeshScene
from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.geometry.gripper import GripperGeometry
from heapgrasp.geometry.motion import TimedPath
from heapgrasp.perception.frames import Capture, Frame
from heapgrasp.perception.segmenters import MaskSource

__all__ = [
    "Arm",
    "Camera",
    "Contact",
    "Gripper",
    "Robot",
    "SceneTruth",
    "UnreachableError",
]

F64 = npt.NDArray[np.float64]


class UnreachableError(HeapgraspError):
    """A pose the arm cannot reach (a ``ValueError``). A method that raises it leaves the
    arm where it was."""


@dataclass(frozen=True)
class Contact:
    """What the robot touched when a motion stopped on contact."""

    bodies: frozenset[int] = frozenset()
    """What was touched, in the robot's own ids (the simulator's body ids; empty where
    the robot cannot tell)."""
    parts: frozenset[str] = frozenset()
    """Which parts of the robot touched: ``"palm"``, ``"finger"``, ``"arm"``."""


@runtime_checkable
class Camera(Protocol):
    """The hand-eye camera."""

    @property
    def spec(self) -> CameraSpec:
        """Intrinsics and image size."""
        ...

    @property
    def depth(self) -> bool:
        """Whether its frames carry depth (the VGN baseline's camera)."""
        ...


@runtime_checkable
class Arm(Protocol):
    """An arm carrying the hand-eye camera and the gripper."""

    @property
    def camera(self) -> Camera:
        """The camera it carries."""
        ...

    @property
    def clock(self) -> float:
        """The robot's clock (s): frames and motions are timed on it."""
        ...

    @property
    def tcp(self) -> F64:
        """The TCP pose last commanded (world)."""
        ...

    def park(self) -> None:
        """Moves out of the camera's view of the scene."""
        ...

    def look(self, cam2world: F64) -> Frame:
        """Moves the camera to ``cam2world`` and captures one frame there, at rest."""
        ...

    def follow(self, path: TimedPath) -> Capture:
        """Moves the camera along ``path`` (``cam2world`` poses), capturing continuously
        at the camera's rate; raises :class:`UnreachableError` (the arm back where it was)
        if the path leaves its reach."""
        ...

    def move_to(self, tcp: F64, *, opening: float) -> None:
        """Brings the TCP to ``tcp`` through free space with the fingers opened to
        ``opening`` (m): the pre-grasp pose. Raises :class:`UnreachableError`."""
        ...

    def move_linear(self, tcp: F64, *, speed: float = 0.1, stop_on_contact: bool = False) -> bool:
        """Moves the TCP in a straight line to ``tcp`` at ``speed`` (m/s); with
        ``stop_on_contact``, returns False where it stopped on a contact."""
        ...

    def contact(self) -> Contact | None:
        """What the robot touches now, or None."""
        ...


@runtime_checkable
class Gripper(Protocol):
    """A parallel-jaw gripper."""

    @property
    def geometry(self) -> GripperGeometry:
        """Its shape, widest opening and finger depth (one description for planners and
        execution)."""
        ...

    def open(self) -> None:
        """Opens fully."""
        ...

    def close(self, width: float | None = None) -> None:
        """Closes to ``width`` (m), or with None until the fingers meet something
        (force-limited) or shut."""
        ...

    def holding(self) -> bool:
        """Whether something is held between the fingers."""
        ...


@runtime_checkable
class Robot(Protocol):
    """An arm with its camera and gripper."""

    @property
    def arm(self) -> Arm: ...

    @property
    def gripper(self) -> Gripper: ...


@runtime_checkable
class SceneTruth(MaskSource, Protocol):
    """What only a simulator knows about the scene (optional everywhere)."""

    def meshes(self) -> MeshScene:
        """The true meshes at their current poses (the oracle view scorer's input)."""
        ...

    def objects_left(self) -> int:
        """How many objects are still in the scene."""
        ...

    def object_near(self, point: F64, within: float = 0.03) -> int | None:
        """The object whose surface comes nearest ``point`` (within ``within`` m)."""
        ...

    def held_object(self) -> int | None:
        """The object the gripper holds now, if any."""
        ...

    def category(self, object_id: int | None) -> str | None:
        """The object's material category (``transparent``, ``specular``, ``opaque``)."""
        ...

    def touched(self, contact: Contact, target: int | None) -> list[str]:
        """What a contact touched, by name: ``"table"``, ``"target"`` (``target``),
        ``"object"`` or ``"other"``; sorted, without repeats."""
        ...

    def placed(self, object_id: int) -> None:
        """The object was released over the bin and has left the scene."""
        ...

    def settle(self) -> dict[int, str | None]:
        """Lets the scene come to rest after a grasp attempt and takes out of it the
        objects that ended outside the workspace (VGN's protocol); returns those objects'
        categories by id ("knocked out": they count neither as removed nor as left)."""
        ...
