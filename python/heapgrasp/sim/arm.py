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
* **camera** (on the hand) and **base** (beside the workspace): placed by
  :class:`~heapgrasp.sim.arm_config.ArmConfig` (see :mod:`heapgrasp.sim.arm_config`).

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

The arm's configuration (placement, camera extrinsic, joint limits, IK settings) is
:class:`heapgrasp.sim.arm_config.ArmConfig`; the timing of camera paths within its joint
limits (:func:`~heapgrasp.sim.arm_timing.retime_for_arm`) is :mod:`heapgrasp.sim.arm_timing`.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pybullet_data

from heapgrasp.robot.grasping import HandPart, translate
from heapgrasp.robot.interfaces import UnreachableError as RobotUnreachableError
from heapgrasp.sim.arm_config import ArmConfig
from heapgrasp.sim.bullet import pb
from heapgrasp.sim.hand import FINGER_FRICTION, MAX_OPENING, TCP_OFFSET, Fingers
from heapgrasp.sim.poses import (
    check_pose,
    interpolate_pose,
    pose_errors,
    pose_matrix,
    roll,
    split_pose,
    transport,
)
from heapgrasp.sim.world import SimWorld

__all__ = [
    "PandaArm",
    "UnreachableError",
]

FloatArray = npt.NDArray[np.float64]

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


#: Extra rolls (rad) tried in ``camera_roll="free"`` mode where the transported roll fails.
_ROLLS = (0.0, 0.5 * math.pi, -0.5 * math.pi, math.pi)


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
        pos, quat = split_pose(cfg.base_pose)
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
        pose = pose_matrix(state[4], state[5])
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
        pos, quat = split_pose(goal)
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
            return pose_errors(reached, target)
        return pose_errors(reached @ tip, target @ tip)

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
        target = check_pose("tcp", tcp)
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
        target = check_pose("tcp", tcp)
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
        cam = check_pose("cam2world", cam2world)
        seed = self._continuation_seed()
        if self.config.camera_roll == "free" and not self._parked:
            cam = transport(self.camera_pose(), cam[None])[0]
        rolls = _ROLLS if self.config.camera_roll == "free" else _ROLLS[:1]
        with self._kinematic_scratch():
            found = None
            best: tuple[FloatArray, FloatArray, float, float] | None = None
            for fallback in (False, True):
                for angle in rolls:
                    target = roll(cam, angle) @ self._tcp2camera
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
        mid = interpolate_pose(pose_a, pose_b, 0.5)
        q_mid = self._continue(q_prev, pose_a, mid, tip, depth + 1)
        if q_mid is None:
            return None
        return self._continue(q_mid, mid, pose_b, tip, depth + 1)

    def _roll_tcp(self, tcp: FloatArray, angle: float) -> FloatArray:
        """TCP pose(s) that turn the camera by ``angle`` about its optical axis."""
        return np.asarray(roll(tcp @ self.camera2tcp, angle) @ self._tcp2camera, np.float64)

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
            poses = transport(poses[0] if self._parked else self.camera_pose(), poses)
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
        goal = check_pose("target", target)
        if not (math.isfinite(speed) and speed > 0):
            raise ValueError(f"speed must be finite and > 0 (m/s), got {speed}")
        start = self.tcp.copy()
        dt = self.world.config.time_step
        dist, angle = pose_errors(start, goal)
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
