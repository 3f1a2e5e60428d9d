"""The Franka Panda hand as both simulated robots carry it: its dimensions, its meshes and
its two fingers.

The free-flying hand (:class:`heapgrasp.sim.gripper.PandaHand`) and the arm
(:class:`heapgrasp.sim.arm.PandaArm`) load a body whose two prismatic finger joints are
coupled; everything the grasp protocol asks of the fingers (open, close force-limited,
read the opening, tell which object both fingers hold) depends only on that body, its
finger joints and the world, so it lives here once. A class mixing :class:`Fingers` in
sets ``world``, ``client``, ``body``, ``finger_joints`` and ``finger_force``, and provides
``step``. The hand's dimensions are shared with the grasp labeller
(:mod:`heapgrasp.sim.grasp_labels`).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import pybullet_data

from heapgrasp.geometry.gripper import PANDA_HAND
from heapgrasp.sim.bullet import pb
from heapgrasp.sim.world import SimWorld

__all__ = [
    "FINGER_FRICTION",
    "FINGER_JOINT_Z",
    "MAX_OPENING",
    "MIN_HELD_WIDTH",
    "PANDA_MESHES",
    "TCP_OFFSET",
    "Fingers",
]

#: Maximum opening of the Panda hand (m): :data:`heapgrasp.geometry.gripper.PANDA_HAND`.
MAX_OPENING = PANDA_HAND.max_opening

#: Lateral friction of the finger links (PyBullet multiplies it by the object's).
FINGER_FRICTION = 1.0

#: Below this opening (m) the fingers count as shut, holding nothing (VGN's 10 % of the
#: widest opening, here of each finger's travel).
MIN_HELD_WIDTH = 0.1 * MAX_OPENING * 0.5

#: Distance from the hand base to the TCP along z, metres.
TCP_OFFSET = 0.105

#: Distance from the hand base to the finger joints along z, metres.
FINGER_JOINT_Z = 0.0584

#: The Panda meshes of ``pybullet_data`` (``visual/`` and ``collision/``).
PANDA_MESHES = Path(pybullet_data.getDataPath()) / "franka_panda" / "meshes"


class Fingers:
    """Finger control and grasp checks for a body with two coupled finger joints."""

    world: SimWorld
    client: int
    body: int
    finger_joints: Sequence[int]
    """The two finger joint (and link) indices of ``body``."""
    finger_force: float
    """Force limit of each finger's position motor (N)."""

    if TYPE_CHECKING:

        def step(self, n: int = 1) -> None:
            """Runs ``n`` physics steps (the robot's own)."""

    def _finger_targets(self, width: float) -> None:
        for joint in self.finger_joints:
            pb.setJointMotorControl2(
                self.body,
                joint,
                pb.POSITION_CONTROL,
                targetPosition=0.5 * width,
                force=self.finger_force,
                physicsClientId=self.client,
            )

    def width(self) -> float:
        """Current finger opening (m)."""
        states = pb.getJointStates(self.body, list(self.finger_joints), physicsClientId=self.client)
        return float(sum(s[0] for s in states))

    def close(self, seconds: float = 0.5, width: float = 0.0) -> None:
        """Closes the fingers toward ``width`` (m; 0: shut), force-limited: they stop on
        whatever they meet."""
        self._finger_targets(width)
        self.step(int(seconds / self.world.config.time_step))

    def open(self, seconds: float = 0.3) -> None:
        """Opens the fingers fully."""
        self._finger_targets(MAX_OPENING)
        self.step(int(seconds / self.world.config.time_step))

    def finger_contacts(self) -> tuple[set[int], set[int]]:
        """Bodies touched by the left and by the right finger."""
        out = []
        for link in self.finger_joints:
            pts = pb.getContactPoints(bodyA=self.body, linkIndexA=link, physicsClientId=self.client)
            out.append({int(p[2]) for p in pts if p[2] != self.body})
        return out[0], out[1]

    def held_object(self) -> int | None:
        """World id of the object both fingers touch, if the fingers are not shut."""
        if self.width() < MIN_HELD_WIDTH:
            return None
        left, right = self.finger_contacts()
        both = left & right
        for oid, obj in self.world.objects.items():
            if obj.body in both:
                return oid
        return None
