"""What carries the hand-eye camera and the gripper: one interface, two embodiments.

* :class:`heapgrasp.sim.gripper.PandaHand` — a free-flying Panda hand and a free camera
  (VGN's simulation): fast, for experiments where arm kinematics are not the question;
* :class:`heapgrasp.sim.arm.PandaArm` — the Franka Panda arm of ``pybullet_data`` with the
  camera on its hand (configurable hand-to-camera extrinsic), moved by inverse kinematics
  within its joint limits.

Both satisfy :class:`Robot`, so grasp execution (:func:`heapgrasp.sim.gripper.execute_grasp`),
the clutter-removal protocol and camera motion (:meth:`heapgrasp.sim.world.SimWorld.follow`)
work with either.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from heapgrasp.sim.gripper import HandPart
    from heapgrasp.sim.world import SimWorld

__all__ = ["CameraMount", "Robot"]

FloatArray = npt.NDArray[np.float64]


@runtime_checkable
class CameraMount(Protocol):
    """Something that can place the hand-eye camera."""

    def move_camera(self, cam2world: FloatArray) -> FloatArray:
        """Moves so the camera is at ``cam2world`` (OpenCV axes) as closely as it can;
        returns the ``cam2world`` actually reached."""
        ...


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

    def close(self, seconds: float = ...) -> None:
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
