"""A UR e-Series arm over RTDE (``ur-rtde``) as the loop's :class:`~heapgrasp.robot.interfaces.Arm`.

:class:`URArm` carries the hand-eye camera along the loop's timed paths (HEAPGrasp §V,
eq. 8: continuous capture while moving) and runs the grasp sequence of
:mod:`heapgrasp.robot.grasping`:

* a camera path is sampled at ``[arm] servo_rate``, turned about the optical axis where
  the view sphere's look-at poses roll (:func:`continuous_roll`: a silhouette does not
  depend on the roll), converted to TCP poses through the hand-eye extrinsic, slowed
  until the TCP keeps the caps, **checked whole** (:mod:`heapgrasp.robot.safety`: the workspace
  box, the speed and acceleration caps, the joint speeds from the controller's inverse
  kinematics) and only then streamed with ``servoL``; the TCP pose is read with a host
  timestamp every cycle;
* every camera frame that arrived meanwhile is paired with the camera pose at the
  frame's own timestamp, interpolated in that record (:class:`PoseBuffer`);
* still frames (:meth:`URArm.look`) are taken after the arm rests ``[arm] settle`` s;
* pre-grasp moves go up to ``[arm] travel_height``, across, and down (``moveL``); a
  motion that stops on contact watches the TCP force.

The controller's protective and emergency stops and a lost connection become
:class:`~heapgrasp.robot.errors.ProtectiveStop` and
:class:`~heapgrasp.robot.errors.ConnectionLost`; the run stops with what it recorded.
A pose outside the workspace box is :class:`OutsideWorkspace`, a path above the caps
:class:`PathRefused`: refused before anything is sent and, being
:class:`~heapgrasp.robot.interfaces.UnreachableError` too, a view waypoint the loop skips
or a grasp that fails without moving.

Clocks: the arm's clock is the host's (``time.time``); the RealSense stamps its frames in
the same (global) time domain, so a frame and the TCP record are compared directly.
"""

from __future__ import annotations

import math
import socket
import struct
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt
from scipy.spatial.transform import Rotation, Slerp

from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.geometry.motion import TimedPath
from heapgrasp.perception.frames import Capture, Frame
from heapgrasp.robot.config import RobotConfig
from heapgrasp.robot.errors import ConnectionLost, DeviceError, ProtectiveStop, SafetyError
from heapgrasp.robot.interfaces import Contact, UnreachableError
from heapgrasp.robot.safety import (
    check_inside,
    check_move,
    check_path,
    joint_speed,
    measure_path,
    slowdown,
)

__all__ = [
    "OutsideWorkspace",
    "PathRefused",
    "PoseBuffer",
    "StampedCamera",
    "StampedFrame",
    "URArm",
    "connect_ur",
    "continuous_roll",
    "pose_from_rtde",
    "pose_to_rtde",
]

F64 = npt.NDArray[np.float64]


class OutsideWorkspace(SafetyError, UnreachableError):
    """A pose outside the workspace box: refused before anything was sent."""


class PathRefused(SafetyError, UnreachableError):
    """A camera path whose speeds would exceed the caps (e.g. a path over the view
    sphere's pole, where the look-at camera rolls half a turn): refused before anything
    was sent; the loop skips that view."""


def pose_to_rtde(pose: F64) -> list[float]:
    """A ``(4, 4)`` pose as RTDE's ``[x, y, z, rx, ry, rz]`` (m, rotation vector)."""
    rv = Rotation.from_matrix(pose[:3, :3]).as_rotvec()
    return [float(v) for v in (*pose[:3, 3], *rv)]


def pose_from_rtde(vector: Sequence[float]) -> F64:
    """RTDE's ``[x, y, z, rx, ry, rz]`` as a ``(4, 4)`` pose."""
    v = np.asarray(vector, dtype=np.float64).reshape(-1)
    if v.shape != (6,) or not np.isfinite(v).all():
        raise DeviceError(f"the controller sent a pose that is not 6 finite numbers: {list(v)}")
    m = np.eye(4)
    m[:3, :3] = Rotation.from_rotvec(v[3:]).as_matrix()
    m[:3, 3] = v[:3]
    return m


def continuous_roll(cams: F64, start: F64) -> F64:
    """``cams`` (``(N, 4, 4)`` camera poses) each turned about its optical axis (z) so
    that every orientation is the nearest to the one before it, the first the nearest to
    ``start``'s: the same positions and viewing directions, with no roll the wrist need
    not make. A silhouette does not depend on the roll (the frames record the poses they
    were taken at); the look-at poses of the view sphere roll half a turn where a path
    passes over its pole."""
    out = np.array(cams, dtype=np.float64, copy=True)
    prev = np.asarray(start, dtype=np.float64)[:3, :3]
    for i in range(len(out)):
        r = out[i, :3, :3]
        m = r.T @ prev
        psi = math.atan2(m[1, 0] - m[0, 1], m[0, 0] + m[1, 1])
        c, s = math.cos(psi), math.sin(psi)
        out[i, :3, :3] = r @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        prev = out[i, :3, :3]
    return out


class StampedFrame(Protocol):
    """A camera frame with a host timestamp (:class:`heapgrasp.robot.realsense.CameraFrame`)."""

    time: float
    rgb: npt.NDArray[np.uint8]
    depth: npt.NDArray[np.float32] | None


class StampedCamera(Protocol):
    """What :class:`URArm` needs from its camera
    (:class:`heapgrasp.robot.realsense.RealSenseCamera`)."""

    @property
    def spec(self) -> CameraSpec: ...

    @property
    def depth(self) -> bool: ...

    def poll(self) -> Sequence[StampedFrame]:
        """Every frame that arrived since the last call, oldest first (non-blocking)."""
        ...

    def wait(self, timeout: float | None = None) -> StampedFrame:
        """The next frame (blocking)."""
        ...


@dataclass
class PoseBuffer:
    """Timestamped poses (host clock), interpolated at any time inside their span:
    positions linearly, rotations by slerp."""

    times: list[float] = field(default_factory=list)
    poses: list[F64] = field(default_factory=list)

    def add(self, t: float, pose: F64) -> None:
        """Appends a pose read at ``t`` (times must not decrease; an equal time replaces)."""
        if self.times and t < self.times[-1]:
            raise DeviceError(f"pose timestamps went backwards: {t} after {self.times[-1]}")
        if self.times and t == self.times[-1]:
            self.poses[-1] = pose
            return
        self.times.append(t)
        self.poses.append(pose)

    def span(self) -> tuple[float, float]:
        """The first and last time recorded."""
        if not self.times:
            raise DeviceError("no arm pose was recorded")
        return self.times[0], self.times[-1]

    def at(self, t: npt.ArrayLike) -> F64:
        """``(N, 4, 4)`` poses at times ``t``, each inside :meth:`span`."""
        ts = np.atleast_1d(np.asarray(t, dtype=np.float64))
        lo, hi = self.span()
        if (ts < lo).any() or (ts > hi).any():
            raise ValueError(f"times outside the recorded span [{lo}, {hi}]")
        poses = np.stack(self.poses)
        if len(self.times) == 1:
            return np.repeat(poses, len(ts), axis=0)
        times = np.asarray(self.times)
        out = np.repeat(np.eye(4)[None], len(ts), axis=0)
        out[:, :3, :3] = Slerp(times, Rotation.from_matrix(poses[:, :3, :3]))(ts).as_matrix()
        for k in range(3):
            out[:, k, 3] = np.interp(ts, times, poses[:, k, 3])
        return out


#: RTDE's port on a UR controller, and how long a controller has to answer (s).
RTDE_PORT = 30004
RTDE_TIMEOUT_S = 5.0
#: RTDE's request of the protocol version (message type ``V``) and the version asked.
_RTDE_REQUEST_PROTOCOL_VERSION = 86
_RTDE_PROTOCOL_VERSION = 2


def probe_rtde(host: str, *, port: int = RTDE_PORT, timeout: float = RTDE_TIMEOUT_S) -> None:
    """Asks ``host``'s RTDE server for its protocol version and waits at most ``timeout``
    seconds for the connection and for an answer, so that an address nobody answers at,
    or a host that accepts TCP and never speaks RTDE, is a :class:`ConnectionLost`
    naming it within seconds — ``ur_rtde`` itself waits minutes, or for ever."""
    where = f"{host}:{port}"
    try:
        with socket.create_connection((host, port), timeout=timeout) as sock:
            sock.settimeout(timeout)
            sock.sendall(
                struct.pack(">HBH", 5, _RTDE_REQUEST_PROTOCOL_VERSION, _RTDE_PROTOCOL_VERSION)
            )
            reply = b""
            while len(reply) < 3:
                chunk = sock.recv(3 - len(reply))
                if not chunk:
                    raise ConnectionLost(
                        f"the UR controller at {where} closed the connection without answering RTDE"
                    )
                reply += chunk
    except TimeoutError:
        raise ConnectionLost(
            f"no RTDE answer from the UR controller at {where} within {timeout:g} s (is it "
            "on, in remote-control mode, and is [arm] host its address?)"
        ) from None
    except OSError as exc:  # refused, unreachable, no route, unknown name
        raise ConnectionLost(f"cannot reach the UR controller at {where}: {exc}") from None
    if reply[2] != _RTDE_REQUEST_PROTOCOL_VERSION:
        raise ConnectionLost(f"{where} answered, but not as a UR controller's RTDE server")


def connect_ur(host: str, tcp: Sequence[float]) -> tuple[Any, Any]:
    """Opens RTDE's control and receive interfaces to ``host`` and sets the TCP.

    Raises :class:`DeviceError` where ``ur-rtde`` is not installed and
    :class:`ConnectionLost` where the controller does not answer."""
    if not host:
        raise DeviceError("[arm] host is empty: set the controller's address in robot.toml")
    try:
        import rtde_control
        import rtde_receive
    except ImportError as exc:
        raise DeviceError(
            f"the UR driver needs ur-rtde: pip install 'heapgrasp[robot]' ({exc})"
        ) from None
    probe_rtde(host)  # seconds, not minutes, where nothing answers
    try:
        receive = rtde_receive.RTDEReceiveInterface(host)
        control = rtde_control.RTDEControlInterface(host)
    except RuntimeError as exc:
        raise ConnectionLost(
            f"cannot reach the UR controller at {host}: {exc} (is it on, in remote-control "
            "mode, and is the address right?)"
        ) from None
    if not control.setTcp(list(tcp)):
        raise DeviceError(f"the controller refused the TCP {list(tcp)}")
    return control, receive


class URArm:
    """:class:`~heapgrasp.robot.interfaces.Arm` over RTDE (see the module docstring).

    ``control`` and ``receive`` are ``ur_rtde``'s ``RTDEControlInterface`` and
    ``RTDEReceiveInterface`` (or objects with the same methods: the tests' fakes);
    ``open_to`` opens the gripper to a width (m) before a pre-grasp move. ``clock`` and
    ``sleep`` are the host's (tests pass a simulated clock).
    """

    def __init__(
        self,
        control: Any,
        receive: Any,
        camera: StampedCamera,
        config: RobotConfig,
        *,
        open_to: Callable[[float], Any] | None = None,
        clock: Callable[[], float] = time.time,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        cal = config.calibration
        if cal.cam2tcp is None or cal.world2base is None:
            raise DeviceError(
                f"{config.source}: [calibration] is missing: run `heapgrasp robot calibrate` first"
            )
        self.control = control
        self.receive = receive
        self._camera = camera
        self.config = config
        self.cam2tcp: F64 = cal.cam2tcp
        self.world2base: F64 = cal.world2base
        self.base2world: F64 = np.asarray(np.linalg.inv(cal.world2base), dtype=np.float64)
        self.open_to = open_to
        self._clock = clock
        self._sleep = sleep
        self.commands = 0
        """Motion commands sent so far (for the record)."""
        self.slowdowns: list[float] = []
        """The slowdown of every camera path followed (1: at the loop's timing)."""

    # ------------------------------------------------------------------ state
    @property
    def camera(self) -> StampedCamera:
        """The camera it carries."""
        return self._camera

    @property
    def clock(self) -> float:
        """The host clock (s)."""
        return self._clock()

    def _call(self, what: str, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        """Calls the controller, mapping its failures to the package's errors."""
        try:
            result = fn(*args, **kwargs)
        except RuntimeError as exc:
            raise ConnectionLost(f"UR controller: {what} failed: {exc}") from None
        if result is False:
            self.check_state(what)
            raise DeviceError(f"UR controller refused {what}")
        return result

    def check_state(self, what: str = "the arm") -> None:
        """Raises where the controller is stopped or the connection is gone."""
        try:
            connected = self.receive.isConnected() and self.control.isConnected()
            protective = self.receive.isProtectiveStopped()
            emergency = self.receive.isEmergencyStopped()
        except RuntimeError as exc:
            raise ConnectionLost(f"UR controller: {what}: {exc}") from None
        if not connected:
            raise ConnectionLost(f"UR controller: {what}: the RTDE connection was lost")
        if emergency:
            raise ProtectiveStop(f"UR controller: {what}: emergency stop")
        if protective:
            raise ProtectiveStop(
                f"UR controller: {what}: protective stop (clear it on the teach pendant)"
            )

    def _tcp_base(self) -> F64:
        try:
            return pose_from_rtde(self.receive.getActualTCPPose())
        except RuntimeError as exc:
            raise ConnectionLost(f"UR controller: reading the TCP pose: {exc}") from None

    @property
    def tcp(self) -> F64:
        """The TCP pose now (world)."""
        return self.base2world @ self._tcp_base()

    def _to_base(self, tcp_world: F64) -> list[float]:
        return pose_to_rtde(self.world2base @ tcp_world)

    def _force(self) -> float:
        try:
            f = self.receive.getActualTCPForce()
        except RuntimeError as exc:
            raise ConnectionLost(f"UR controller: reading the TCP force: {exc}") from None
        return float(np.linalg.norm(np.asarray(f, dtype=np.float64)[:3]))

    # ------------------------------------------------------------------ checks
    def check_poses(self, tcp_world: F64) -> None:
        """The TCP and the camera inside the box at these ``(N, 4, 4)`` TCP poses."""
        tcp_world = tcp_world.reshape(-1, 4, 4)
        ws = self.config.workspace
        try:
            check_inside(ws, tcp_world[:, :3, 3], "the TCP")
            check_inside(ws, (tcp_world @ self.cam2tcp)[:, :3, 3], "the camera")
        except SafetyError as exc:
            raise OutsideWorkspace(str(exc)) from None

    def check_reachable(self, tcp_world: F64) -> None:
        """:class:`UnreachableError` where the controller says the pose is out of reach."""
        pose = self._to_base(tcp_world)
        if not self._call("the safety-limit check", self.control.isPoseWithinSafetyLimits, pose):
            raise UnreachableError("the pose is outside the arm's reach or safety limits")

    def straight_poses(self, a: F64, b: F64, n: int = 11) -> F64:
        """Poses along the straight TCP motion from ``a`` to ``b`` (for the box check)."""
        s = np.linspace(0.0, 1.0, n)
        rots = Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([a[:3, :3], b[:3, :3]])))(s)
        out = np.repeat(np.eye(4)[None], n, axis=0)
        out[:, :3, :3] = rots.as_matrix()
        out[:, :3, 3] = a[:3, 3] + s[:, None] * (b[:3, 3] - a[:3, 3])
        return out

    # ------------------------------------------------------------------ motions
    def move_l(self, tcp_world: F64, speed: float, acceleration: float) -> None:
        """A checked blocking ``moveL`` from where the TCP is to ``tcp_world``."""
        check_move(self.config.limits, speed, acceleration)
        self.check_poses(self.straight_poses(self.tcp, tcp_world))
        self.check_reachable(tcp_world)
        self.check_state("moveL")
        self.commands += 1
        self._call("moveL", self.control.moveL, self._to_base(tcp_world), speed, acceleration)
        self.check_state("moveL")

    def park_pose(self) -> F64:
        """The TCP pose (world) of ``[arm] park``, from the controller's forward
        kinematics."""
        q = list(self.config.arm.park)
        fk = self._call("forward kinematics", self.control.getForwardKinematics, q)
        return self.base2world @ pose_from_rtde(fk)

    def park(self) -> None:
        """``moveJ`` to ``[arm] park`` (its TCP checked inside the box first)."""
        self.check_poses(self.park_pose())
        lim = self.config.limits
        self.check_state("moveJ")
        self.commands += 1
        self._call(
            "moveJ",
            self.control.moveJ,
            list(self.config.arm.park),
            lim.joint_speed,
            lim.joint_acceleration,
        )
        self.check_state("moveJ")

    def still_frame(self) -> Frame:
        """A frame taken after the arm rests ``[arm] settle`` s, with its pose."""
        self._sleep(self.config.arm.settle)
        self._camera.poll()  # drop what was taken while moving
        t_min = self.clock
        timeout = self.config.camera.timeout
        for _ in range(100):
            shot = self._camera.wait(timeout)
            if shot.time >= t_min:
                break
        else:
            raise DeviceError("the camera kept delivering frames older than the arm's rest")
        pose = self.tcp @ self.cam2tcp
        return Frame(pose, self._camera.spec, shot.time, shot.rgb, shot.depth)

    def look(self, cam2world: F64) -> Frame:
        """Moves (``moveL``) so the camera is at ``cam2world`` (turned about its optical
        axis to the roll nearest the camera's now, :func:`continuous_roll`), rests, and
        captures."""
        lim = self.config.limits
        goal = continuous_roll(np.asarray(cam2world)[None], self.tcp @ self.cam2tcp)[0]
        self.move_l(goal @ np.linalg.inv(self.cam2tcp), lim.tool_speed, lim.tool_acceleration)
        return self.still_frame()

    def _ik(self, tcp: F64, picks: list[int]) -> F64:
        """Joint positions at the TCP samples ``picks`` (controller IK, each near the
        last); :class:`UnreachableError` where there is none."""
        joints: list[list[float]] = []
        for i in picks:
            q = self._call(
                "inverse kinematics",
                self.control.getInverseKinematics,
                self._to_base(tcp[i]),
                joints[-1] if joints else [],
            )
            if len(q) != 6:
                raise UnreachableError(f"no inverse kinematics for the path's sample {i}")
            joints.append(list(q))
        return np.asarray(joints, dtype=np.float64)

    def _sample(self, path: TimedPath, slowdown: float) -> tuple[F64, F64]:
        """The path's TCP poses at ``[arm] servo_rate`` with its timing stretched by
        ``slowdown``."""
        rate = self.config.arm.servo_rate
        duration = path.duration * slowdown
        n = max(2, math.ceil(duration * rate) + 1)
        times = np.linspace(0.0, duration, n) if duration > 0 else np.zeros(1)
        cams = np.stack([path.at(float(t) / slowdown) for t in times])
        cams = continuous_roll(cams, self.tcp @ self.cam2tcp)
        return times, cams @ np.linalg.inv(self.cam2tcp)

    def plan_path(self, path: TimedPath) -> tuple[F64, F64, float]:
        """The TCP samples (times, ``(N, 4, 4)`` world poses) streamed for ``path`` and
        the slowdown applied, all checked before anything is sent.

        The loop times its paths for the camera (``max_velocity``, ``max_acceleration``);
        the TCP, behind the camera, moves faster where the camera turns. Like the
        simulated Panda (:func:`heapgrasp.sim.arm_timing.retime_for_arm`) the path is then
        slowed uniformly by the factor that brings the TCP's and the camera's speeds,
        the TCP's angular speed and acceleration, and the joint speeds (controller IK at
        ~30 Hz) within ``[limits]``; only the timing changes. A path that would need
        more than ``[arm] max_slowdown``, or leaves the box, is refused."""
        times, tcp = self._sample(path, 1.0)
        self.check_poses(tcp)
        if len(times) < 2:
            return times, tcp, 1.0
        stride = max(1, int(self.config.arm.servo_rate / 30))
        picks = list(range(0, len(times), stride))
        if picks[-1] != len(times) - 1:
            picks.append(len(times) - 1)
        joints = self._ik(tcp, picks)
        lim = self.config.limits
        qd = joint_speed(times[picks], joints)
        measured = measure_path(times, tcp, self.cam2tcp)
        k = 1.0
        for _ in range(6):  # the differences are approximate: measure again after a stretch
            step = slowdown(measured, lim, qd / k)
            if step <= 1.0:
                break
            k *= step * 1.02
            if k > self.config.arm.max_slowdown:
                raise PathRefused(
                    f"the path would have to go {k:.1f} times slower than planned to keep "
                    f"the caps (at the planned timing: TCP {measured.tcp_speed:.2f} m/s, "
                    f"{measured.rotation_speed:.2f} rad/s, {measured.acceleration:.2f} m/s²; "
                    f"[arm] max_slowdown {self.config.arm.max_slowdown}); nothing was sent"
                )
            times, tcp = self._sample(path, k)
            measured = measure_path(times, tcp, self.cam2tcp)
        try:
            check_path(self.config.workspace, lim, times, tcp, self.cam2tcp)
        except SafetyError as exc:
            raise PathRefused(str(exc)) from None
        if qd / k > lim.joint_speed * 1.05:
            raise PathRefused(
                f"the path turns a joint at {qd / k:.3f} rad/s, above the cap "
                f"{lim.joint_speed} ([limits] joint_speed); nothing was sent"
            )
        return times, tcp, k

    def follow(self, path: TimedPath) -> Capture:
        """Streams the checked path (``servoL`` at ``[arm] servo_rate``), reading the TCP
        pose every cycle, and pairs every frame that arrived with the camera pose at its
        timestamp."""
        _, tcp, slowed = self.plan_path(path)
        self.slowdowns.append(slowed)
        lim = self.config.limits
        here = self.tcp
        if np.linalg.norm(here[:3, 3] - tcp[0, :3, 3]) > 0.005:
            self.move_l(tcp[0], lim.tool_speed, lim.tool_acceleration)
        arm = self.config.arm
        dt = 1.0 / arm.servo_rate
        buffer = PoseBuffer()
        frames: list[StampedFrame] = []
        self._camera.poll()
        t0 = self.clock
        buffer.add(t0, self.tcp)
        self.check_state("servoL")
        self.commands += 1
        hold = math.ceil(arm.lookahead / dt) + 1  # the last pose, until the arm is there
        targets = [*tcp, *([tcp[-1]] * hold)]
        try:
            for target in targets:
                start = self._call("initPeriod", self.control.initPeriod)
                self._call(
                    "servoL",
                    self.control.servoL,
                    self._to_base(target),
                    0.0,
                    0.0,
                    dt,
                    arm.lookahead,
                    arm.gain,
                )
                buffer.add(self.clock, self.tcp)
                frames.extend(self._camera.poll())
                self.check_state("servoL")
                self.control.waitPeriod(start)
        finally:
            try:
                self.control.servoStop()
            except RuntimeError:
                pass
        buffer.add(self.clock, self.tcp)
        frames.extend(self._camera.poll())
        lo, hi = buffer.span()
        kept = [f for f in frames if lo <= f.time <= hi]
        poses = buffer.at([f.time for f in kept]) @ self.cam2tcp if kept else np.zeros((0, 4, 4))
        spec = self._camera.spec
        out = [Frame(p, spec, f.time, f.rgb, f.depth) for p, f in zip(poses, kept, strict=True)]
        return Capture(
            np.array([f.time for f in out]), out, duration=hi - lo, timing_kept=slowed == 1.0
        )

    def move_to(self, tcp: F64, *, opening: float) -> None:
        """Opens the gripper to ``opening``, then goes up to ``[arm] travel_height``,
        across above ``tcp`` and down to it (three checked ``moveL``)."""
        pose = np.asarray(tcp, dtype=np.float64)
        self.check_poses(pose)
        self.check_reachable(pose)
        if self.open_to is not None:
            self.open_to(opening)
        lim = self.config.limits
        height = max(self.config.arm.travel_height, pose[2, 3])
        here = self.tcp
        up = here.copy()
        up[2, 3] = max(here[2, 3], height)
        above = pose.copy()
        above[2, 3] = height
        for leg in (up, above, pose):
            self.move_l(leg, lim.tool_speed, lim.tool_acceleration)

    def move_linear(self, tcp: F64, *, speed: float = 0.1, stop_on_contact: bool = False) -> bool:
        """A straight ``moveL`` at ``speed`` (capped at ``[limits] tool_speed``); with
        ``stop_on_contact`` it runs asynchronously and stops where the TCP force exceeds
        ``[arm] contact_force`` (returns False there)."""
        lim = self.config.limits
        speed = min(speed, lim.tool_speed)
        if not stop_on_contact:
            self.move_l(np.asarray(tcp, dtype=np.float64), speed, lim.tool_acceleration)
            return True
        target = np.asarray(tcp, dtype=np.float64)
        check_move(lim, speed, lim.tool_acceleration)
        self.check_poses(self.straight_poses(self.tcp, target))
        self.check_reachable(target)
        self._call("zeroFtSensor", self.control.zeroFtSensor)
        self.check_state("moveL")
        self.commands += 1
        self._call(
            "moveL", self.control.moveL, self._to_base(target), speed, lim.tool_acceleration, True
        )
        distance = float(np.linalg.norm(target[:3, 3] - self.tcp[:3, 3]))
        deadline = self.clock + 2.0 * distance / speed + 2.0
        while True:
            self.check_state("moveL")
            if self._force() > self.config.arm.contact_force:
                self._call("stopL", self.control.stopL, lim.tool_acceleration * 4)
                return False
            status = self.control.getAsyncOperationProgressEx()
            if not status.isAsyncOperationRunning():
                return True
            if self.clock > deadline:
                self._call("stopL", self.control.stopL, lim.tool_acceleration * 4)
                raise DeviceError("moveL did not finish in twice its expected time")
            self._sleep(0.002)

    def contact(self) -> Contact | None:
        """A contact where the TCP force exceeds ``[arm] contact_force`` (the arm cannot
        tell what it touched)."""
        return Contact() if self._force() > self.config.arm.contact_force else None

    def stop(self) -> None:
        """Stops any motion and ends the controller's script (best effort)."""
        for call in (lambda: self.control.stopL(2.0), self.control.stopScript):
            try:
                call()
            except RuntimeError:
                pass
