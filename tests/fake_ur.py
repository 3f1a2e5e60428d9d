"""Fakes of ``ur_rtde``'s control and receive interfaces over one simulated controller.

:class:`FakeController` holds the TCP pose (base frame), a clock that only moves when the
arm does (or when the driver sleeps), and a log of every command it received. Its
"joints" are the RTDE pose vector itself (an identity inverse kinematics), which is
enough to check what the driver sends and how it reacts. Faults can be injected: a
protective stop after N motion commands, a dropped connection after N calls, a contact
force below a table height. ``test_ur.py`` checks that every method the fakes offer
exists on the real ``rtde_control`` / ``rtde_receive`` classes.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
from heapgrasp.robot.ur import pose_from_rtde, pose_to_rtde

F64 = npt.NDArray[np.float64]


@dataclass
class _Async:
    running: bool

    def isAsyncOperationRunning(self) -> bool:
        return self.running


@dataclass
class FakeController:
    """The simulated UR controller shared by the two fake interfaces."""

    tcp: list[float] = field(default_factory=lambda: [0.3, -0.1, 0.5, 3.14159, 0.0, 0.0])
    clock: float = 1000.0
    log: list[tuple[str, tuple[Any, ...]]] = field(default_factory=list)
    protective_after: int | None = None
    """Motion commands after which the controller enters a protective stop."""
    protective_on: tuple[str, int] | None = None
    """``(command, n)``: a protective stop at the n-th command of that name."""
    drop_after: int | None = None
    """Calls after which every call raises RuntimeError (the connection is gone)."""
    contact_z: float | None = None
    """Base-frame z below which the TCP feels a 50 N contact (and an async move stops)."""
    reach: float = 1.3
    """Distance from the base beyond which poses are outside the safety limits."""
    lag: list[float] | None = None
    _calls: int = 0
    _motions: int = 0
    protective: bool = False
    connected: bool = True
    _async_target: list[float] | None = None
    _async_speed: float = 0.0

    # ------------------------------------------------------------------ helpers
    def connect(self) -> FakeController:
        """A new connection (after a disconnect)."""
        self.connected = True
        self._calls = 0
        self.drop_after = None
        return self

    def call(self, name: str, *args: Any) -> None:
        self._calls += 1
        if self.drop_after is not None and self._calls > self.drop_after:
            self.connected = False
        if not self.connected:
            raise RuntimeError(f"RTDE: not connected ({name})")
        self.log.append((name, args))
        if self.protective_on is not None and self.protective_on[0] == name:
            if self.names().count(name) >= self.protective_on[1]:
                self.protective = True

    def motion(self) -> bool:
        self._motions += 1
        if self.protective_after is not None and self._motions > self.protective_after:
            self.protective = True
        return not self.protective

    def advance(self, seconds: float) -> None:
        """Lets time pass (the driver's sleep); an async move progresses."""
        if self._async_target is not None:
            a = np.asarray(self.tcp[:3])
            b = np.asarray(self._async_target[:3])
            d = float(np.linalg.norm(b - a))
            step = self._async_speed * seconds
            if step >= d:
                self.tcp = list(self._async_target)
                self._async_target = None
            else:
                p = a + (b - a) * step / d
                self.tcp = [*p.tolist(), *self.tcp[3:]]
            if self.touching():
                self._async_target = None
        self.clock += seconds

    def touching(self) -> bool:
        return self.contact_z is not None and self.tcp[2] <= self.contact_z

    def moved(self, target: list[float], speed: float) -> None:
        d = float(np.linalg.norm(np.asarray(target[:3]) - np.asarray(self.tcp[:3])))
        self.clock += d / max(speed, 1e-6) + 0.05
        self.tcp = list(target)

    def names(self) -> list[str]:
        return [n for n, _ in self.log]


class FakeControl:
    """``rtde_control.RTDEControlInterface`` over a :class:`FakeController`."""

    def __init__(self, ctl: FakeController) -> None:
        self.ctl = ctl

    def isConnected(self) -> bool:
        return self.ctl.connected

    def setTcp(self, tcp: list[float]) -> bool:
        self.ctl.call("setTcp", tcp)
        return True

    def moveL(
        self,
        pose: list[float],
        speed: float = 0.25,
        acceleration: float = 1.2,
        asynchronous: bool = False,
    ) -> bool:
        self.ctl.call("moveL", pose, speed, acceleration, asynchronous)
        if not self.ctl.motion():
            return False
        if asynchronous:
            self.ctl._async_target = list(pose)
            self.ctl._async_speed = speed
        else:
            self.ctl.moved(list(pose), speed)
        return True

    def moveJ(self, q: list[float], speed: float = 1.05, acceleration: float = 1.4) -> bool:
        self.ctl.call("moveJ", q, speed, acceleration)
        if not self.ctl.motion():
            return False
        self.ctl.moved(list(q), speed)
        return True

    def servoL(
        self,
        pose: list[float],
        speed: float,
        acceleration: float,
        time: float,
        lookahead: float,
        gain: float,
    ) -> bool:
        self.ctl.call("servoL", pose, time, lookahead, gain)
        if not self.ctl.motion():
            return False
        self.ctl.tcp = list(pose)
        return True

    def servoStop(self, a: float = 10.0) -> bool:
        self.ctl.call("servoStop")
        return True

    def stopL(self, a: float = 10.0, asynchronous: bool = False) -> None:
        self.ctl.call("stopL", a)
        self.ctl._async_target = None

    def stopScript(self) -> None:
        self.ctl.call("stopScript")

    def initPeriod(self) -> float:
        return self.ctl.clock

    def waitPeriod(self, start: float) -> None:
        dt = next(a[1] for n, a in reversed(self.ctl.log) if n == "servoL")
        self.ctl.clock = max(self.ctl.clock, start + dt)

    def getForwardKinematics(
        self, q: list[float] | None = None, tcp_offset: list[float] | None = None
    ) -> list[float]:
        self.ctl.call("getForwardKinematics", q)
        return list(q) if q else list(self.ctl.tcp)

    def getInverseKinematics(
        self,
        x: list[float],
        qnear: list[float] | None = None,
        max_position_error: float = 1e-10,
        max_orientation_error: float = 1e-10,
    ) -> list[float]:
        self.ctl.call("getInverseKinematics", x)
        if np.linalg.norm(x[:3]) > self.ctl.reach:
            return []  # no solution
        # Continuous stand-in joints: the position and the tool's z axis.
        return [*x[:3], *pose_from_rtde(x)[:3, 2].tolist()]

    def isPoseWithinSafetyLimits(self, pose: list[float]) -> bool:
        self.ctl.call("isPoseWithinSafetyLimits", pose)
        return bool(np.linalg.norm(pose[:3]) <= self.ctl.reach)

    def zeroFtSensor(self) -> bool:
        self.ctl.call("zeroFtSensor")
        return True

    def getAsyncOperationProgressEx(self) -> _Async:
        self.ctl.call("getAsyncOperationProgressEx")
        return _Async(self.ctl._async_target is not None)

    def disconnect(self) -> None:
        self.ctl.connected = False


class FakeReceive:
    """``rtde_receive.RTDEReceiveInterface`` over a :class:`FakeController`."""

    def __init__(self, ctl: FakeController) -> None:
        self.ctl = ctl

    def isConnected(self) -> bool:
        return self.ctl.connected

    def getActualTCPPose(self) -> list[float]:
        if not self.ctl.connected:
            raise RuntimeError("RTDE: not connected")
        return list(self.ctl.tcp)

    def getActualQ(self) -> list[float]:
        return list(self.ctl.tcp)

    def getTimestamp(self) -> float:
        return self.ctl.clock

    def getActualTCPForce(self) -> list[float]:
        return [0.0, 0.0, 50.0 if self.ctl.touching() else 0.5, 0.0, 0.0, 0.0]

    def isProtectiveStopped(self) -> bool:
        return self.ctl.protective

    def isEmergencyStopped(self) -> bool:
        return False

    def getRobotMode(self) -> int:
        return 7

    def getSafetyMode(self) -> int:
        return 3 if self.ctl.protective else 1

    def disconnect(self) -> None:
        self.ctl.connected = False


def world_pose(ctl: FakeController, world2base: F64) -> F64:
    """The controller's TCP in the world frame."""
    return np.linalg.inv(world2base) @ pose_from_rtde(ctl.tcp)


def set_world_pose(ctl: FakeController, world2base: F64, tcp_world: F64) -> None:
    """Puts the TCP at a world pose."""
    ctl.tcp = pose_to_rtde(world2base @ tcp_world)


@dataclass
class StillFrame:
    time: float
    rgb: npt.NDArray[np.uint8]
    depth: npt.NDArray[np.float32] | None = None


class ClockCamera:
    """A camera on the fake controller's clock: a frame every ``1/fps`` s of controller
    time, rendered by ``render(cam2world)`` at the camera's pose then."""

    def __init__(
        self,
        ctl: FakeController,
        world2base: F64,
        cam2tcp: F64,
        render: Callable[[F64], npt.NDArray[np.uint8]],
        spec: Any,
        fps: float = 30.0,
    ) -> None:
        self.ctl, self.world2base, self.cam2tcp = ctl, world2base, cam2tcp
        self.render, self._spec, self.fps = render, spec, fps
        self._next = ctl.clock

    @property
    def spec(self) -> Any:
        return self._spec

    @property
    def depth(self) -> bool:
        return False

    def _shot(self, t: float) -> StillFrame:
        pose = world_pose(self.ctl, self.world2base) @ self.cam2tcp
        return StillFrame(t, self.render(pose))

    def poll(self) -> list[StillFrame]:
        """The frame due since the last call, rendered where the camera is now and stamped
        now (exact pairs; a real camera's exposure lags a little)."""
        out = []
        if self._next <= self.ctl.clock:
            out.append(self._shot(self.ctl.clock))
            while self._next <= self.ctl.clock:
                self._next += 1.0 / self.fps
        return out

    def wait(self, timeout: float | None = None) -> StillFrame:
        self.ctl.advance(max(0.0, self._next - self.ctl.clock))
        shot = self._shot(self._next)
        self._next += 1.0 / self.fps
        return shot
