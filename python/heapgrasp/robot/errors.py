"""What can go wrong on real hardware, as exception types the loop and the CLI catch.

Every one is a :class:`RobotError` (a :class:`heapgrasp.HeapgraspError`, so a
``ValueError``): the command line prints it and exits 1, after keeping everything
recorded so far. Nothing here needs a driver library installed.
"""

from __future__ import annotations

from heapgrasp import HeapgraspError

__all__ = [
    "ConnectionLost",
    "DeviceError",
    "ProtectiveStop",
    "RobotConfigError",
    "RobotError",
    "SafetyError",
]


class RobotError(HeapgraspError):
    """A real robot (arm, camera, gripper) failed or refused; the run stops."""


class RobotConfigError(RobotError):
    """The robot configuration (``robot.toml``) is invalid: names the key and the value."""


class SafetyError(RobotError):
    """A command was refused before anything was sent: a pose outside the configured
    workspace box, or a speed or acceleration above the configured caps."""


class ProtectiveStop(RobotError):
    """The arm's controller stopped the motion (protective or emergency stop)."""


class ConnectionLost(RobotError):
    """A device stopped answering, or closed the connection."""


class DeviceError(RobotError):
    """A device answered, but not as expected (a missing driver library, a bad reply, a
    stream that cannot be configured)."""
