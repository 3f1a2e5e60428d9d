"""The Franka Emika Panda arm with a wrist camera: the "arm" mode of the simulation.

:class:`PandaArm` loads the real ``pybullet_data/franka_panda/panda.urdf`` (7 revolute arm
joints, the Panda hand, two finger joints and the ``panda_grasptarget`` TCP link) on a
fixed base beside the workspace, and satisfies :class:`heapgrasp.sim.robot.Robot`, so
:func:`heapgrasp.sim.gripper.execute_grasp`, the clutter-removal protocol and
:meth:`heapgrasp.sim.world.SimWorld.follow` work with it unchanged.

Frames and conventions (metres, radians, seconds; poses are ``(4, 4)`` rigid matrices):

* **TCP** = ``panda_grasptarget``, 0.105 m along the hand's z axis (as the free-flying
  :class:`~heapgrasp.sim.gripper.PandaHand`): z = approach direction, fingers close
  along y.
* **camera**: a wrist camera rigidly fixed to ``panda_hand``; :attr:`ArmConfig.hand2camera`
  is its pose in the hand frame (OpenCV axes: x right, y down, z forward). The default
  (:func:`default_hand2camera`) sits on the hand's +x face, 6.5 cm off the hand axis and
  4 cm above the flange, looking along the approach direction, with the hand toward the
  top of its image.
* **base**: :attr:`ArmConfig.base_position` / :attr:`ArmConfig.base_yaw` place the arm's
  ``panda_link0`` frame in the world frame (the scene cube spans ``[0, 0.3]^3``, the table
  top is z = 0). The default, 0.24 m behind the cube's x = 0 face on its centre line and
  facing +x, reaches every Table I view candidate, top-down grasps anywhere in the cube
  and the bin pose (see :class:`ArmConfig`).

Kinematics: inverse kinematics uses ``pybullet.calculateInverseKinematics``: one
null-space solve (joint limits, rest pose = the seed, which keeps consecutive solutions
close) followed by plain damped-least-squares refinements, each solution brought into the
joint limits and written with ``resetJointState`` until the forward-kinematics error (of
the TCP, or of the camera for camera targets) is within
:attr:`ArmConfig.ik_position_tolerance` and :attr:`ArmConfig.ik_angle_tolerance`. Fixed
seeds around the rest pose, then reproducible random seeds, are tried when the first seed
fails; a target that none reaches raises :class:`UnreachableError` (a ``ValueError``)
with the position and angle errors of the best solution. Scratch IK never disturbs the
simulated arm: its joint state is restored afterwards.

Motion: :meth:`PandaArm.reset`, :meth:`PandaArm.park` and :meth:`PandaArm.move_camera`
are kinematic (the joints are set, no physics step, no simulated time), like the free
hand's teleports and :meth:`~heapgrasp.sim.world.SimWorld.follow` (which accounts the
time of a camera path itself); :meth:`PandaArm.move_linear` is physical: the straight TCP
line is converted to joint positions by IK and tracked by force-limited joint position
control, one target per physics step, so the arm pushes objects and stops on contact.
Successive camera poses are solved from the previous configuration, so a camera path
gives a continuous joint path unless a joint limit forces a re-configuration (counted in
:attr:`PandaArm.reconfigurations`). Look-at view paths spin the camera about its optical
axis near the view sphere's pole, which the wrist's range cannot always follow;
``ArmConfig(camera_roll="free")`` lets the arm choose that roll (the images see the same
scene, rotated, and frames carry the pose actually reached).

Timing: :func:`retime_for_arm` slows a Cartesian :class:`~heapgrasp.geometry.motion.TimedPath`
until the Panda's joint velocity, acceleration and jerk limits (datasheet values in
:class:`ArmConfig`) hold along it, as measured by :func:`joint_profile` (IK at the path's
samples, a cubic spline in arc length, and the path's timing); a path that needs a
re-configuration raises :class:`JointPathError`.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
import numpy.typing as npt
import pybullet_data

from heapgrasp import HeapgraspError
from heapgrasp.geometry.motion import MotionLimits, TimedPath
from heapgrasp.robot.grasping import HandPart, translate
from heapgrasp.robot.interfaces import UnreachableError as RobotUnreachableError
from heapgrasp.sim.bullet import pb
from heapgrasp.sim.fingers import FINGER_FRICTION, MAX_OPENING, Fingers
from heapgrasp.sim.gripper import TCP_OFFSET
from heapgrasp.sim.world import SimWorld, _pose, _split_pose

__all__ = [
    "PANDA_LOWER",
    "PANDA_MAX_ACCELERATION",
    "PANDA_MAX_JERK",
    "PANDA_MAX_TORQUE",
    "PANDA_MAX_VELOCITY",
    "PANDA_PARK",
    "PANDA_READY",
    "PANDA_UPPER",
    "ArmConfig",
    "JointPathError",
    "JointProfile",
    "PandaArm",
    "UnreachableError",
    "default_hand2camera",
    "joint_profile",
    "retime_for_arm",
]

FloatArray = npt.NDArray[np.float64]
Joints = tuple[float, float, float, float, float, float, float]

#: Joint position limits of the Panda (datasheet, rad); slightly inside the URDF's.
PANDA_LOWER: Joints = (-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973)
PANDA_UPPER: Joints = (2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973)
#: Joint velocity limits (datasheet, rad/s).
PANDA_MAX_VELOCITY: Joints = (2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61)
#: Joint acceleration limits (datasheet, rad/s^2).
PANDA_MAX_ACCELERATION: Joints = (15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0)
#: Joint jerk limits (datasheet, rad/s^3).
PANDA_MAX_JERK: Joints = (7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0)
#: Joint torque limits (datasheet, N m): the force limits of the position controllers.
PANDA_MAX_TORQUE: Joints = (87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0)
#: Franka's "ready" configuration: hand pointing down, 0.3 m in front of the base.
PANDA_READY: Joints = (0.0, -math.pi / 4, 0.0, -3 * math.pi / 4, 0.0, math.pi / 2, math.pi / 4)
#: Parking configuration: folded and turned to the base's left (+y with the default
#: placement), the hand 0.38 m above the table and 0.24 m outside the scene cube.
PANDA_PARK: Joints = (math.pi / 2, -1.7, 0.0, -3.0, 0.0, 1.6, math.pi / 4)

_ARM_JOINTS = tuple(f"panda_joint{i}" for i in range(1, 8))
_FINGER_JOINTS = ("panda_finger_joint1", "panda_finger_joint2")
#: Lever arm (m) converting an angle error into a distance when ranking IK solutions.
_LEVER = 0.1
#: Offsets of joint 1 and joint 7 added to the rest pose to make the fallback IK seeds.
_SEED_J1 = (0.0, 0.6, -0.6)
_SEED_J7 = (0.0, -math.pi, 0.7 * math.pi, -0.5 * math.pi, 0.5 * math.pi)
#: Upper bound on the shoulder (joint 2) to TCP distance of the Panda (m): upper arm
#: 0.327, forearm 0.393, wrist to flange 0.139, flange to TCP 0.105, plus a margin.
_MAX_TCP_REACH = 0.98


def default_hand2camera() -> FloatArray:
    """The default wrist-camera extrinsic: camera pose in the ``panda_hand`` frame.

    Returns
    -------
    numpy.ndarray, shape (4, 4)
        Optical centre at ``(0.065, 0, 0.04)`` m: on the hand's +x face (the housing
        spans ``|x| <= 0.032``, the fingers travel along y), 6.5 cm off the hand axis and
        4 cm above the flange, like a RealSense on a flange adapter. Camera z = hand z
        (looking along the approach direction), camera x = -hand y (the sensor's long
        side along the fingers' travel), camera y = hand x: the hand is toward the top
        of the image and the TCP, 6.5 cm ahead of the camera, projects above the image
        centre. With look-at views (image up = world up), this keeps the hand above the
        camera, which is what lets the arm reach the far side of the view sphere.
    """
    m = translate(0.065, 0.0, 0.04)
    m[:3, :3] = [[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    return m


def _joints(name: str, value: Sequence[float], *, positive: bool = False) -> Joints:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be 7 numbers, got {value!r}") from None
    if arr.shape != (7,):
        raise ValueError(f"{name} must have 7 values (one per arm joint), got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} must be finite, got {arr.tolist()}")
    if positive and not (arr > 0).all():
        raise ValueError(f"{name} must be > 0, got {arr.tolist()}")
    a = [float(x) for x in arr]
    return (a[0], a[1], a[2], a[3], a[4], a[5], a[6])


def _finite(name: str, value: object, *, positive: bool = False) -> float:
    try:
        v = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(v) or (positive and not v > 0):
        raise ValueError(f"{name} must be finite{' and > 0' if positive else ''}, got {value!r}")
    return v


def _rigid(name: str, value: npt.ArrayLike) -> FloatArray:
    m = np.array(value, dtype=np.float64)
    if m.shape != (4, 4) or not np.isfinite(m).all():
        raise ValueError(f"{name} must be a finite (4, 4) matrix, got shape {m.shape}")
    r = m[:3, :3]
    ortho = float(np.abs(r.T @ r - np.eye(3)).max())
    if (
        ortho > 1e-6
        or abs(float(np.linalg.det(r)) - 1.0) > 1e-6
        or not np.array_equal(m[3], [0.0, 0.0, 0.0, 1.0])
    ):
        raise ValueError(
            f"{name} must be a rigid transform (orthonormal rotation, det +1, last row "
            f"[0, 0, 0, 1]); got orthogonality error {ortho:.3g}, det "
            f"{float(np.linalg.det(r)):.6g}, last row {m[3].tolist()}"
        )
    return m


@dataclass(frozen=True, eq=False)
class ArmConfig:
    """Placement, camera extrinsic, limits and IK settings of :class:`PandaArm`.

    The default base placement, ``(-0.24, 0.15, 0)`` facing +x (0.24 m behind the scene
    cube's x = 0 face, on its centre line), reaches with the default camera and IK
    settings: every one of the 761 distinct Table I view candidates
    (``ViewSphere.for_cube((0, 0, 0), 0.30, radius=0.33).candidates(40, 20, pi / 5)``)
    and the ``circle_waypoints`` ring at ``theta = pi / 5``; top-down grasps over the
    whole cube (x, y in [0, 0.3], z in [0.01, 0.2], every yaw); and ``protocol.BIN_POSE``
    (``tests/test_sim_arm.py`` checks all candidates, a grasp grid and the bin). Of the
    GraspNeRF hemisphere (radius 0.5 about the cube centre, ``theta = pi / 6``) it misses
    the far side, azimuths within about 25° of +x: farther than the arm stretches. A base
    much closer to the cube loses grasps near its x = 0 face.

    Configurations compare by identity (the extrinsic is an array).

    Parameters
    ----------
    base_position
        World position of the ``panda_link0`` frame (m); the base stands on the table
        (z = 0).
    base_yaw
        Rotation of the base about world z (rad); 0 = the arm faces world +x.
    hand2camera
        ``(4, 4)`` rigid pose of the camera (OpenCV axes) in the ``panda_hand`` frame;
        default :func:`default_hand2camera`.
    joint_lower, joint_upper
        Joint position limits (rad), 7 values each; default the datasheet's.
    max_velocity, max_acceleration, max_jerk
        Joint limits used by :func:`retime_for_arm` and :meth:`PandaArm.move_linear`
        (rad/s, rad/s^2, rad/s^3); default the datasheet's.
    max_torque
        Force limits of the joint position controllers (N m); default the datasheet's.
    rest_pose
        Configuration the IK's null space is pulled toward when seeding from scratch
        (rad); default :data:`PANDA_READY`.
    park_pose
        Configuration of :meth:`PandaArm.park` (rad); default :data:`PANDA_PARK`.
    ik_position_tolerance
        Largest accepted TCP / camera position error of an IK solution (m).
    ik_angle_tolerance
        Largest accepted orientation error of an IK solution (rad).
    ik_iterations
        Refinement rounds per IK seed (each a ``calculateInverseKinematics`` call of up to
        100 iterations followed by ``resetJointState`` and a check).
    ik_random_restarts
        Uniformly random seeds (fixed generator) tried after the fixed ones fail.
    max_joint_jump
        Largest change of any joint between consecutive IK solutions of a path (rad) that
        still counts as continuous motion; more is a re-configuration (see
        :meth:`PandaArm.camera_joint_path`).
    camera_roll
        ``"fixed"``: :meth:`PandaArm.move_camera` reaches the requested ``cam2world``
        exactly (within the tolerances). ``"free"``: the roll about the optical axis is
        left to the arm: it reaches the requested camera position and viewing direction,
        with the roll carried over from the current camera by the smallest rotation
        (parallel transport; a quarter or half turn more where a joint limit requires),
        and returns the pose it reached, which :meth:`~heapgrasp.sim.world.SimWorld.follow`
        then captures from. Look-at view paths spin the camera about its axis near the
        view sphere's pole, which the wrist's limited range cannot always follow; the
        images of a rolled camera see the same scene.
    finger_force
        Force limit of each finger's position controller (N), as the free hand's.
    max_angular_speed
        TCP rotation speed of :meth:`PandaArm.move_linear` (rad/s).
    """

    base_position: tuple[float, float, float] = (-0.24, 0.15, 0.0)
    base_yaw: float = 0.0
    hand2camera: FloatArray = field(default_factory=default_hand2camera)
    joint_lower: Joints = PANDA_LOWER
    joint_upper: Joints = PANDA_UPPER
    max_velocity: Joints = PANDA_MAX_VELOCITY
    max_acceleration: Joints = PANDA_MAX_ACCELERATION
    max_jerk: Joints = PANDA_MAX_JERK
    max_torque: Joints = PANDA_MAX_TORQUE
    rest_pose: Joints = PANDA_READY
    park_pose: Joints = PANDA_PARK
    ik_position_tolerance: float = 1e-3
    ik_angle_tolerance: float = 5e-3
    ik_iterations: int = 30
    ik_random_restarts: int = 40
    max_joint_jump: float = 0.5
    camera_roll: Literal["fixed", "free"] = "fixed"
    finger_force: float = 40.0
    max_angular_speed: float = 1.0

    def __post_init__(self) -> None:
        base = np.asarray(self.base_position, dtype=np.float64)
        if base.shape != (3,) or not np.isfinite(base).all():
            raise ValueError(
                f"base_position must be 3 finite numbers (m), got {self.base_position!r}"
            )
        object.__setattr__(self, "base_position", (float(base[0]), float(base[1]), float(base[2])))
        _finite("base_yaw", self.base_yaw)
        h2c = _rigid("hand2camera", self.hand2camera)
        h2c.flags.writeable = False
        object.__setattr__(self, "hand2camera", h2c)
        for name in ("joint_lower", "joint_upper", "rest_pose", "park_pose"):
            object.__setattr__(self, name, _joints(name, getattr(self, name)))
        for name in ("max_velocity", "max_acceleration", "max_jerk", "max_torque"):
            object.__setattr__(self, name, _joints(name, getattr(self, name), positive=True))
        lo, hi = np.array(self.joint_lower), np.array(self.joint_upper)
        if not (lo < hi).all():
            bad = [i + 1 for i in range(7) if not lo[i] < hi[i]]
            raise ValueError(
                f"joint_lower must be < joint_upper for every joint; not so for joint(s) {bad}"
            )
        for name in ("rest_pose", "park_pose"):
            q = np.array(getattr(self, name))
            out = [i + 1 for i in range(7) if not lo[i] <= q[i] <= hi[i]]
            if out:
                raise ValueError(
                    f"{name} must lie within the joint limits; joint(s) {out} do not: "
                    f"{[round(float(q[i - 1]), 4) for i in out]}"
                )
        for name in (
            "ik_position_tolerance",
            "ik_angle_tolerance",
            "max_joint_jump",
            "finger_force",
            "max_angular_speed",
        ):
            _finite(name, getattr(self, name), positive=True)
        if self.camera_roll not in ("fixed", "free"):
            raise ValueError(f"camera_roll must be 'fixed' or 'free', got {self.camera_roll!r}")
        for name, least in (("ik_iterations", 1), ("ik_random_restarts", 0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < least:
                raise ValueError(f"{name} must be an int >= {least}, got {v!r}")

    @property
    def base_pose(self) -> FloatArray:
        """``(4, 4)`` pose of ``panda_link0`` in the world."""
        c, s = math.cos(self.base_yaw), math.sin(self.base_yaw)
        m = np.eye(4)
        m[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
        m[:3, 3] = self.base_position
        return m


class UnreachableError(RobotUnreachableError):
    """A pose the arm cannot reach within the IK tolerance (a ``ValueError``).

    Attributes
    ----------
    target : numpy.ndarray, shape (4, 4)
        The requested pose (TCP or camera, see ``frame``).
    reached : numpy.ndarray, shape (4, 4)
        The pose of the best IK solution found.
    position_error : float
        Distance between the two (m).
    angle_error : float
        Rotation angle between the two (rad).
    frame : str
        ``"tcp"`` or ``"camera"``.
    """

    def __init__(
        self,
        target: FloatArray,
        reached: FloatArray,
        position_error: float,
        angle_error: float,
        frame: str,
        tolerance: tuple[float, float],
    ) -> None:
        self.target = np.array(target, dtype=np.float64)
        self.reached = np.array(reached, dtype=np.float64)
        self.position_error = float(position_error)
        self.angle_error = float(angle_error)
        self.frame = frame
        p = ", ".join(f"{x:.4f}" for x in self.target[:3, 3])
        super().__init__(
            f"{frame} pose at ({p}) m is unreachable by the Panda arm: the best IK solution "
            f"is off by position error {1e3 * self.position_error:.1f} mm and angle error "
            f"{self.angle_error:.4f} rad ({math.degrees(self.angle_error):.2f}°) "
            f"(tolerance {1e3 * tolerance[0]:.1f} mm, {tolerance[1]:.4f} rad)"
        )


def _angle_between(a: FloatArray, b: FloatArray) -> float:
    """Rotation angle (rad) between the rotation blocks of two poses (robust near 0)."""
    r = a[:3, :3].T @ b[:3, :3]
    c = 0.5 * (float(np.trace(r)) - 1.0)
    s = 0.5 * math.sqrt(
        float(r[2, 1] - r[1, 2]) ** 2
        + float(r[0, 2] - r[2, 0]) ** 2
        + float(r[1, 0] - r[0, 1]) ** 2
    )
    return math.atan2(s, c)


def _pose_errors(a: FloatArray, b: FloatArray) -> tuple[float, float]:
    return float(np.linalg.norm(a[:3, 3] - b[:3, 3])), _angle_between(a, b)


def _interpolate_pose(a: FloatArray, b: FloatArray, s: float) -> FloatArray:
    """Pose at fraction ``s`` from ``a`` to ``b``: position linear, rotation slerped."""
    from scipy.spatial.transform import Rotation, Slerp

    slerp = Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([a[:3, :3], b[:3, :3]])))
    out = np.eye(4)
    out[:3, :3] = slerp([s]).as_matrix()[0]
    out[:3, 3] = (1.0 - s) * a[:3, 3] + s * b[:3, 3]
    return out


def _align(a: FloatArray, b: FloatArray) -> FloatArray:
    """Smallest rotation taking unit vector ``a`` to unit vector ``b``."""
    v = np.cross(a, b)
    c = float(np.dot(a, b))
    if c < -1.0 + 1e-12:  # opposite: half turn about any axis normal to a
        axis = np.cross(a, [1.0, 0.0, 0.0])
        if np.linalg.norm(axis) < 1e-6:
            axis = np.cross(a, [0.0, 1.0, 0.0])
        axis /= np.linalg.norm(axis)
        return np.asarray(2.0 * np.outer(axis, axis) - np.eye(3), dtype=np.float64)
    vx = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.asarray(np.eye(3) + vx + vx @ vx / (1.0 + c), dtype=np.float64)


def _roll(pose: FloatArray, angle: float) -> FloatArray:
    """``pose`` turned by ``angle`` about its own z axis."""
    c, s = math.cos(angle), math.sin(angle)
    turn = np.eye(4)
    turn[:2, :2] = [[c, -s], [s, c]]
    return pose @ turn


def _transport(reference: FloatArray, poses: FloatArray) -> FloatArray:
    """``poses`` with their rolls replaced by parallel transport of ``reference``'s
    rotation along their z axes: each rotation is the smallest turn of the previous one
    that aligns its z axis (positions and z axes unchanged)."""
    out = np.array(poses, dtype=np.float64)
    rot = reference[:3, :3]
    for k in range(out.shape[0]):
        rot = _align(rot[:, 2], out[k, :3, 2]) @ rot
        out[k, :3, :3] = rot
    return out


#: Extra rolls (rad) tried in ``camera_roll="free"`` mode where the transported roll fails.
_ROLLS = (0.0, 0.5 * math.pi, -0.5 * math.pi, math.pi)


def _check_pose(name: str, pose: npt.ArrayLike) -> FloatArray:
    m = np.asarray(pose, dtype=np.float64)
    if m.shape != (4, 4) or not np.isfinite(m).all():
        raise ValueError(f"{name} must be a finite (4, 4) pose, got shape {m.shape}")
    return m


class PandaArm(Fingers):
    """The Franka Panda arm (``panda.urdf``, fixed base) with a wrist camera.

    Satisfies :class:`heapgrasp.sim.robot.Robot`. The arm is added to ``world``'s
    PyBullet client when constructed; like :class:`~heapgrasp.sim.gripper.PandaHand`, make
    it after :meth:`SimWorld.reset`, which clears the simulation.

    Parameters
    ----------
    world
        The world to act in.
    config
        Placement, camera, limits, IK settings; default :class:`ArmConfig()`.

    Attributes
    ----------
    body : int
        PyBullet body id of the arm.
    tcp : numpy.ndarray, shape (4, 4)
        Current commanded TCP pose (world).
    camera2tcp : numpy.ndarray, shape (4, 4)
        Pose of the camera in the TCP frame (from :attr:`ArmConfig.hand2camera`).
    """

    def __init__(self, world: SimWorld, config: ArmConfig | None = None) -> None:
        self.world = world
        self.config = config if config is not None else ArmConfig()
        self.client = world.client
        cfg = self.config
        urdf = Path(pybullet_data.getDataPath()) / "franka_panda" / "panda.urdf"
        pos, quat = _split_pose(cfg.base_pose)
        self.body = int(
            pb.loadURDF(str(urdf), pos, quat, useFixedBase=True, physicsClientId=self.client)
        )
        names: dict[str, int] = {}
        links: dict[str, int] = {}
        for j in range(pb.getNumJoints(self.body, physicsClientId=self.client)):
            info = pb.getJointInfo(self.body, j, physicsClientId=self.client)
            names[info[1].decode()] = j
            links[info[12].decode()] = j
        self._arm = [names[n] for n in _ARM_JOINTS]
        self.finger_joints = [names[n] for n in _FINGER_JOINTS]
        self.finger_force = self.config.finger_force
        self._hand_link = links["panda_hand"]
        self._hand2tcp: FloatArray | None = None
        if "panda_grasptarget" in links:
            self._tcp_link = links["panda_grasptarget"]
        else:  # an older URDF without the TCP link: IK on the hand, TCP 0.105 m along z
            self._tcp_link = self._hand_link
            self._hand2tcp = translate(0.0, 0.0, TCP_OFFSET)
        # Movable joints in PyBullet's IK order (arm joints then fingers).
        self._n_dof = sum(
            pb.getJointInfo(self.body, j, physicsClientId=self.client)[2] != pb.JOINT_FIXED
            for j in range(pb.getNumJoints(self.body, physicsClientId=self.client))
        )
        self._lower = np.array(cfg.joint_lower)
        self._upper = np.array(cfg.joint_upper)
        self._vmax = np.array(cfg.max_velocity)
        self._torque = np.array(cfg.max_torque)
        hand2tcp = translate(0.0, 0.0, TCP_OFFSET)
        self.camera2tcp: FloatArray = np.asarray(
            np.linalg.inv(hand2tcp) @ cfg.hand2camera, dtype=np.float64
        )
        self._tcp2camera: FloatArray = np.asarray(np.linalg.inv(self.camera2tcp), np.float64)
        for joint in self.finger_joints:
            pb.changeDynamics(
                self.body, joint, lateralFriction=FINGER_FRICTION, physicsClientId=self.client
            )
        # Fingers mirror each other (the URDF's mimic joint, as a gear constraint).
        gear = pb.createConstraint(
            self.body,
            self.finger_joints[0],
            self.body,
            self.finger_joints[1],
            pb.JOINT_GEAR,
            [1, 0, 0],
            [0, 0, 0],
            [0, 0, 0],
            physicsClientId=self.client,
        )
        pb.changeConstraint(gear, gearRatio=-1, erp=0.1, maxForce=50, physicsClientId=self.client)
        rest = np.array(cfg.rest_pose)
        self._seeds = [
            self._wrap(rest + np.array([d1, 0, 0, 0, 0, 0, d7]))
            for d7 in _SEED_J7
            for d1 in _SEED_J1
        ]
        self._shoulder = np.asarray(
            pb.getLinkState(
                self.body, self._arm[1], computeForwardKinematics=True, physicsClientId=self.client
            )[4],
            dtype=np.float64,
        )
        self._q_cmd = np.array(cfg.park_pose)
        self._parked = True
        self.stopped_early = False
        """Whether the last :meth:`move_linear` ended before its target (joint limit)."""
        self.reconfigurations = 0
        """How many :meth:`move_camera` calls moved a joint by more than
        :attr:`ArmConfig.max_joint_jump` (a jump: a re-configuration at a joint limit, or a
        pose far from the previous one), not counting the first after :meth:`park`."""
        self.tcp = np.eye(4)
        self.park()

    # ---------------------------------------------------------------- state
    @property
    def time(self) -> float:
        """The world's simulated clock (s)."""
        return self.world.time

    def joint_positions(self) -> FloatArray:
        """Current positions of the 7 arm joints (rad)."""
        states = pb.getJointStates(self.body, self._arm, physicsClientId=self.client)
        return np.array([s[0] for s in states], dtype=np.float64)

    def step(self, n: int = 1) -> None:
        """Runs ``n`` physics steps (advancing the world's clock)."""
        self.world.step_physics(n)

    # ---------------------------------------------------------------- kinematics
    def _set_arm(self, q: FloatArray) -> None:
        for joint, value in zip(self._arm, q, strict=True):
            pb.resetJointState(self.body, joint, float(value), 0.0, physicsClientId=self.client)

    @contextmanager
    def _kinematic_scratch(self) -> Iterator[None]:
        """Restores the arm's joint positions and velocities after scratch IK/FK."""
        states = pb.getJointStates(self.body, self._arm, physicsClientId=self.client)
        try:
            yield
        finally:
            for joint, s in zip(self._arm, states, strict=True):
                pb.resetJointState(self.body, joint, s[0], s[1], physicsClientId=self.client)

    def _tcp_fk(self) -> FloatArray:
        state = pb.getLinkState(
            self.body, self._tcp_link, computeForwardKinematics=True, physicsClientId=self.client
        )
        pose = _pose(state[4], state[5])
        return pose if self._hand2tcp is None else pose @ self._hand2tcp

    def tcp_pose(self) -> FloatArray:
        """TCP pose of the current joint positions (forward kinematics, world)."""
        return self._tcp_fk()

    def camera_pose(self) -> FloatArray:
        """``cam2world`` of the current joint positions (forward kinematics)."""
        return self._tcp_fk() @ self.camera2tcp

    def forward_kinematics(self, q: npt.ArrayLike) -> FloatArray:
        """TCP pose (world) of the arm configuration ``q`` (7 joint angles, rad)."""
        qa = np.asarray(q, dtype=np.float64)
        if qa.shape != (7,) or not np.isfinite(qa).all():
            raise ValueError(f"q must be 7 finite joint angles, got shape {qa.shape}")
        with self._kinematic_scratch():
            self._set_arm(qa)
            return self._tcp_fk()

    def _wrap(self, q: FloatArray) -> FloatArray:
        """Brings angles into the joint limits by ±2π where that helps, then clips."""
        q = np.array(q, dtype=np.float64)
        two_pi = 2.0 * math.pi
        q = np.where((q > self._upper) & (q - two_pi >= self._lower), q - two_pi, q)
        q = np.where((q < self._lower) & (q + two_pi <= self._upper), q + two_pi, q)
        return np.clip(q, self._lower, self._upper)

    def _ik_call(self, target: FloatArray, rest: FloatArray | None) -> FloatArray:
        goal = target if self._hand2tcp is None else target @ np.linalg.inv(self._hand2tcp)
        pos, quat = _split_pose(goal)
        if rest is None:
            sol = pb.calculateInverseKinematics(
                self.body,
                self._tcp_link,
                pos,
                quat,
                maxNumIterations=100,
                residualThreshold=1e-7,
                physicsClientId=self.client,
            )
        else:
            extra = self._n_dof - 7
            width = 0.5 * MAX_OPENING
            sol = pb.calculateInverseKinematics(
                self.body,
                self._tcp_link,
                pos,
                quat,
                lowerLimits=[*self._lower.tolist(), *[0.0] * extra],
                upperLimits=[*self._upper.tolist(), *[width] * extra],
                jointRanges=[*(self._upper - self._lower).tolist(), *[width] * extra],
                restPoses=[*rest.tolist(), *[0.5 * width] * extra],
                maxNumIterations=100,
                residualThreshold=1e-7,
                physicsClientId=self.client,
            )
        return self._wrap(np.asarray(sol[:7], dtype=np.float64))

    def _ik_from(
        self, target: FloatArray, seed: FloatArray, tip: FloatArray | None = None
    ) -> tuple[FloatArray, float, float]:
        """IK from one seed (joints left at the best result): a null-space solve, then
        refinements until the error is a tenth of the tolerance, or within the tolerance
        and no longer shrinking, or :attr:`ArmConfig.ik_iterations` rounds."""
        cfg = self.config
        tol_p, tol_a = cfg.ik_position_tolerance, cfg.ik_angle_tolerance
        self._set_arm(seed)
        q = self._ik_call(target, seed)
        best: tuple[FloatArray, float, float] | None = None
        for _ in range(cfg.ik_iterations):
            self._set_arm(q)
            dp, da = self._errors(target, tip)
            score = dp / tol_p + da / tol_a
            previous = math.inf if best is None else best[1] / tol_p + best[2] / tol_a
            if score < previous:
                best = (q, dp, da)
            if dp <= 0.1 * tol_p and da <= 0.1 * tol_a:
                break
            if dp <= tol_p and da <= tol_a and score > 0.9 * previous:
                break
            q = self._ik_call(target, None)
        assert best is not None
        self._set_arm(best[0])
        return best

    def _errors(self, target: FloatArray, tip: FloatArray | None) -> tuple[float, float]:
        """Position and angle errors of the current TCP from ``target``, measured at the
        frame ``tip`` (its pose in the TCP frame, e.g. the camera; default the TCP)."""
        reached = self._tcp_fk()
        if tip is None:
            return _pose_errors(reached, target)
        return _pose_errors(reached @ tip, target @ tip)

    def _solve(
        self,
        target: FloatArray,
        first: Sequence[FloatArray],
        *,
        fallback: bool = True,
        tip: FloatArray | None = None,
    ) -> tuple[FloatArray, float, float, bool]:
        """Best IK solution from the seeds ``first``, then (``fallback``) the fixed seeds
        around the rest pose, then :attr:`ArmConfig.ik_random_restarts` uniform random
        seeds (a fixed generator, so results are reproducible) unless the target is
        farther from the shoulder than the arm can stretch. Must be called inside
        :meth:`_kinematic_scratch`. Returns ``(q, dp, da, ok)``."""
        cfg = self.config
        best: tuple[FloatArray, float, float] | None = None

        def attempts() -> Iterator[FloatArray]:
            yield from first
            if not fallback:
                return
            yield from self._seeds
            if np.linalg.norm(target[:3, 3] - self._shoulder) > _MAX_TCP_REACH:
                return
            rng = np.random.default_rng(0)
            for _ in range(cfg.ik_random_restarts):
                yield rng.uniform(self._lower, self._upper)

        for seed in attempts():
            q, dp, da = self._ik_from(target, self._wrap(seed), tip)
            if dp <= cfg.ik_position_tolerance and da <= cfg.ik_angle_tolerance:
                return q, dp, da, True
            if best is None or dp + _LEVER * da < best[1] + _LEVER * best[2]:
                best = (q, dp, da)
        assert best is not None
        return best[0], best[1], best[2], False

    def _unreachable(
        self, target: FloatArray, q: FloatArray, dp: float, da: float, frame: str
    ) -> UnreachableError:
        self._set_arm(q)
        reached = self._tcp_fk()
        if frame == "camera":
            target, reached = target @ self.camera2tcp, reached @ self.camera2tcp
        tol = (self.config.ik_position_tolerance, self.config.ik_angle_tolerance)
        return UnreachableError(target, reached, dp, da, frame, tol)

    def inverse_kinematics(
        self, tcp: npt.ArrayLike, seed: npt.ArrayLike | None = None
    ) -> FloatArray:
        """Joint angles putting the TCP at ``tcp`` (world); the arm is not moved.

        Parameters
        ----------
        tcp
            ``(4, 4)`` TCP pose in the world frame.
        seed
            Configuration to start from (7 angles); default the rest pose. The other
            seeds are tried if it fails.

        Returns
        -------
        numpy.ndarray, shape (7,)
            Joint angles within the joint limits.

        Raises
        ------
        UnreachableError
            If no seed reaches ``tcp`` within the tolerances.
        """
        target = _check_pose("tcp", tcp)
        first = [np.array(self.config.rest_pose if seed is None else seed, dtype=np.float64)]
        with self._kinematic_scratch():
            q, dp, da, ok = self._solve(target, first)
            if not ok:
                raise self._unreachable(target, q, dp, da, "tcp")
        return q

    # ---------------------------------------------------------------- control
    def _command(self, q: FloatArray, qd: FloatArray | None = None) -> None:
        pb.setJointMotorControlArray(
            self.body,
            self._arm,
            pb.POSITION_CONTROL,
            targetPositions=q.tolist(),
            targetVelocities=(np.zeros(7) if qd is None else qd).tolist(),
            forces=self._torque.tolist(),
            positionGains=[0.3] * 7,
            velocityGains=[1.0] * 7,
            physicsClientId=self.client,
        )
        self._q_cmd = np.array(q, dtype=np.float64)

    def _teleport(self, q: FloatArray, width: float | None = None) -> None:
        self._set_arm(q)
        if width is not None:
            for joint in self.finger_joints:
                pb.resetJointState(self.body, joint, 0.5 * width, 0.0, physicsClientId=self.client)
            self._finger_targets(width)
        self._command(q)
        self.tcp = self._tcp_fk()
        self._parked = False

    def _continuation_seed(self) -> FloatArray:
        """Where IK of a camera motion starts: the current configuration, or the rest
        pose when parked (the folded park pose is a poor start)."""
        return np.array(self.config.rest_pose) if self._parked else self._q_cmd.copy()

    def reset(self, tcp: FloatArray, width: float = MAX_OPENING) -> None:
        """Teleports the arm so its TCP is at ``tcp`` (IK from the rest pose), fingers at
        ``width``; no physics step.

        Raises
        ------
        UnreachableError
            If ``tcp`` is out of reach (the arm does not move).
        """
        target = _check_pose("tcp", tcp)
        if not (math.isfinite(width) and 0.0 <= width <= MAX_OPENING + 1e-9):
            raise ValueError(f"width must be in [0, {MAX_OPENING}] m, got {width}")
        with self._kinematic_scratch():
            q, dp, da, ok = self._solve(target, [np.array(self.config.rest_pose), self._q_cmd])
            if not ok:
                raise self._unreachable(target, q, dp, da, "tcp")
        self._teleport(q, width)
        self.tcp = target.copy()

    def park(self) -> None:
        """Teleports the arm to :attr:`ArmConfig.park_pose` (folded, out of the scene),
        fingers open; no physics step."""
        self._teleport(np.array(self.config.park_pose), MAX_OPENING)
        self._parked = True

    def move_camera(self, cam2world: FloatArray) -> FloatArray:
        """Moves the arm (kinematically) so its camera is at ``cam2world``.

        IK starts from the current configuration (so a sequence of nearby poses gives a
        continuous joint path; from the rest pose when parked), then from the fallback
        seeds. No physics step and no simulated time: the caller accounts the motion's
        time (:meth:`~heapgrasp.sim.world.SimWorld.follow` does).

        With :attr:`ArmConfig.camera_roll` ``"free"``, the roll about the optical axis
        is carried over from the current camera instead of taken from ``cam2world``.

        Returns
        -------
        numpy.ndarray, shape (4, 4)
            The ``cam2world`` actually reached (forward kinematics).

        Raises
        ------
        UnreachableError
            If no IK solution is within the tolerances (the arm does not move); the
            message gives the position and angle errors of the best one.
        """
        cam = _check_pose("cam2world", cam2world)
        seed = self._continuation_seed()
        if self.config.camera_roll == "free" and not self._parked:
            cam = _transport(self.camera_pose(), cam[None])[0]
        rolls = _ROLLS if self.config.camera_roll == "free" else _ROLLS[:1]
        with self._kinematic_scratch():
            found = None
            best: tuple[FloatArray, FloatArray, float, float] | None = None
            for fallback in (False, True):
                for angle in rolls:
                    target = _roll(cam, angle) @ self._tcp2camera
                    q, dp, da, ok = self._solve(
                        target, [seed], fallback=fallback, tip=self.camera2tcp
                    )
                    if ok:
                        found = q
                        break
                    if angle == 0.0 and fallback:
                        best = (target, q, dp, da)
                if found is not None:
                    break
            if found is None:
                assert best is not None
                raise self._unreachable(*best, "camera")
            q = found
        if not self._parked and float(np.abs(q - seed).max()) > self.config.max_joint_jump:
            self.reconfigurations += 1
        self._teleport(q)
        return self.camera_pose()

    def _continue(
        self,
        q_prev: FloatArray,
        pose_a: FloatArray,
        pose_b: FloatArray,
        tip: FloatArray | None,
        depth: int = 0,
    ) -> FloatArray | None:
        """IK of ``pose_b`` reached continuously from ``q_prev`` (the solution at
        ``pose_a``): no joint may move more than :attr:`ArmConfig.max_joint_jump` between
        solutions; large changes are checked on the halves of the segment (to depth 5),
        so a big but continuous motion passes and a joint-limit flip does not. None if
        only a re-configuration gets there. Call inside :meth:`_kinematic_scratch`."""
        q, _, _, ok = self._solve(pose_b, [q_prev], fallback=False, tip=tip)
        if ok and float(np.abs(q - q_prev).max()) <= self.config.max_joint_jump:
            return q
        if depth >= 5:
            return None
        mid = _interpolate_pose(pose_a, pose_b, 0.5)
        q_mid = self._continue(q_prev, pose_a, mid, tip, depth + 1)
        if q_mid is None:
            return None
        return self._continue(q_mid, mid, pose_b, tip, depth + 1)

    def _roll_tcp(self, tcp: FloatArray, angle: float) -> FloatArray:
        """TCP pose(s) that turn the camera by ``angle`` about its optical axis."""
        return np.asarray(_roll(tcp @ self.camera2tcp, angle) @ self._tcp2camera, np.float64)

    def _chain_from(
        self,
        targets: FloatArray,
        q0: FloatArray,
        frame: str,
        *,
        strict: bool,
        rolls: Sequence[float] = (0.0,),
    ) -> tuple[FloatArray, int | None, float]:
        """IK along ``targets[1:]``, each continued from the previous solution
        (:meth:`_continue`), from ``q0`` (the solution for ``targets[0]``); call inside
        :meth:`_kinematic_scratch`.

        Returns ``(q, stop, jump)``: the ``(N, 7)`` solutions, the index of the first
        target that cannot be reached continuously (a re-configuration, or out of
        reach), or None, and the largest joint change between consecutive solutions.
        ``strict`` stops at that index (``q[stop:]`` is left zero); otherwise the fallback
        seeds take over there (the arm re-configures; with camera ``rolls``, also turning
        the camera by one of them from there on), and an unreachable target raises
        :class:`UnreachableError`.
        """
        targets = np.array(targets, dtype=np.float64)
        tip = self.camera2tcp if frame == "camera" else None
        out = np.zeros((targets.shape[0], 7))
        out[0] = q0
        prev = q0
        stop: int | None = None
        worst = 0.0
        for k in range(1, targets.shape[0]):
            q_next = self._continue(prev, targets[k - 1], targets[k], tip)
            if q_next is None:
                if stop is None:
                    stop = k
                if strict:
                    return out, stop, worst
                found = None
                best: tuple[FloatArray, FloatArray, float, float] | None = None
                for angle in rolls:
                    cand = targets[k] if angle == 0.0 else self._roll_tcp(targets[k], angle)
                    q_next, dp, da, ok = self._solve(cand, [prev], tip=tip)
                    if ok:
                        found = q_next
                        if angle != 0.0:
                            targets[k:] = [self._roll_tcp(t, angle) for t in targets[k:]]
                        break
                    if angle == 0.0:
                        best = (cand, q_next, dp, da)
                if found is None:
                    assert best is not None
                    raise self._unreachable(*best, frame)
                q_next = found
            worst = max(worst, float(np.abs(q_next - prev).max()))
            out[k] = q_next
            prev = q_next
        return out, stop, worst

    def camera_joint_path(self, cam_poses: npt.ArrayLike) -> FloatArray:
        """Joint angles ``(N, 7)`` putting the camera at each of ``cam_poses`` ``(N, 4, 4)``
        in turn; the arm is not moved.

        The IK chain starts from the current configuration (the rest pose when parked),
        each pose seeded by the previous solution, as :meth:`move_camera` does. If that
        chain is discontinuous (a joint limit forces a re-configuration: some joint
        changes by more than :attr:`ArmConfig.max_joint_jump` between consecutive poses),
        the other IK seeds are tried as the configuration at the first pose, and the
        first continuous chain is returned: to follow it with :meth:`move_camera`, first
        :meth:`set_joint_positions` to its row 0 (a re-configuration at rest, at the
        same camera pose). If none is continuous, the chain from the current
        configuration is returned, re-configuring where it must
        (:meth:`camera_joint_chain` tells where).

        Raises
        ------
        UnreachableError
            At the first pose out of reach.
        """
        return self.camera_joint_chain(cam_poses)[0]

    def camera_joint_chain(self, cam_poses: npt.ArrayLike) -> tuple[FloatArray, int | None]:
        """:meth:`camera_joint_path` and the index of the first pose where it
        re-configures the arm (None if continuous)."""
        poses = np.asarray(cam_poses, dtype=np.float64)
        if poses.ndim != 3 or poses.shape[1:] != (4, 4) or not np.isfinite(poses).all():
            raise ValueError(f"cam_poses must be finite (N, 4, 4) poses, got shape {poses.shape}")
        free = self.config.camera_roll == "free"
        if free:
            poses = _transport(poses[0] if self._parked else self.camera_pose(), poses)
        targets = poses @ self._tcp2camera
        with self._kinematic_scratch():
            tip = self.camera2tcp
            q0, dp, da, ok = self._solve(targets[0], [self._continuation_seed()], tip=tip)
            if not ok:
                raise self._unreachable(targets[0], q0, dp, da, "camera")
            chain, stop, _ = self._chain_from(targets, q0, "camera", strict=True)
            if stop is None:
                return chain, None
            tried = [q0]
            for angle in _ROLLS if free else _ROLLS[:1]:
                rolled = self._roll_tcp(targets, angle)
                for seed in self._seeds:
                    q, dp, da, ok = self._solve(rolled[0], [seed], fallback=False, tip=tip)
                    if not ok or min(float(np.abs(q - t).max()) for t in tried) < 0.1:
                        continue
                    tried.append(q)
                    chain, stop2, _ = self._chain_from(rolled, q, "camera", strict=True)
                    if stop2 is None:
                        return chain, None
            rolls = _ROLLS if free else _ROLLS[:1]
            chain, stop, _ = self._chain_from(targets, q0, "camera", strict=False, rolls=rolls)
            return chain, stop

    def set_joint_positions(self, q: npt.ArrayLike) -> None:
        """Sets the arm's 7 joint angles (kinematic, no physics step), e.g. to the start
        of a :meth:`camera_joint_path`."""
        qa = np.asarray(q, dtype=np.float64)
        if qa.shape != (7,) or not np.isfinite(qa).all():
            raise ValueError(f"q must be 7 finite joint angles, got shape {qa.shape}")
        out = [i + 1 for i in range(7) if not self._lower[i] <= qa[i] <= self._upper[i]]
        if out:
            raise ValueError(f"q is outside the joint limits at joint(s) {out}: {qa.tolist()}")
        self._teleport(qa)

    def _line(self, start: FloatArray, target: FloatArray, n: int) -> FloatArray:
        from scipy.spatial.transform import Rotation, Slerp

        slerp = Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([start[:3, :3], target[:3, :3]])))
        s = np.arange(1, n + 1, dtype=np.float64) / n
        poses = np.zeros((n, 4, 4))
        poses[:, 3, 3] = 1.0
        poses[:, :3, :3] = slerp(s).as_matrix()
        poses[:, :3, 3] = (1.0 - s)[:, None] * start[:3, 3] + s[:, None] * target[:3, 3]
        return poses

    def _line_joints(
        self, start: FloatArray, goal: FloatArray, n: int
    ) -> tuple[FloatArray, FloatArray, bool]:
        """``n`` poses along the line after ``start`` and their IK, continued from the
        commanded configuration; cut before the first pose that needs a re-configuration
        or is out of reach. Returns ``(poses, q, complete)``."""
        poses = self._line(start, goal, n)
        targets = np.concatenate([start[None], poses])
        with self._kinematic_scratch():
            chain, stop, _ = self._chain_from(targets, self._q_cmd, "tcp", strict=True)
        if stop is None:
            return poses, chain[1:], True
        return poses[: stop - 1], chain[1:stop], False

    def move_linear(
        self, target: FloatArray, *, speed: float = 0.1, abort_on_contact: bool = False
    ) -> bool:
        """Moves the TCP in a straight line to ``target`` (orientation slerped).

        The line is traversed at ``speed`` m/s (rotation at most
        :attr:`ArmConfig.max_angular_speed`), slower where a joint would exceed its
        velocity limit; its IK solution, continued from the current configuration, is
        tracked by force-limited joint position control one physics step at a time, then
        the arm settles for 0.1 s. Where going on would need a joint beyond its limit (a
        re-configuration) or leave the reachable space, the motion ends at the last pose
        reached continuously, as a real arm stops at a joint limit; :attr:`stopped_early`
        is then True.

        Returns
        -------
        bool
            False if it stopped on a contact (``abort_on_contact``).
        """
        goal = _check_pose("target", target)
        if not (math.isfinite(speed) and speed > 0):
            raise ValueError(f"speed must be finite and > 0 (m/s), got {speed}")
        start = self.tcp.copy()
        dt = self.world.config.time_step
        dist, angle = _pose_errors(start, goal)
        steps = max(1, math.ceil(max(dist / speed, angle / self.config.max_angular_speed) / dt))
        poses, qs, complete = self._line_joints(start, goal, steps)
        # Slow down where a joint would exceed its velocity limit.
        if len(qs):
            dq = np.abs(np.diff(np.vstack([self._q_cmd, qs]), axis=0))
            ratio = float((dq / (self._vmax * dt)).max())
            if ratio > 1.0:
                steps = math.ceil(steps * ratio * 1.05)
                poses, qs, complete = self._line_joints(start, goal, steps)
        self.stopped_early = not complete
        prev = self._q_cmd
        for k in range(len(qs)):
            self._command(qs[k], (qs[k] - prev) / dt)
            prev = qs[k]
            self.step()
            self.tcp = poses[k]
            if abort_on_contact and self.contacts():
                self._command(self.joint_positions())
                return False
        self._command(prev)
        self.step(round(0.1 / dt))
        return True

    # ---------------------------------------------------------------- contacts
    def contacts(self) -> set[int]:
        """Bodies touched by the arm's moving links, hand or fingers (PyBullet ids); the
        base link standing on the table does not count, nor does the arm itself."""
        pts = pb.getContactPoints(bodyA=self.body, physicsClientId=self.client)
        return {int(p[2]) for p in pts if p[2] != self.body and p[3] != -1}

    def touching_parts(self) -> set[HandPart]:
        """Which of the arm's moving links touch another body: ``"palm"`` (the hand),
        ``"finger"`` or ``"arm"`` (any link above the hand)."""
        pts = pb.getContactPoints(bodyA=self.body, physicsClientId=self.client)
        parts: set[HandPart] = set()
        for p in pts:
            if p[2] == self.body or p[3] == -1:
                continue
            link = int(p[3])
            if link in self.finger_joints:
                parts.add("finger")
            elif link == self._hand_link:
                parts.add("palm")
            else:
                parts.add("arm")
        return parts


# --------------------------------------------------------------------------- timing


class JointPathError(HeapgraspError):
    """A camera path the arm cannot follow continuously (a ``ValueError``): a joint limit
    forces a re-configuration (a jump of the IK solution) along it."""


@dataclass(frozen=True, eq=False)
class JointProfile:
    """Joint trajectory of the arm along a timed camera path (:func:`joint_profile`).

    Attributes
    ----------
    times : numpy.ndarray, shape (K,)
        Uniform sample times from 0 to the path's duration (s).
    positions, velocities, accelerations, jerks : numpy.ndarray, shape (K, 7)
        Joint angles and their time derivatives (rad, rad/s, rad/s^2, rad/s^3).
    """

    times: FloatArray
    positions: FloatArray
    velocities: FloatArray
    accelerations: FloatArray
    jerks: FloatArray
    discontinuity: int | None = None
    """Index in ``path.poses`` where the arm must re-configure (None: continuous)."""

    def limit_ratios(self, config: ArmConfig) -> tuple[float, float, float]:
        """Largest ``|derivative| / limit`` over joints and samples, for velocity,
        acceleration and jerk (<= 1 means within the limits)."""
        if self.times.shape[0] < 2:
            return 0.0, 0.0, 0.0
        v = float((np.abs(self.velocities) / np.array(config.max_velocity)).max())
        a = float((np.abs(self.accelerations) / np.array(config.max_acceleration)).max())
        j = float((np.abs(self.jerks) / np.array(config.max_jerk)).max())
        return v, a, j


def joint_profile(path: TimedPath, arm: PandaArm, *, rate: float = 100.0) -> JointProfile:
    """The arm's joint trajectory along a timed camera path, sampled at ``rate`` Hz.

    The joint path is solved at the path's geometric samples (``path.poses``, e.g. every
    5 mm) by :meth:`PandaArm.camera_joint_path` (from the arm's current configuration,
    or a re-configured start if that one runs into a joint limit) and interpolated by a
    cubic spline in the arc length ``s``: the polyline of samples stands for a smooth
    curve, whose kinks would otherwise make the acceleration depend on the sampling.
    With ``s(t)`` and its derivatives from the path's timing, ``q' = q_s s'`` and
    ``q'' = q_ss s'^2 + q_s s''`` are exact for the spline; the jerk is the
    finite-difference derivative of ``q''`` at ``rate``. The arm is not moved.

    Parameters
    ----------
    path
        Timed ``cam2world`` path (e.g. from :func:`heapgrasp.geometry.motion.plan_waypoints`).
    arm
        The arm carrying the camera.
    rate
        Sampling rate of the profile (Hz).

    Returns
    -------
    JointProfile

    Raises
    ------
    UnreachableError
        If a pose of the path is out of reach.
    """
    from scipy.interpolate import CubicSpline

    if not (math.isfinite(rate) and rate > 0):
        raise ValueError(f"rate must be finite and > 0 (Hz), got {rate}")
    knots, first = np.unique(np.asarray(path.arclength), return_index=True)
    q_knots, jump = arm.camera_joint_chain(np.asarray(path.poses)[first])
    discontinuity = None if jump is None else int(first[jump])
    n = max(1, math.ceil(path.duration * rate))
    times = np.linspace(0.0, path.duration, n + 1)
    if knots.shape[0] < 2 or path.duration == 0.0:
        q = np.repeat(q_knots[:1], times.shape[0], axis=0)
        zeros = np.zeros_like(q)
        return JointProfile(times, q, zeros, zeros.copy(), zeros.copy(), discontinuity)
    state = np.array([path.state(float(t)) for t in times])
    s, sd, sdd = state[:, 0], state[:, 1:2], state[:, 2:3]
    spline = CubicSpline(knots, q_knots, axis=0)
    q = np.asarray(spline(s), dtype=np.float64)
    q_s = np.asarray(spline(s, 1), dtype=np.float64)
    q_ss = np.asarray(spline(s, 2), dtype=np.float64)
    qd = q_s * sd
    qdd = q_ss * sd**2 + q_s * sdd
    qddd = np.gradient(qdd, times, axis=0)
    return JointProfile(times, q, qd, qdd, qddd, discontinuity)


def retime_for_arm(
    path: TimedPath,
    arm: PandaArm,
    *,
    rate: float = 100.0,
    margin: float = 0.95,
    max_iterations: int = 8,
) -> TimedPath:
    """The path re-timed so the arm's joints respect their velocity, acceleration and
    jerk limits.

    The joint profile along the path (:func:`joint_profile`) is checked against
    :attr:`ArmConfig.max_velocity`, :attr:`~ArmConfig.max_acceleration` and
    :attr:`~ArmConfig.max_jerk`. If a ratio ``r`` exceeds 1, the path is slowed
    uniformly by ``k = max(r_v, sqrt(r_a), cbrt(r_j)) / margin``: its Cartesian
    :class:`~heapgrasp.geometry.motion.MotionLimits` become ``(v / k, a / k^2, j / k^3)``, which
    stretches ruckig's time-optimal profile by ``k`` and so divides every joint velocity,
    acceleration and jerk by ``k``, ``k^2``, ``k^3``; this repeats (finite differences are
    approximate) up to ``max_iterations`` times. Only the timing changes, not the poses;
    a path already within the limits is returned as is. Uniform slowing is simple and
    conservative: the whole path goes at the pace of its most demanding part.

    The joint path is the one :func:`joint_profile` finds; if it starts from a
    re-configured start (see :meth:`PandaArm.camera_joint_path`), put the arm there
    (:meth:`PandaArm.set_joint_positions`) before following the path with it.

    Parameters
    ----------
    path
        Timed ``cam2world`` path.
    arm
        The arm carrying the camera.
    rate
        Sampling rate of the check (Hz).
    margin
        Target fraction of the limits after a re-timing, in (0, 1].
    max_iterations
        Upper bound on re-timings.

    Returns
    -------
    TimedPath
        ``path`` itself, or a slower copy with the same poses and ``fps``.

    Raises
    ------
    UnreachableError
        If a pose of the path is out of reach.
    JointPathError
        If the arm cannot follow the path without a re-configuration (no timing helps),
        or the limits still fail after ``max_iterations`` re-timings.
    """
    if not (math.isfinite(margin) and 0.0 < margin <= 1.0):
        raise ValueError(f"margin must be in (0, 1], got {margin}")
    if max_iterations < 0:
        raise ValueError(f"max_iterations must be >= 0, got {max_iterations}")
    current = path
    rv = ra = rj = 0.0
    for iteration in range(max_iterations + 1):
        profile = joint_profile(current, arm, rate=rate)
        if profile.discontinuity is not None:
            pose = np.asarray(current.poses)[profile.discontinuity]
            p = ", ".join(f"{x:.3f}" for x in pose[:3, 3])
            raise JointPathError(
                f"the arm cannot follow this camera path continuously: at path sample "
                f"{profile.discontinuity} (camera at ({p}) m) a joint limit forces a "
                f"re-configuration (a joint jump > max_joint_jump = "
                f"{arm.config.max_joint_jump} rad), from any start configuration tried; "
                f"no timing can follow it (split the path or change its waypoints)"
            )
        rv, ra, rj = profile.limit_ratios(arm.config)
        if max(rv, ra, rj) <= 1.0:
            return current
        if iteration == max_iterations:
            break
        k = max(rv, math.sqrt(ra), rj ** (1.0 / 3.0), 1.0) / margin
        lim = current.limits
        new = MotionLimits(lim.max_velocity / k, lim.max_acceleration / k**2, lim.max_jerk / k**3)
        current = TimedPath(np.asarray(current.poses), new, current.fps)
    raise JointPathError(
        f"retime_for_arm: joint limits still exceeded after {max_iterations} re-timings "
        f"(velocity ratio {rv:.3f}, acceleration {ra:.3f}, jerk {rj:.3f})"
    )
