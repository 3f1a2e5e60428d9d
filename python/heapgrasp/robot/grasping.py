"""A grasp and how any robot executes it: VGN's sequence, built from the robot seam.

:func:`execute_grasp`: the TCP goes to the pre-grasp pose (``pregrasp_distance`` back
along the grasp's z) with the fingers opened to the grasp's width plus 1 cm; touching
anything there, or on the straight approach along z to the grasp pose (stopping on
contact), is a collision. It then closes, lifts by ``lift_height`` along world z,
optionally shakes (±20° about the approach axis), and succeeds if the gripper still
holds something. :func:`place` carries what is held to a place pose and releases it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum
from typing import Literal

import numpy as np
import numpy.typing as npt

from heapgrasp.robot.interfaces import Contact, Robot, UnreachableError

__all__ = [
    "BIN_POSE",
    "PREGRASP_DISTANCE",
    "CollisionStage",
    "Grasp",
    "GraspOutcome",
    "GraspResult",
    "HandPart",
    "execute_grasp",
    "place",
    "translate",
]

F64 = npt.NDArray[np.float64]

#: TCP pose above the bin (beside the workspace, -y side), pointing down.
BIN_POSE = np.array(
    [[1.0, 0.0, 0.0, 0.15], [0.0, -1.0, 0.0, -0.25], [0.0, 0.0, -1.0, 0.25], [0.0, 0.0, 0.0, 1.0]]
)


#: How far back along the grasp's z the pre-grasp pose is (m; VGN's 5 cm).
PREGRASP_DISTANCE = 0.05


def translate(x: float, y: float, z: float) -> F64:
    """A pure translation as a (4, 4) matrix."""
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


@dataclass(frozen=True)
class Grasp:
    """A grasp: TCP pose in the world frame (z = approach direction) and opening width."""

    pose: F64
    width: float

    def __post_init__(self) -> None:
        pose = np.asarray(self.pose, dtype=np.float64)
        if pose.shape != (4, 4) or not np.isfinite(pose).all():
            raise ValueError(f"Grasp.pose must be a finite (4, 4) matrix, got shape {pose.shape}")
        r = pose[:3, :3]
        if np.abs(r.T @ r - np.eye(3)).max() > 1e-6 or np.linalg.det(r) < 0:
            raise ValueError("Grasp.pose must be a rigid transform")
        if not (math.isfinite(self.width) and self.width >= 0.0):
            raise ValueError(f"Grasp.width must be finite and >= 0 m, got {self.width}")
        object.__setattr__(self, "pose", pose)


class GraspOutcome(StrEnum):
    """How a grasp attempt ended."""

    SUCCESS = "success"
    COLLISION = "collision"
    """The hand touched something at the pre-grasp pose or while approaching."""
    EMPTY = "empty"
    """The fingers closed on nothing, or dropped the object while lifting or shaking."""
    UNREACHABLE = "unreachable"
    """The arm cannot reach the pre-grasp or grasp pose."""


CollisionStage = Literal["pregrasp", "approach"]
"""Where a grasp attempt touched something (:attr:`GraspResult.stage`)."""

HandPart = Literal["palm", "finger", "arm"]
"""Which part of the robot touched something (:attr:`GraspResult.parts`): the hand's
body (``"palm"``), a finger, or a link of the arm above the hand."""


@dataclass(frozen=True)
class GraspResult:
    """Outcome of :func:`execute_grasp`."""

    outcome: GraspOutcome
    object_id: int | None
    """The object held after lifting, where the scene truth tells (simulation); else None."""
    duration: float
    """Time of the whole attempt on the robot's clock (s)."""
    touched: frozenset[int] = frozenset()
    """For a collision: what the hand touched when it stopped (:attr:`Contact.bodies`)."""
    stage: CollisionStage | None = None
    """For a collision: ``"pregrasp"`` (touching at the pre-grasp pose) or
    ``"approach"`` (on the way from there to the grasp pose)."""
    parts: frozenset[str] = frozenset()
    """For a collision: the parts of the robot that touched (:attr:`Contact.parts`)."""

    @property
    def success(self) -> bool:
        """Whether an object was held after lifting and shaking."""
        return self.outcome == GraspOutcome.SUCCESS


def _collision(robot: Robot, t0: float, stage: CollisionStage, contact: Contact) -> GraspResult:
    robot.arm.park()
    return GraspResult(
        GraspOutcome.COLLISION,
        None,
        robot.arm.clock - t0,
        contact.bodies,
        stage,
        contact.parts,
    )


def execute_grasp(
    robot: Robot,
    grasp: Grasp,
    *,
    pregrasp_distance: float = PREGRASP_DISTANCE,
    lift_height: float = 0.10,
    shake: bool = True,
) -> GraspResult:
    """Runs one grasp attempt (VGN's protocol, see the module docstring) and returns its
    outcome; ``object_id`` is left None (the scene truth fills it in simulation)."""
    arm, gripper = robot.arm, robot.gripper
    t0 = arm.clock
    pre = grasp.pose @ translate(0.0, 0.0, -pregrasp_distance)
    try:
        arm.move_to(pre, opening=min(gripper.geometry.max_opening, grasp.width + 0.01))
    except UnreachableError:  # an attempt that fails
        arm.park()
        return GraspResult(GraspOutcome.UNREACHABLE, None, arm.clock - t0)
    if (touching := arm.contact()) is not None:
        return _collision(robot, t0, "pregrasp", touching)
    if not arm.move_linear(grasp.pose, stop_on_contact=True):
        return _collision(robot, t0, "approach", arm.contact() or Contact())
    gripper.close()
    lift = translate(0.0, 0.0, lift_height) @ grasp.pose
    arm.move_linear(lift, speed=0.2)
    if shake and gripper.holding():
        for angle in (0.35, -0.35, 0.0):
            c, s = math.cos(angle), math.sin(angle)
            turn = np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])
            arm.move_linear(lift @ turn, speed=0.5)
    outcome = GraspOutcome.SUCCESS if gripper.holding() else GraspOutcome.EMPTY
    return GraspResult(outcome, None, arm.clock - t0)


def place(
    robot: Robot,
    pose: F64 = BIN_POSE,
    *,
    released: Callable[[], None] | None = None,
) -> float:
    """Carries what the gripper holds up and over to ``pose`` (TCP), opens, calls
    ``released`` (the simulator takes the object out of the scene there) and parks.
    Returns the time it took (s)."""
    arm = robot.arm
    t0 = arm.clock
    up = np.array(arm.tcp, dtype=np.float64)
    up[2, 3] = max(up[2, 3], pose[2, 3])
    arm.move_linear(up, speed=0.5)
    arm.move_linear(pose, speed=0.5)
    robot.gripper.open()
    if released is not None:
        released()
    arm.park()
    return arm.clock - t0
