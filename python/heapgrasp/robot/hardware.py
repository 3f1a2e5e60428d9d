"""The real robot assembled from ``robot.toml``: a UR arm, a RealSense and a Robotiq 2F-140.

:class:`HardwareRobot` is the loop's :class:`~heapgrasp.robot.interfaces.Robot` on
hardware. :meth:`HardwareRobot.connect` opens the three devices in turn (camera, gripper,
arm) and closes what it opened if a later one fails; :meth:`HardwareRobot.close` stops
the arm and releases everything. The drivers are built by :class:`Drivers`, whose
factories the tests replace with fakes.

``activate=False`` (the dry run) connects the gripper without activating it: activation
moves the fingers through their whole stroke, and a dry run moves nothing.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from types import TracebackType
from typing import Any

from heapgrasp.robot.config import RobotConfig
from heapgrasp.robot.realsense import RealSenseCamera, RealSenseSettings
from heapgrasp.robot.robotiq import Robotiq2F140, WidthCalibration
from heapgrasp.robot.ur import URArm, connect_ur

__all__ = ["Drivers", "HardwareRobot", "camera_settings"]


def _camera(settings: RealSenseSettings) -> Any:
    return RealSenseCamera(settings)


def _gripper(config: RobotConfig) -> Any:
    g = config.gripper
    calibration = None
    if g.open_position is not None and g.closed_position is not None:
        calibration = WidthCalibration(g.open_position, g.closed_position)
    return Robotiq2F140(
        config.gripper_host,
        g.port,
        timeout=g.timeout,
        speed=g.speed,
        force=g.force,
        calibration=calibration,
    )


@dataclass
class Drivers:
    """How each device is opened (the tests pass fakes)."""

    arm: Callable[[str, Sequence[float]], tuple[Any, Any]] = connect_ur
    """``(host, tcp) -> (control, receive)``: ur_rtde's interfaces."""
    camera: Callable[[RealSenseSettings], Any] = _camera
    """Settings → an unstarted camera (``start``/``stop``/``poll``/``wait``)."""
    gripper: Callable[[RobotConfig], Any] = _gripper
    """The config → an unconnected gripper (``connect``/``activate``/...)."""
    clock: Callable[[], float] = time.time
    sleep: Callable[[float], None] = time.sleep


def camera_settings(config: RobotConfig) -> RealSenseSettings:
    """``[camera]`` as the RealSense driver's settings."""
    c = config.camera
    return RealSenseSettings(
        width=c.width,
        height=c.height,
        fps=c.fps,
        depth=c.depth,
        serial=c.serial or None,
        timeout_s=c.timeout,
    )


class HardwareRobot:
    """An arm with its camera and gripper (:class:`~heapgrasp.robot.interfaces.Robot`)."""

    def __init__(self, arm: URArm, gripper: Any) -> None:
        self.arm = arm
        self.gripper = gripper

    @property
    def camera(self) -> Any:
        """The camera the arm carries."""
        return self.arm.camera

    @classmethod
    def connect(
        cls, config: RobotConfig, drivers: Drivers | None = None, *, activate: bool = True
    ) -> HardwareRobot:
        """Opens the camera, the gripper (activated unless ``activate`` is False) and the
        arm; whatever was opened is closed again if a later device fails."""
        config.require_hosts()  # before any device is touched
        d = drivers or Drivers()
        opened: list[Callable[[], None]] = []
        try:
            camera = d.camera(camera_settings(config))
            camera.start()
            opened.append(camera.stop)
            gripper = d.gripper(config)
            gripper.connect()
            opened.append(gripper.disconnect)
            if activate:
                gripper.activate(auto_calibrate=config.gripper.open_position is None)
            control, receive = d.arm(config.arm.host, config.arm.tcp)
            opened.append(control.disconnect)
            opened.append(receive.disconnect)
            arm = URArm(
                control,
                receive,
                camera,
                config,
                open_to=gripper.move,
                clock=d.clock,
                sleep=d.sleep,
            )
        except BaseException:
            for close in reversed(opened):
                try:
                    close()
                except Exception:
                    continue
            raise
        return cls(arm, gripper)

    def close(self) -> None:
        """Stops the arm and releases every device (best effort, never raises)."""
        for step in (
            self.arm.stop,
            self.arm.control.disconnect,
            self.arm.receive.disconnect,
            self.gripper.disconnect,
            self.camera.stop,
        ):
            try:
                step()
            except Exception:
                continue

    def __enter__(self) -> HardwareRobot:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
