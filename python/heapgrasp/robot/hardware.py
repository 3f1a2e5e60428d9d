"""The real robot assembled from ``robot.toml``: a UR arm, a RealSense and a Robotiq 2F-140.

:class:`HardwareRobot` is the loop's :class:`~heapgrasp.robot.interfaces.Robot` on
hardware. :meth:`HardwareRobot.connect` opens the three devices in turn (camera, gripper,
arm) and closes what it opened if a later one fails; :meth:`HardwareRobot.close` stops
the arm and releases everything. The drivers are built by :class:`Drivers`, whose
factories the tests replace with fakes.

``activate=False`` (the dry run) connects the gripper without activating it: activation
moves the fingers through their whole stroke, and a dry run moves nothing.

A rehearsal (``heapgrasp robot ... --sim``, :mod:`heapgrasp.sim.rehearsal`) passes drivers
whose devices are the simulator's: :attr:`Drivers.scene` then says what only a simulator
knows (each frame's exact silhouette, what happened to the objects), and no host is
needed.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from types import TracebackType
from typing import Any, Protocol, runtime_checkable

from heapgrasp.geometry.gripper import GRIPPERS, ROBOTIQ_2F140, GripperGeometry
from heapgrasp.perception.segmenters import MaskSource
from heapgrasp.robot.config import RobotConfig
from heapgrasp.robot.realsense import RealSenseCamera, RealSenseSettings
from heapgrasp.robot.robotiq import Robotiq2F140, WidthCalibration
from heapgrasp.robot.ur import URArm, connect_ur

__all__ = ["Drivers", "HardwareRobot", "SimulatedScene", "camera_settings", "hand_name"]


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


@runtime_checkable
class SimulatedScene(MaskSource, Protocol):
    """What a rehearsal's drivers know and hardware cannot: the exact silhouette of every
    frame their camera delivered (:meth:`silhouette`, read by the simulator's segmenters
    and recorded with the frames), and what became of the objects (:meth:`report`)."""

    def report(self) -> dict[str, Any]:
        """The scene's truth now: objects placed, removed, left (plain data)."""
        ...


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
    hand: GripperGeometry = ROBOTIQ_2F140
    """The shape of the gripper these drivers open (what the planners plan for)."""
    scene: SimulatedScene | None = None
    """A rehearsal's scene truth; None on hardware."""


def hand_name(hand: GripperGeometry) -> str:
    """The name of ``hand`` in :data:`~heapgrasp.geometry.gripper.GRIPPERS` (``custom``
    where it is none of them)."""
    return next((name for name, g in GRIPPERS.items() if g == hand), "custom")


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
        d = drivers or Drivers()
        if d.scene is None:
            config.require_hosts()  # before any device is touched
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
