"""A free-flying Franka Panda hand and VGN-style grasp execution.

The hand is the ``panda_hand`` + fingers of ``pybullet_data/franka_panda/panda.urdf``
(8 cm maximum opening), written as a hand-only URDF next to the object cache, and is
moved by a fixed constraint to a target pose, as VGN's simulation does; this is the
"free-flying gripper" mode of the world, for experiments where arm kinematics are not
the question.

Frames: the **TCP** (tool centre point) frame is ``panda_grasptarget``, 0.105 m along
the hand's z axis from its base: z is the approach direction (out of the palm, toward
the object), the fingers close along y. A grasp is a TCP pose in the world frame plus a
width; :func:`execute_grasp` runs VGN's protocol: pre-grasp 5 cm back along z, approach
along z (abort on contact), close, lift 10 cm, shake, and check the object is held.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import numpy.typing as npt

from heapgrasp.robot.grasping import (
    PREGRASP_DISTANCE,
    CollisionStage,
    Grasp,
    GraspOutcome,
    GraspResult,
    HandPart,
    translate,
)
from heapgrasp.robot.grasping import execute_grasp as robot_execute_grasp
from heapgrasp.sim.bullet import pb
from heapgrasp.sim.hand import (
    FINGER_FRICTION,
    FINGER_JOINT_Z,
    MAX_OPENING,
    PANDA_MESHES,
    TCP_OFFSET,
    Fingers,
)
from heapgrasp.sim.object_model import default_cache_dir
from heapgrasp.sim.poses import split_pose
from heapgrasp.sim.robot import Robot, SimRobot
from heapgrasp.sim.world import SimWorld

__all__ = [
    "MAX_OPENING",
    "CollisionStage",
    "Grasp",
    "GraspOutcome",
    "GraspResult",
    "HandPart",
    "PandaHand",
    "execute_grasp",
]

FloatArray = npt.NDArray[np.float64]

_HAND_URDF = """<?xml version="1.0"?>
<robot name="panda_hand_free">
  <link name="panda_hand">
    <inertial><origin xyz="0 0 0.04"/><mass value="0.81"/>
      <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>
    <visual><geometry><mesh filename="{m}/visual/hand.obj"/></geometry></visual>
    <collision><geometry><mesh filename="{m}/collision/hand.obj"/></geometry></collision>
  </link>
  <link name="panda_leftfinger">
    <contact><friction_anchor/><stiffness value="30000.0"/><damping value="1000.0"/>
      <spinning_friction value="0.1"/><lateral_friction value="1.0"/></contact>
    <inertial><origin xyz="0 0.01 0.02"/><mass value="0.1"/>
      <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>
    <visual><geometry><mesh filename="{m}/visual/finger.obj"/></geometry></visual>
    <collision><geometry><mesh filename="{m}/collision/finger.obj"/></geometry></collision>
  </link>
  <link name="panda_rightfinger">
    <contact><friction_anchor/><stiffness value="30000.0"/><damping value="1000.0"/>
      <spinning_friction value="0.1"/><lateral_friction value="1.0"/></contact>
    <inertial><origin xyz="0 -0.01 0.02"/><mass value="0.1"/>
      <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>
    <visual><origin rpy="0 0 3.14159265359"/>
      <geometry><mesh filename="{m}/visual/finger.obj"/></geometry></visual>
    <collision><origin rpy="0 0 3.14159265359"/>
      <geometry><mesh filename="{m}/collision/finger.obj"/></geometry></collision>
  </link>
  <joint name="panda_finger_joint1" type="prismatic">
    <parent link="panda_hand"/><child link="panda_leftfinger"/>
    <origin xyz="0 0 {j}"/><axis xyz="0 1 0"/>
    <limit effort="20" lower="0.0" upper="0.04" velocity="0.2"/>
  </joint>
  <joint name="panda_finger_joint2" type="prismatic">
    <parent link="panda_hand"/><child link="panda_rightfinger"/>
    <origin xyz="0 0 {j}"/><axis xyz="0 -1 0"/>
    <limit effort="20" lower="0.0" upper="0.04" velocity="0.2"/>
  </joint>
</robot>
"""


def hand_urdf(cache_dir: Path | None = None) -> Path:
    """Writes (once) and returns the hand-only URDF."""
    root = (cache_dir or default_cache_dir()) / "robots"
    root.mkdir(parents=True, exist_ok=True)
    path = root / "panda_hand_free.urdf"
    text = _HAND_URDF.format(m=PANDA_MESHES.as_posix(), j=FINGER_JOINT_Z)
    if not path.exists() or path.read_text() != text:
        path.write_text(text)
    return path


class PandaHand(Fingers):
    """The free-flying Panda hand in a :class:`SimWorld`."""

    finger_joints = (0, 1)
    finger_force = 40.0

    def __init__(self, world: SimWorld, *, max_force: float = 300.0) -> None:
        self.world = world
        self.client = world.client
        self.max_force = max_force
        self.body = pb.loadURDF(str(hand_urdf()), useFixedBase=False, physicsClientId=self.client)
        # PyBullet places a body by its base's inertial frame, not its link frame.
        inertial = pb.getDynamicsInfo(self.body, -1, physicsClientId=self.client)[3]
        self.tcp2body = translate(0.0, 0.0, -TCP_OFFSET) @ translate(*inertial)
        for joint in (0, 1):
            pb.changeDynamics(
                self.body, joint, lateralFriction=FINGER_FRICTION, physicsClientId=self.client
            )
        # Fingers mirror each other (the URDF's mimic joint, as a gear constraint).
        gear = pb.createConstraint(
            self.body,
            0,
            self.body,
            1,
            pb.JOINT_GEAR,
            [1, 0, 0],
            [0, 0, 0],
            [0, 0, 0],
            physicsClientId=self.client,
        )
        pb.changeConstraint(gear, gearRatio=-1, erp=0.1, maxForce=50, physicsClientId=self.client)
        self.constraint = pb.createConstraint(
            self.body,
            -1,
            -1,
            -1,
            pb.JOINT_FIXED,
            [0, 0, 0],
            [0, 0, 0],
            [0, 0, 0],
            physicsClientId=self.client,
        )
        self.tcp = np.eye(4)
        self.park()

    @property
    def time(self) -> float:
        """The world's simulated clock (s)."""
        return self.world.time

    # ---------------------------------------------------------------- kinematics
    def _body_pose(self, tcp: FloatArray) -> tuple[list[float], list[float]]:
        return split_pose(tcp @ self.tcp2body)

    def reset(self, tcp: FloatArray, width: float = MAX_OPENING) -> None:
        """Teleports the hand so its TCP is at ``tcp``, fingers at ``width``."""
        pos, quat = self._body_pose(tcp)
        pb.resetBasePositionAndOrientation(self.body, pos, quat, physicsClientId=self.client)
        pb.changeConstraint(
            self.constraint, pos, quat, maxForce=self.max_force, physicsClientId=self.client
        )
        for joint in (0, 1):
            pb.resetJointState(self.body, joint, 0.5 * width, physicsClientId=self.client)
        self._finger_targets(width)
        self.tcp = np.array(tcp, dtype=np.float64)

    def park(self) -> None:
        """Moves the hand out of the way, high above the table."""
        self.reset(translate(-0.5, -0.5, 1.0))

    def step(self, n: int = 1) -> None:
        """Runs ``n`` physics steps (advancing the world's clock)."""
        self.world.step_physics(n)

    def move_camera(self, cam2world: FloatArray) -> FloatArray:
        """The free-flying mode's camera is not attached to the hand (as in VGN's
        simulation): it is exactly where asked."""
        return np.asarray(cam2world, dtype=np.float64)

    def contacts(self) -> set[int]:
        """Bodies the hand touches (PyBullet ids)."""
        pts = pb.getContactPoints(bodyA=self.body, physicsClientId=self.client)
        return {int(p[2]) for p in pts if p[2] != self.body}

    def touching_parts(self) -> set[HandPart]:
        """The parts of the hand touching another body: ``"palm"`` (the hand's base
        link) and ``"finger"``."""
        pts = pb.getContactPoints(bodyA=self.body, physicsClientId=self.client)
        return {"palm" if p[3] == -1 else "finger" for p in pts if p[2] != self.body}

    def servo(self, tcp: FloatArray) -> None:
        """Sets the hand's target pose to ``tcp`` without stepping: the fixed constraint
        pulls the hand there over the next physics steps (a streamed motion's setpoint)."""
        pos, quat = self._body_pose(np.asarray(tcp, dtype=np.float64))
        pb.changeConstraint(
            self.constraint, pos, quat, maxForce=self.max_force, physicsClientId=self.client
        )
        self.tcp = np.array(tcp, dtype=np.float64)

    def move_linear(
        self, target: FloatArray, *, speed: float = 0.1, abort_on_contact: bool = False
    ) -> bool:
        """Moves the TCP in a straight line to ``target`` at ``speed`` m/s (orientation
        slerped). Returns False if it stopped on a contact."""
        start = self.tcp.copy()
        dist = float(np.linalg.norm(target[:3, 3] - start[:3, 3]))
        dt = self.world.config.time_step
        steps = max(1, math.ceil(dist / speed / dt))
        from scipy.spatial.transform import Rotation, Slerp

        slerp = Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([start[:3, :3], target[:3, :3]])))
        for k in range(1, steps + 1):
            s = k / steps
            pose = np.eye(4)
            pose[:3, :3] = slerp([s]).as_matrix()[0]
            pose[:3, 3] = (1 - s) * start[:3, 3] + s * target[:3, 3]
            pos, quat = self._body_pose(pose)
            pb.changeConstraint(
                self.constraint, pos, quat, maxForce=self.max_force, physicsClientId=self.client
            )
            self.step()
            self.tcp = pose
            if abort_on_contact and self.contacts():
                return False
        self.step(int(0.1 / dt))  # let the constraint catch up
        return True


def execute_grasp(
    hand: Robot,
    grasp: Grasp,
    *,
    pregrasp_distance: float = PREGRASP_DISTANCE,
    lift_height: float = 0.10,
    shake: bool = True,
) -> GraspResult:
    """Runs one grasp attempt with a simulated hand or arm
    (:func:`heapgrasp.robot.grasping.execute_grasp`, VGN's protocol) and names the object
    held after lifting (:attr:`GraspResult.object_id`)."""
    result = robot_execute_grasp(
        SimRobot(hand),
        grasp,
        pregrasp_distance=pregrasp_distance,
        lift_height=lift_height,
        shake=shake,
    )
    if result.outcome in (GraspOutcome.SUCCESS, GraspOutcome.EMPTY):
        return dataclasses.replace(result, object_id=hand.held_object())
    return result
