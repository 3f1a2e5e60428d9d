"""A gripper driver in the simulator: what :class:`heapgrasp.robot.robotiq.Robotiq2F140`
offers the arm and the loop, over the simulator's fingers.

The rehearsal's hand is the simulator's (the Panda hand, 8 cm wide open: the planners
plan for it, :data:`heapgrasp.geometry.gripper.PANDA_HAND`); a Robotiq 2F-140 is not
modelled. :class:`SimRobotiq` connects, activates, moves to a width, closes
force-limited and reports ``holding`` and its status registers as the driver does. An
object released outside the scene cube falls into the bin: it leaves the world, and the
rehearsal counts it as removed.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from heapgrasp.geometry.gripper import PANDA_HAND, GripperGeometry
from heapgrasp.robot.errors import DeviceError

if TYPE_CHECKING:
    from heapgrasp.sim.gripper import PandaHand

__all__ = ["SimRobotiq"]

#: The motion of the fingers to a width, and a full opening or closing (s).
FINGER_TIME_S = 0.4
#: Robotiq's ``OBJ`` codes: at the requested position, stopped on an object.
OBJ_AT_POSITION = 3
OBJ_CONTACT_CLOSING = 2


class SimRobotiq:
    """The rehearsal's gripper driver (see the module docstring)."""

    def __init__(
        self, hand: PandaHand, cube_size: float, on_release: Callable[[int], None]
    ) -> None:
        self.hand = hand
        self.cube_size = cube_size
        self.on_release = on_release
        self.connected = False
        self.active = False
        self._closed = False

    @property
    def geometry(self) -> GripperGeometry:
        """The simulator's hand."""
        return PANDA_HAND

    def _require(self, what: str) -> None:
        if not self.connected:
            raise DeviceError(f"rehearsal gripper: {what} before connect()")
        if not self.active and what != "status":
            raise DeviceError(f"rehearsal gripper: {what} before activate()")

    def connect(self) -> None:
        self.connected = True

    def disconnect(self) -> None:
        self.connected = False

    def activate(self, *, auto_calibrate: bool = True, timeout: float | None = None) -> None:
        """Activates (the fingers open fully)."""
        if not self.connected:
            raise DeviceError("rehearsal gripper: activate() before connect()")
        self.active = True
        self.open()

    def move(
        self,
        width: float,
        *,
        speed: int | None = None,
        force: int | None = None,
        wait: bool = True,
    ) -> int:
        """Moves the fingers to ``width`` (m, at most the hand's widest opening)."""
        self._require("move")
        self._closed = False
        self.hand.close(seconds=FINGER_TIME_S, width=min(max(width, 0.0), PANDA_HAND.max_opening))
        return OBJ_AT_POSITION

    def open(self) -> None:
        """Opens fully; what was held outside the scene cube falls into the bin."""
        self._require("open")
        held = self.hand.held_object() if self._closed else None
        self._closed = False
        self.hand.open(seconds=FINGER_TIME_S)
        x, y = np.asarray(self.hand.tcp)[:2, 3]
        inside = 0.0 <= x <= self.cube_size and 0.0 <= y <= self.cube_size
        if held is not None and not inside:
            self.on_release(held)

    def close(self, width: float | None = None) -> None:
        """Closes toward ``width`` (None: shut), stopping on what the fingers meet."""
        self._require("close")
        self._closed = True
        self.hand.close(seconds=FINGER_TIME_S, width=0.0 if width is None else width)

    def holding(self) -> bool:
        """Whether the fingers, last closed, hold an object."""
        return self._closed and self.hand.held_object() is not None

    def width(self) -> float:
        """The opening now (m)."""
        return float(self.hand.width())

    def status(self) -> dict[str, int]:
        """Robotiq's status registers (``STA`` 3 once activated)."""
        self._require("status")
        obj = OBJ_CONTACT_CLOSING if self.holding() else OBJ_AT_POSITION
        pos = round(255 * (1.0 - self.width() / PANDA_HAND.max_opening)) if self.active else 0
        return {"STA": 3 if self.active else 0, "OBJ": obj, "FLT": 0, "POS": pos, "PRE": pos}
