"""Configuration of the simulated Franka Panda arm (:class:`heapgrasp.sim.arm.PandaArm`):
base placement, wrist-camera extrinsic, the datasheet's joint limits (:data:`PANDA_LOWER`
... :data:`PANDA_MAX_TORQUE`), its "ready" and parking configurations, and the IK
settings.

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
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import numpy.typing as npt

from heapgrasp.robot.grasping import translate

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
    "default_hand2camera",
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
