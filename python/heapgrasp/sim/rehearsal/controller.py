"""A UR controller in the simulator: ``ur_rtde``'s control and receive interfaces over
the rehearsal's world.

:class:`SimController` answers every call :class:`heapgrasp.robot.ur.URArm`, ``robot
check`` and ``robot calibrate`` make of ``RTDEControlInterface`` and
``RTDEReceiveInterface``, with the same names and arguments, so the real driver runs
unchanged on it (:class:`SimControl`, :class:`SimReceive`). The TCP is the simulator's
free-flying hand (:class:`heapgrasp.sim.gripper.PandaHand`), placed in the world
through the rehearsal's true base pose; joints come from the UR5e's kinematics
(:mod:`heapgrasp.sim.rehearsal.ur5e`), so reach, ``[arm] park`` and the joint-speed caps are
checked as a controller would. Time is the world's simulated clock (offset by
:data:`EPOCH`, so it reads like a host's): ``moveL`` and ``moveJ`` take the time their
motion takes, a streamed ``servoL`` the period ``waitPeriod`` waits, and the driver's
``sleep`` steps the physics (:meth:`SimController.advance`).

What a rehearsal does not model: the arm's links (only the hand collides), joint-space
paths (``moveJ`` moves the TCP in a straight line), the controller's own protective
stops, and a force sensor beyond "the hand touches something" (:data:`CONTACT_FORCE`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from heapgrasp.robot.ur import pose_from_rtde, pose_to_rtde
from heapgrasp.sim.rehearsal.ur5e import UR5e

if TYPE_CHECKING:
    from heapgrasp.sim.gripper import PandaHand

__all__ = ["CONTACT_FORCE", "EPOCH", "SimControl", "SimController", "SimReceive"]

F64 = npt.NDArray[np.float64]

#: The controller's clock at the world's time 0 (s): a host-like timestamp.
EPOCH = 1.7e9
#: The TCP force (N) the controller reports while the hand touches anything.
CONTACT_FORCE = 60.0
#: UR's robot mode "running" and safety mode "normal" (as ``getRobotMode`` and
#: ``getSafetyMode`` report them).
ROBOT_MODE_RUNNING = 7
SAFETY_MODE_NORMAL = 1


@dataclass
class _Async:
    running: bool

    def isAsyncOperationRunning(self) -> bool:
        return self.running


@dataclass
class SimController:
    """The simulated controller both interfaces talk to (see the module docstring)."""

    hand: PandaHand
    world2base: F64
    kinematics: UR5e = field(default_factory=UR5e)
    connected: bool = True
    q: F64 = field(default_factory=lambda: np.zeros(6))
    commands: list[str] = field(default_factory=list)
    """The name of every motion command received, in order."""
    _async: tuple[F64, float] | None = None
    """An asynchronous ``moveL``'s target (world) and speed, while it runs."""

    def __post_init__(self) -> None:
        self.base2world: F64 = np.asarray(np.linalg.inv(self.world2base), dtype=np.float64)
        q = self.kinematics.inverse(self.tcp_base())
        self.q = q if q is not None else np.zeros(6)

    # ------------------------------------------------------------------ state
    @property
    def clock(self) -> float:
        """Seconds on the controller's clock (the world's, offset by :data:`EPOCH`)."""
        return EPOCH + self.hand.world.time

    def tcp_base(self) -> F64:
        """The TCP pose in the base frame."""
        return np.asarray(self.world2base @ self.hand.tcp, dtype=np.float64)

    def touching(self) -> bool:
        """Whether the hand touches anything."""
        return bool(self.hand.contacts())

    def require(self) -> None:
        """RuntimeError where the connection was closed (as ``ur_rtde`` raises)."""
        if not self.connected:
            raise RuntimeError("RTDE: not connected")

    def joints_for(self, pose_base: F64) -> F64 | None:
        """Joints for a TCP pose (base), near the joints last solved for (a streamed
        motion updates them lazily); None where out of reach."""
        return self.kinematics.inverse(pose_base, self.q)

    def advance(self, seconds: float) -> None:
        """Lets ``seconds`` pass (the driver's sleep): the physics steps, and an
        asynchronous ``moveL`` progresses, stopping where the hand touches something."""
        world = self.hand.world
        dt = world.config.time_step
        steps = max(1, round(seconds / dt)) if seconds > 0 else 0
        for _ in range(steps):
            if self._async is not None:
                target, speed = self._async
                here = self.hand.tcp
                gap = target[:3, 3] - here[:3, 3]
                dist = float(np.linalg.norm(gap))
                step = speed * dt
                if step >= dist:
                    pose = target
                    self._async = None
                else:
                    pose = here.copy()
                    pose[:3, 3] = here[:3, 3] + gap * (step / dist)
                self.hand.servo(pose)
            world.step_physics(1)
            if self._async is not None and self.touching():
                self._async = None  # the controller's contact stop

    def _sync_q(self) -> None:
        q = self.joints_for(self.tcp_base())
        if q is not None:
            self.q = q

    def move(self, target_base: F64, speed: float) -> None:
        """A blocking straight TCP motion to ``target_base`` at ``speed`` m/s."""
        target = self.base2world @ target_base
        self.hand.move_linear(target, speed=max(speed, 1e-3))
        self._sync_q()


class SimControl:
    """``rtde_control.RTDEControlInterface`` over a :class:`SimController`."""

    def __init__(self, ctl: SimController) -> None:
        self.ctl = ctl

    # ur_rtde's method names are camelCase: the driver calls them so
    def isConnected(self) -> bool:
        return self.ctl.connected

    def setTcp(self, tcp: list[float]) -> bool:
        self.ctl.require()
        self.ctl.kinematics.tcp = pose_from_rtde(tcp)
        return True

    def moveL(
        self,
        pose: list[float],
        speed: float = 0.25,
        acceleration: float = 1.2,
        asynchronous: bool = False,
    ) -> bool:
        self.ctl.require()
        self.ctl.commands.append("moveL")
        target = pose_from_rtde(pose)
        if self.ctl.joints_for(target) is None:
            return False  # the controller refuses a pose out of reach
        if asynchronous:
            self.ctl._async = (self.ctl.base2world @ target, float(speed))
        else:
            self.ctl.move(target, speed)
        return True

    def moveJ(self, q: list[float], speed: float = 1.05, acceleration: float = 1.4) -> bool:
        self.ctl.require()
        self.ctl.commands.append("moveJ")
        target = self.ctl.kinematics.forward(q)
        # a joint move, approximated: the TCP in a straight line at a moderate speed
        self.ctl.move(target, 0.5 * speed)
        self.ctl.q = np.asarray(q, dtype=np.float64)
        return True

    def servoL(
        self,
        pose: list[float],
        speed: float,
        acceleration: float,
        time: float,
        lookahead_time: float,
        gain: float,
    ) -> bool:
        self.ctl.require()
        self.ctl.commands.append("servoL")
        self._period = float(time)
        self.ctl.hand.servo(self.ctl.base2world @ pose_from_rtde(pose))
        return True

    def servoStop(self, a: float = 10.0) -> bool:
        self.ctl.require()
        return True

    def stopL(self, a: float = 10.0, asynchronous: bool = False) -> bool:
        self.ctl._async = None
        return True

    def stopScript(self) -> None:
        self.ctl._async = None

    def initPeriod(self) -> float:
        self.ctl.require()
        return self.ctl.clock

    def waitPeriod(self, start: float) -> None:
        """Steps the physics to the end of the servo period begun at ``start``."""
        period = getattr(self, "_period", 0.008)
        left = start + period - self.ctl.clock
        if left > 0:
            self.ctl.advance(left)

    def getForwardKinematics(
        self, q: list[float] | None = None, tcp_offset: list[float] | None = None
    ) -> list[float]:
        self.ctl.require()
        joints = self.ctl.q if not q else np.asarray(q, dtype=np.float64)
        return pose_to_rtde(self.ctl.kinematics.forward(joints))

    def getInverseKinematics(
        self,
        x: list[float],
        qnear: list[float] | None = None,
        max_position_error: float = 1e-10,
        max_orientation_error: float = 1e-10,
    ) -> list[float]:
        self.ctl.require()
        q = self.ctl.kinematics.inverse(pose_from_rtde(x), qnear if qnear else self.ctl.q)
        return [] if q is None else [float(v) for v in q]

    def isPoseWithinSafetyLimits(self, pose: list[float]) -> bool:
        self.ctl.require()
        return self.ctl.joints_for(pose_from_rtde(pose)) is not None

    def zeroFtSensor(self) -> bool:
        self.ctl.require()
        return True

    def getAsyncOperationProgressEx(self) -> _Async:
        self.ctl.require()
        return _Async(self.ctl._async is not None)

    def disconnect(self) -> None:
        self.ctl._async = None


class SimReceive:
    """``rtde_receive.RTDEReceiveInterface`` over a :class:`SimController`."""

    def __init__(self, ctl: SimController) -> None:
        self.ctl = ctl

    def isConnected(self) -> bool:
        return self.ctl.connected

    def getActualTCPPose(self) -> list[float]:
        self.ctl.require()
        return pose_to_rtde(self.ctl.tcp_base())

    def getActualQ(self) -> list[float]:
        self.ctl.require()
        self.ctl._sync_q()
        return [float(v) for v in self.ctl.q]

    def getTimestamp(self) -> float:
        return self.ctl.clock

    def getActualTCPForce(self) -> list[float]:
        self.ctl.require()
        force = CONTACT_FORCE if self.ctl.touching() else 0.0
        return [0.0, 0.0, force, 0.0, 0.0, 0.0]

    def isProtectiveStopped(self) -> bool:
        return False

    def isEmergencyStopped(self) -> bool:
        return False

    def getRobotMode(self) -> int:
        return ROBOT_MODE_RUNNING

    def getSafetyMode(self) -> int:
        return SAFETY_MODE_NORMAL

    def disconnect(self) -> None:
        pass
