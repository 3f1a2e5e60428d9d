"""The real robot's configuration: one TOML file (``robot.toml``), checked whole on load.

Tables (``docs/real_robot.md`` lists every key with its default)::

    [arm]          # the UR e-Series arm, over RTDE (heapgrasp.robot.ur)
    host = "192.168.1.10"
    [workspace]    # the safety box, in the workspace (world) frame, metres
    [limits]       # speed and acceleration caps, checked before any command
    [camera]       # the RealSense (heapgrasp.robot.realsense)
    [gripper]      # the Robotiq 2F-140 over the URCap socket (heapgrasp.robot.robotiq)
    [calibration]  # written by `heapgrasp robot calibrate`
    [networks]     # the segmentation, view and grasp networks' files
    [method]       # any heapgrasp.loop.config.RunConfig setting

Frames. The *world* is the workspace frame of the loop: the scene cube's minimum corner
on the table, z up (:class:`heapgrasp.geometry.grid.GridFrame`). The arm's *base* frame
is the controller's; ``calibration.world2base`` places the world in it. The *TCP* is
the controller's tool centre point, set from ``arm.tcp`` (flange frame; z along the
approach, the fingers closing along y, as every grasp pose in the package);
``calibration.cam2tcp`` is the camera's pose in it (OpenCV axes).

Every error is a :class:`~heapgrasp.robot.errors.RobotConfigError` naming the file, the
key and the value; unknown keys are errors (a typo never silently falls back to a
default).
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from heapgrasp.robot.errors import RobotConfigError

__all__ = [
    "ArmSettings",
    "CalibrationSettings",
    "CameraSettings",
    "GripperSettings",
    "Limits",
    "NetworkSettings",
    "RobotConfig",
    "Workspace",
    "rigid",
]

F64 = npt.NDArray[np.float64]


def rigid(name: str, value: Any) -> F64:
    """``value`` as a finite rigid ``(4, 4)`` transform; :class:`RobotConfigError` naming
    ``name`` otherwise."""
    try:
        m = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise RobotConfigError(f"{name} must be a 4x4 matrix of numbers, got {value!r}") from None
    if m.shape != (4, 4) or not np.isfinite(m).all():
        raise RobotConfigError(f"{name} must be a finite 4x4 matrix, got shape {m.shape}")
    r = m[:3, :3]
    if (
        np.abs(r.T @ r - np.eye(3)).max() > 1e-5
        or np.linalg.det(r) < 0
        or np.abs(m[3] - [0, 0, 0, 1]).max() > 1e-9
    ):
        raise RobotConfigError(f"{name} must be a rigid transform (rotation + translation)")
    return m


def _check_positive(section: str, obj: Any, names: Sequence[str]) -> None:
    for name in names:
        v = getattr(obj, name)
        if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
            raise RobotConfigError(f"[{section}] {name} must be a number > 0, got {v!r}")


def _at_most(section: str, obj: Any, bounds: Mapping[str, tuple[float, str]]) -> None:
    """Each named value within the hardware's documented range: ``name: (most, why)``; a
    value above it is refused naming the table, the key, the value and the reason."""
    for name, (most, why) in bounds.items():
        value = getattr(obj, name)
        if value > most:
            raise RobotConfigError(
                f"[{section}] {name} must be at most {most:g} ({why}), got {value!r}"
            )


@dataclass(frozen=True)
class ArmSettings:
    """``[arm]``: the UR arm over RTDE."""

    host: str = ""
    """The controller's address (the arm must be in remote-control mode)."""
    tcp: tuple[float, ...] = (0.0, 0.0, 0.2, 0.0, 0.0, 0.0)
    """The TCP in the flange frame, ``[x, y, z, rx, ry, rz]`` (m, rotation vector), set on
    the controller at connection. The 2F-140's fingertip pads are ~0.2 m from the flange."""
    park: tuple[float, ...] = (0.0, -1.5708, 1.5708, -1.5708, -1.5708, 0.0)
    """Joint positions (rad) where the arm waits out of the camera's view of the scene."""
    servo_rate: float = 125.0
    """Rate (Hz) at which the camera paths are streamed with ``servoL``."""
    lookahead: float = 0.1
    """``servoL``'s lookahead time (s, 0.03-0.2)."""
    gain: float = 300.0
    """``servoL``'s proportional gain (100-2000)."""
    contact_force: float = 25.0
    """TCP force (N) above which a motion that stops on contact stops."""
    travel_height: float = 0.25
    """Height above the table (m, world z) at which the TCP travels to a pre-grasp pose."""
    settle: float = 0.1
    """Time (s) the arm rests before a still frame is taken."""
    max_slowdown: float = 6.0
    """A camera path is slowed until the TCP keeps ``[limits]`` (only its timing
    changes); a path that would need to go more than this many times slower is refused."""

    def __post_init__(self) -> None:
        if not isinstance(self.host, str):
            raise RobotConfigError(f"[arm] host must be a string, got {self.host!r}")
        for name, n in (("tcp", 6), ("park", 6)):
            v = getattr(self, name)
            if len(v) != n or not all(isinstance(x, int | float) and math.isfinite(x) for x in v):
                raise RobotConfigError(f"[arm] {name} must be {n} finite numbers, got {list(v)}")
        _check_positive(
            "arm",
            self,
            ("servo_rate", "lookahead", "gain", "contact_force", "travel_height", "max_slowdown"),
        )
        if self.max_slowdown < 1:
            raise RobotConfigError(f"[arm] max_slowdown must be >= 1, got {self.max_slowdown}")
        if not 0.03 <= self.lookahead <= 0.2:
            raise RobotConfigError(
                f"[arm] lookahead must be in [0.03, 0.2] s, got {self.lookahead}"
            )
        if not 100 <= self.gain <= 2000:
            raise RobotConfigError(f"[arm] gain must be in [100, 2000], got {self.gain}")
        if not 10 <= self.servo_rate <= 500:
            raise RobotConfigError(
                f"[arm] servo_rate must be in [10, 500] Hz, got {self.servo_rate}"
            )
        if not (isinstance(self.settle, int | float) and 0 <= self.settle <= 5):
            raise RobotConfigError(f"[arm] settle must be in [0, 5] s, got {self.settle!r}")
        _at_most(
            "arm",
            self,
            {
                "contact_force": (150.0, "N; a UR5e's force sensing and the 2F-140's 125 N grip"),
                "travel_height": (1.0, "m; a UR5e reaches 0.85 m"),
                "max_slowdown": (100.0, "times slower"),
            },
        )
        offset = math.hypot(*self.tcp[:3])
        if offset > 0.5:
            raise RobotConfigError(
                f"[arm] tcp is {offset:.3g} m from the flange; at most 0.5 m (a tool that long "
                f"is not a gripper), got {list(self.tcp)}"
            )
        if math.hypot(*self.tcp[3:]) > 2 * math.pi + 1e-9:
            raise RobotConfigError(
                f"[arm] tcp's rotation vector is longer than 2π: {list(self.tcp)}"
            )
        if any(abs(q) > 2 * math.pi + 1e-9 for q in self.park):
            raise RobotConfigError(
                f"[arm] park must keep every joint within ±2π rad (a UR5e's range), got "
                f"{list(self.park)}"
            )


@dataclass(frozen=True)
class Workspace:
    """``[workspace]``: the box (world frame, m) that the TCP and the camera never leave.
    Every command is checked against it before it is sent."""

    min: tuple[float, ...] = (-0.25, -0.55, -0.01)
    max: tuple[float, ...] = (0.55, 0.55, 0.75)
    bin: tuple[float, ...] = (0.15, -0.3, 0.25)
    """Where a held object is released: the TCP position over the bin (pointing down)."""

    def __post_init__(self) -> None:
        for name in ("min", "max", "bin"):
            v = getattr(self, name)
            if len(v) != 3 or not all(isinstance(x, int | float) and math.isfinite(x) for x in v):
                raise RobotConfigError(f"[workspace] {name} must be 3 finite numbers, got {v!r}")
        if not all(a < b for a, b in zip(self.min, self.max, strict=True)):
            raise RobotConfigError(
                f"[workspace] min {list(self.min)} must be below max {list(self.max)} on every axis"
            )
        if not self.contains([self.bin]).all():
            raise RobotConfigError(f"[workspace] bin {list(self.bin)} is outside the box")
        for name in ("min", "max"):
            if any(abs(x) > 1.5 for x in getattr(self, name)):
                raise RobotConfigError(
                    f"[workspace] {name} must lie within 1.5 m of the workspace frame (a UR5e "
                    f"reaches 0.85 m), got {list(getattr(self, name))}"
                )

    def bin_pose(self) -> npt.NDArray[np.float64]:
        """The TCP pose over the bin: at :attr:`bin`, pointing down."""
        m = np.diag([1.0, -1.0, -1.0, 1.0])
        m[:3, 3] = self.bin
        return m

    def contains(self, points: npt.ArrayLike) -> npt.NDArray[np.bool_]:
        """Which of the ``(N, 3)`` world points lie inside the box (bounds included)."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        lo, hi = np.asarray(self.min), np.asarray(self.max)
        return np.asarray(((p >= lo) & (p <= hi)).all(axis=1))


@dataclass(frozen=True)
class Limits:
    """``[limits]``: caps no command may exceed (checked before it is sent)."""

    tool_speed: float = 0.25
    """TCP and camera linear speed (m/s)."""
    tool_acceleration: float = 1.2
    """TCP linear acceleration (m/s²)."""
    tool_rotation_speed: float = 3.0
    """TCP angular speed (rad/s)."""
    joint_speed: float = 1.0
    """Every joint's speed (rad/s)."""
    joint_acceleration: float = 1.4
    """Every joint's acceleration (rad/s²)."""

    def __post_init__(self) -> None:
        names = [f.name for f in dataclasses.fields(self)]
        _check_positive("limits", self, names)
        if self.tool_speed > 1.0:
            raise RobotConfigError(
                f"[limits] tool_speed {self.tool_speed} m/s is above 1 m/s; heapgrasp refuses "
                "caps that high near a scene"
            )
        _at_most(
            "limits",
            self,
            {
                "tool_acceleration": (15.0, "m/s²; a UR5e's tool tops out near 15"),
                "tool_rotation_speed": (math.pi, "rad/s; a UR5e's joints turn at most π rad/s"),
                "joint_speed": (math.pi, "rad/s; a UR5e's joints turn at most π rad/s"),
                "joint_acceleration": (15.0, "rad/s²"),
            },
        )


@dataclass(frozen=True)
class CameraSettings:
    """``[camera]``: the RealSense's colour (and depth) streams."""

    width: int = 320
    height: int = 240
    fps: int = 30
    depth: bool = False
    """Stream depth aligned to colour (only the ``vgn`` baseline needs it)."""
    serial: str = ""
    """Which device (empty: the only one connected)."""
    timeout: float = 1.0
    """Seconds without a frame before the camera counts as lost."""

    def __post_init__(self) -> None:
        if (self.width, self.height) not in ((320, 240), (640, 480), (424, 240), (848, 480)):
            raise RobotConfigError(
                f"[camera] width x height {self.width}x{self.height} is not a colour mode "
                "heapgrasp supports "
                "(320x240, 424x240, 640x480, 848x480)"
            )
        if self.fps not in (6, 15, 30, 60):
            raise RobotConfigError(f"[camera] fps must be 6, 15, 30 or 60, got {self.fps!r}")
        _check_positive("camera", self, ("timeout",))
        _at_most("camera", self, {"timeout": (60.0, "s without a frame")})


@dataclass(frozen=True)
class GripperSettings:
    """``[gripper]``: the Robotiq 2F-140 over the UR's Robotiq URCap socket."""

    host: str = ""
    """Empty: the arm's host (the URCap serves on the controller)."""
    port: int = 63352
    speed: int = 255
    """Finger speed register (0-255)."""
    force: int = 100
    """Grip force register (0-255)."""
    timeout: float = 2.0
    """Seconds to wait for a reply before the connection counts as lost."""
    open_position: int | None = None
    """Register of the fully open fingers (None: measured at activation)."""
    closed_position: int | None = None
    """Register of the fully closed fingers (None: measured at activation)."""

    def __post_init__(self) -> None:
        if not 1 <= self.port <= 65535:
            raise RobotConfigError(f"[gripper] port must be in [1, 65535], got {self.port}")
        for name in ("speed", "force", "open_position", "closed_position"):
            v = getattr(self, name)
            whole = isinstance(v, int) and not isinstance(v, bool)
            if v is not None and not (whole and 0 <= v <= 255):
                raise RobotConfigError(
                    f"[gripper] {name} must be an integer in [0, 255], got {v!r}"
                )
        _check_positive("gripper", self, ("timeout",))
        _at_most("gripper", self, {"timeout": (60.0, "s to wait for a reply")})


@dataclass(frozen=True)
class CalibrationSettings:
    """``[calibration]``: the hand-eye extrinsic and the workspace frame (written by
    ``heapgrasp robot calibrate``)."""

    cam2tcp: F64 | None = None
    """The camera's pose in the TCP frame (OpenCV axes); None: not calibrated."""
    world2base: F64 | None = None
    """The workspace (world) frame in the arm's base frame; None: not calibrated."""
    report: Mapping[str, Any] = field(default_factory=dict)
    """What the calibration measured (method, residuals, board, date), kept as written."""

    @property
    def done(self) -> bool:
        """Whether both transforms are known."""
        return self.cam2tcp is not None and self.world2base is not None


@dataclass(frozen=True)
class NetworkSettings:
    """``[networks]``: the networks' ONNX files (empty: the shipped one, where one ships)."""

    segmentation: str = ""
    """The 4-class segmentation network (``heapgrasp seg train``); no default ships: a
    real camera needs one trained on its own images."""
    view: str = ""
    grasp: str = ""


_TABLES = ("arm", "workspace", "limits", "camera", "gripper", "calibration", "networks", "method")


def _table(cls: type[Any], section: str, data: Any, source: str) -> Any:
    if not isinstance(data, dict):
        raise RobotConfigError(f"{source}: [{section}] must be a table, got {data!r}")
    known = {f.name: f for f in dataclasses.fields(cls)}
    kwargs: dict[str, Any] = {}
    for key, value in data.items():
        if key not in known:
            raise RobotConfigError(
                f"{source}: [{section}] unknown key {key!r} (known: {', '.join(known)})"
            )
        default = known[key].default
        if isinstance(value, list):
            value = tuple(value)
        if isinstance(default, float) and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        if isinstance(default, tuple) and isinstance(value, tuple):
            value = tuple(
                float(x) if isinstance(x, int) and not isinstance(x, bool) else x for x in value
            )
        expected = (
            type(default) if default is not None and default is not dataclasses.MISSING else None
        )
        # a bool is an int to Python, never to a robot.toml: `port = true` is refused
        wrong_bool = isinstance(value, bool) and expected is not None and expected is not bool
        if expected is not None and (wrong_bool or not isinstance(value, expected)):
            raise RobotConfigError(
                f"{source}: [{section}] {key} must be of type {expected.__name__}, got {value!r}"
            )
        kwargs[key] = value
    try:
        return cls(**kwargs)
    except RobotConfigError as exc:
        raise RobotConfigError(f"{source}: {exc}") from None
    except (TypeError, ValueError) as exc:
        raise RobotConfigError(f"{source}: [{section}] {exc}") from None


def _calibration(data: Any, source: str) -> CalibrationSettings:
    if not isinstance(data, dict):
        raise RobotConfigError(f"{source}: [calibration] must be a table, got {data!r}")
    data = dict(data)
    transforms: dict[str, F64 | None] = {}
    for key in ("cam2tcp", "world2base"):
        value = data.pop(key, None)
        try:
            transforms[key] = None if value is None else rigid(f"[calibration] {key}", value)
        except RobotConfigError as exc:
            raise RobotConfigError(f"{source}: {exc}") from None
    return CalibrationSettings(transforms["cam2tcp"], transforms["world2base"], data)


@dataclass(frozen=True)
class RobotConfig:
    """A whole ``robot.toml`` (see the module docstring)."""

    arm: ArmSettings = field(default_factory=ArmSettings)
    workspace: Workspace = field(default_factory=Workspace)
    limits: Limits = field(default_factory=Limits)
    camera: CameraSettings = field(default_factory=CameraSettings)
    gripper: GripperSettings = field(default_factory=GripperSettings)
    calibration: CalibrationSettings = field(default_factory=CalibrationSettings)
    networks: NetworkSettings = field(default_factory=NetworkSettings)
    method: Mapping[str, Any] = field(default_factory=dict)
    """The loop's settings as written; ``heapgrasp.real.stages.run_config`` checks them
    (the loop's configuration lives in a layer above this one)."""
    source: str = "robot config"
    """Where it was read from (for messages)."""

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], *, source: str = "robot config") -> RobotConfig:
        """A config from parsed TOML; every problem raises :class:`RobotConfigError`."""
        unknown = [k for k in data if k not in _TABLES]
        if unknown:
            raise RobotConfigError(
                f"{source}: unknown table or key {unknown[0]!r} (tables: {', '.join(_TABLES)})"
            )
        method = data.get("method", {})
        if not isinstance(method, dict):
            raise RobotConfigError(f"{source}: [method] must be a table, got {method!r}")
        config = cls(
            arm=_table(ArmSettings, "arm", data.get("arm", {}), source),
            workspace=_table(Workspace, "workspace", data.get("workspace", {}), source),
            limits=_table(Limits, "limits", data.get("limits", {}), source),
            camera=_table(CameraSettings, "camera", data.get("camera", {}), source),
            gripper=_table(GripperSettings, "gripper", data.get("gripper", {}), source),
            calibration=_calibration(data.get("calibration", {}), source),
            networks=_table(NetworkSettings, "networks", data.get("networks", {}), source),
            method=dict(method),
            source=source,
        )
        return config

    @classmethod
    def load(cls, path: str | Path) -> RobotConfig:
        """Reads and checks ``robot.toml``."""
        p = Path(path)
        try:
            data = tomllib.loads(p.read_text())
        except FileNotFoundError:
            raise RobotConfigError(f"robot config not found: {p}") from None
        except tomllib.TOMLDecodeError as exc:
            raise RobotConfigError(f"{p}: not valid TOML: {exc}") from None
        except UnicodeDecodeError as exc:  # a binary file
            raise RobotConfigError(f"{p}: not a text file (TOML is UTF-8 text): {exc}") from None
        except OSError as exc:  # a directory, no permission
            raise RobotConfigError(f"{p}: cannot be read: {exc}") from None
        return cls.from_mapping(data, source=str(p))

    @property
    def gripper_host(self) -> str:
        """The gripper's address (the arm's unless set)."""
        return self.gripper.host or self.arm.host

    def require_hosts(self, devices: tuple[str, ...] = ("arm", "gripper")) -> None:
        """:class:`RobotConfigError` naming the key to set where ``devices`` (``arm``,
        ``gripper``) have no address, before anything is contacted: nothing is connected
        to that the user did not name."""
        if "arm" in devices and not self.arm.host.strip():
            raise RobotConfigError(
                f"{self.source}: [arm] host is empty: set it to your UR controller's "
                "address (the gripper's URCap answers there too, unless [gripper] host "
                "is set)"
            )
        if "gripper" in devices and not self.gripper_host.strip():
            raise RobotConfigError(
                f"{self.source}: the gripper has no address: set [arm] host to your UR "
                "controller's (its URCap serves the gripper), or [gripper] host"
            )
