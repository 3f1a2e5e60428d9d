"""An Intel RealSense as the loop's hand-eye :class:`~heapgrasp.robot.interfaces.Camera`:
RGB frames (and, for the VGN baseline, depth aligned to them) with host timestamps.

HEAPGrasp captures continuously while the arm moves (§V, eq. 8: 320×240 at 30 fps in
§VI-B), so every frame counts and each one needs the time it was taken on the clock the
arm's poses are recorded on (the host's, ``time.time``). :class:`RealSenseCamera`:

* streams colour as ``rgb8`` (and depth as ``z16``, aligned to colour with
  ``rs.align``) through ``pyrealsense2``, which is imported only when a camera is made
  (``pip install 'heapgrasp[robot]'``);
* keeps every frame the device delivers, in order, from the pipeline's frame callback;
  :meth:`~RealSenseCamera.poll` hands over all frames that arrived since the last call
  and :meth:`~RealSenseCamera.wait` the next one (librealsense's own ``poll_for_frames``
  keeps only the newest frameset, dropping the rest);
* stamps a frame with its device timestamp where librealsense gives it in the global
  (host-aligned) time domain, which it enables on every sensor that supports it, and
  otherwise with the host clock when the frame arrived
  (:attr:`~RealSenseCamera.arrival_times` records that);
* reads depth in metres as ``z16 × depth_scale``, the depth sensor's own scale (1 mm on
  the D400 series, 0.25 mm on the L515: never assumed);
* reads the colour stream's intrinsics into a :class:`~heapgrasp.geometry.camera.CameraSpec`
  (RealSense's principal point uses the same pixel-centre convention, so ``cx = ppx``)
  and keeps its distortion coefficients (about zero for the RealSense colour stream).

A camera that sends no frame within the timeout is
:class:`~heapgrasp.robot.errors.ConnectionLost`; a missing library, a mode the device
cannot stream or a malformed frame is :class:`~heapgrasp.robot.errors.DeviceError`.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from types import TracebackType
from typing import Any

import numpy as np
import numpy.typing as npt

from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.robot.errors import ConnectionLost, DeviceError

__all__ = ["FPS_CHOICES", "QUEUE_SECONDS", "CameraFrame", "RealSenseCamera", "RealSenseSettings"]

#: The frame rates the RealSense colour streams offer.
FPS_CHOICES = (6, 15, 30, 60)
#: How many seconds of frames are kept for :meth:`RealSenseCamera.poll` (older ones are
#: dropped and counted in :attr:`RealSenseCamera.dropped`).
QUEUE_SECONDS = 2.0

_EXTRA = "pip install 'heapgrasp[robot]'"


def _import_rs() -> Any:
    try:
        import pyrealsense2
    except ImportError as e:
        raise DeviceError(
            f"the RealSense camera needs pyrealsense2 ({_EXTRA}; on Linux it also needs the "
            f"libusb-1.0 system library): {e}"
        ) from e
    return pyrealsense2


@dataclass(frozen=True)
class RealSenseSettings:
    """Which streams to open.

    ``width`` × ``height`` is the colour mode (320×240 and 640×480 are HEAPGrasp's; any
    other mode the device lists works, one it lacks fails at
    :meth:`RealSenseCamera.start`); ``serial`` picks a device (None: the only one);
    ``timeout_s`` is how long without a frame counts as a lost camera.
    """

    width: int = 320
    height: int = 240
    fps: int = 30
    depth: bool = False
    serial: str | None = None
    timeout_s: float = 1.0

    def __post_init__(self) -> None:
        for name in ("width", "height", "fps"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or v <= 0:
                raise ValueError(f"RealSenseSettings.{name} must be an integer > 0, got {v!r}")
            object.__setattr__(self, name, int(v))
        if self.fps not in FPS_CHOICES:
            raise ValueError(
                f"RealSenseSettings.fps must be one of {FPS_CHOICES}, got {self.fps!r}"
            )
        if not isinstance(self.depth, bool | np.bool_):
            raise ValueError(f"RealSenseSettings.depth must be a bool, got {self.depth!r}")
        object.__setattr__(self, "depth", bool(self.depth))
        if self.serial is not None and not isinstance(self.serial, str):
            raise ValueError(f"RealSenseSettings.serial must be a string, got {self.serial!r}")
        if self.serial == "":
            object.__setattr__(self, "serial", None)
        t = self.timeout_s
        if (
            isinstance(t, bool)
            or not isinstance(t, int | float)
            or not (math.isfinite(t) and t > 0)
        ):
            raise ValueError(f"RealSenseSettings.timeout_s must be finite and > 0, got {t!r}")
        object.__setattr__(self, "timeout_s", float(t))


@dataclass
class CameraFrame:
    """One captured frame."""

    time: float
    """When it was taken, host clock (s): the device's global-time stamp, or the host's
    clock at its arrival (:attr:`RealSenseCamera.arrival_times`)."""
    rgb: npt.NDArray[np.uint8]
    """``(H, W, 3)`` colour, RGB order."""
    depth: npt.NDArray[np.float32] | None
    """``(H, W)`` depth aligned to ``rgb``, metres (0 where missing); None without depth."""
    number: int
    """The device's frame counter."""


class RealSenseCamera:
    """An Intel RealSense colour (and depth) camera; see the module docstring.

    Parameters
    ----------
    settings
        The streams to open.
    rs
        The ``pyrealsense2`` module (None: import it; tests pass a fake).
    clock
        The host clock (s) that stamps frames whose device timestamps are not in the
        global time domain.
    """

    def __init__(
        self,
        settings: RealSenseSettings = RealSenseSettings(),
        *,
        rs: Any = None,
        clock: Callable[[], float] = time.time,
    ) -> None:
        if not isinstance(settings, RealSenseSettings):
            raise ValueError(f"settings must be RealSenseSettings, got {settings!r}")
        self.settings = settings
        self._rs = _import_rs() if rs is None else rs
        self._clock = clock
        self._pipe: Any = None
        self._align: Any = None
        self._spec: CameraSpec | None = None
        self._distortion = np.zeros(5)
        self.distortion_model = "none"
        """librealsense's name of the colour stream's distortion model."""
        self.depth_scale: float | None = None
        """Metres per depth unit (None without depth)."""
        self.arrival_times = False
        """Whether some frame was stamped on arrival (its device timestamp was not in the
        global time domain)."""
        self.dropped = 0
        """Frames dropped because nobody collected them within :data:`QUEUE_SECONDS`."""
        self._info: dict[str, Any] = {}
        self._seen = 0
        capacity = max(2, math.ceil(QUEUE_SECONDS * settings.fps))
        self._frames: deque[tuple[float, Any]] = deque(maxlen=capacity)
        self._cond = threading.Condition()

    # -- streaming --------------------------------------------------------------------

    @property
    def name(self) -> str:
        """The device, for messages."""
        serial = self._info.get("serial") or self.settings.serial
        return f"RealSense {serial}" if serial else "RealSense"

    @property
    def started(self) -> bool:
        """Whether it is streaming."""
        return self._pipe is not None

    def start(self) -> None:
        """Opens the streams (a no-op when streaming) and reads the device's intrinsics,
        depth scale and identity."""
        if self._pipe is not None:
            return
        rs, s = self._rs, self.settings
        mode = f"colour {s.width}x{s.height} rgb8 at {s.fps} fps" + (
            " with z16 depth" if s.depth else ""
        )
        pipe = rs.pipeline()
        cfg = rs.config()
        if s.serial is not None:
            cfg.enable_device(s.serial)
        cfg.enable_stream(rs.stream.color, s.width, s.height, rs.format.rgb8, s.fps)
        if s.depth:
            # Depth at the device's own resolution for this rate; rs.align maps it to colour.
            cfg.enable_stream(rs.stream.depth, rs.format.z16, s.fps)
        with self._cond:
            self._frames.clear()
        try:
            profile = pipe.start(cfg, self._on_frame)
        except RuntimeError as e:
            raise DeviceError(f"{self.name} cannot stream {mode}: {e}") from e
        try:
            self._configure(profile, mode)
        except BaseException:
            _stop_quietly(pipe)
            raise
        self._pipe = pipe

    def _configure(self, profile: Any, mode: str) -> None:
        rs, s = self._rs, self.settings
        device = profile.get_device()
        info: dict[str, Any] = {}
        for key, field in (
            ("serial", rs.camera_info.serial_number),
            ("name", rs.camera_info.name),
            ("firmware", rs.camera_info.firmware_version),
        ):
            info[key] = str(device.get_info(field)) if device.supports(field) else None
        self._info = info
        for sensor in device.query_sensors():
            if sensor.supports(rs.option.global_time_enabled):
                try:
                    sensor.set_option(rs.option.global_time_enabled, 1.0)
                except RuntimeError:
                    pass  # then its frames are stamped on arrival
        if s.depth:
            scale = float(device.first_depth_sensor().get_depth_scale())
            if not (math.isfinite(scale) and scale > 0):
                raise DeviceError(f"{self.name} reports depth scale {scale!r} m per unit")
            self.depth_scale = scale
            self._align = rs.align(rs.stream.color)
        intr = profile.get_stream(rs.stream.color).as_video_stream_profile().get_intrinsics()
        if (int(intr.width), int(intr.height)) != (s.width, s.height):
            raise DeviceError(
                f"{self.name} opened colour {intr.width}x{intr.height}, not the "
                f"{s.width}x{s.height} asked for ({mode})"
            )
        try:
            self._spec = CameraSpec(
                width=int(intr.width),
                height=int(intr.height),
                fx=float(intr.fx),
                fy=float(intr.fy),
                cx=float(intr.ppx),
                cy=float(intr.ppy),
                fps=float(s.fps),
            )
        except ValueError as e:
            raise DeviceError(f"{self.name} reports unusable colour intrinsics: {e}") from e
        self._distortion = np.asarray(list(intr.coeffs), dtype=np.float64)
        self.distortion_model = str(intr.model.name)

    def _on_frame(self, frame: Any) -> None:
        """librealsense's callback (its own thread): stamp, keep, queue."""
        arrival = self._clock()
        frame.keep()
        with self._cond:
            if len(self._frames) == self._frames.maxlen:
                self.dropped += 1
            self._frames.append((arrival, frame))
            self._cond.notify_all()

    def stop(self) -> None:
        """Stops streaming (a no-op when stopped); the frames not collected are dropped."""
        pipe, self._pipe = self._pipe, None
        if pipe is not None:
            _stop_quietly(pipe)
        with self._cond:
            self._frames.clear()

    def __enter__(self) -> RealSenseCamera:
        self.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()

    # -- the camera -------------------------------------------------------------------

    @property
    def spec(self) -> CameraSpec:
        """The colour stream's intrinsics, size and rate (known once started)."""
        if self._spec is None:
            raise DeviceError(f"{self.name} is not started: call start() first")
        return self._spec

    @property
    def depth(self) -> bool:
        """Whether frames carry depth."""
        return self.settings.depth

    @property
    def distortion(self) -> npt.NDArray[np.float64]:
        """The colour stream's distortion coefficients (``k1 k2 p1 p2 k3`` of the
        :attr:`distortion_model`, Brown-Conrady or its inverse)."""
        return self._distortion.copy()

    def _require_started(self) -> None:
        if self._pipe is None:
            raise DeviceError(f"{self.name} is not started: call start() first")

    def wait(self, timeout: float | None = None) -> CameraFrame:
        """The next frame not yet handed over (blocking); :class:`ConnectionLost` if none
        comes within ``timeout`` s (None: the settings' ``timeout_s``)."""
        self._require_started()
        limit = self.settings.timeout_s if timeout is None else float(timeout)
        if not (math.isfinite(limit) and limit > 0):
            raise ValueError(f"timeout must be finite and > 0 s, got {timeout!r}")
        deadline = time.monotonic() + limit
        while True:
            with self._cond:
                while not self._frames:
                    left = deadline - time.monotonic()
                    if left <= 0:
                        raise ConnectionLost(f"{self.name}: no frame within {limit} s")
                    self._cond.wait(left)
                arrival, raw = self._frames.popleft()
            frame = self._convert(arrival, raw)
            if frame is not None:
                return frame

    def poll(self) -> list[CameraFrame]:
        """Every frame that arrived since the last call (or :meth:`wait`), oldest first;
        never blocks."""
        self._require_started()
        with self._cond:
            raws = list(self._frames)
            self._frames.clear()
        frames = [self._convert(arrival, raw) for arrival, raw in raws]
        return [f for f in frames if f is not None]

    def _convert(self, arrival: float, raw: Any) -> CameraFrame | None:
        """A delivered frame as a :class:`CameraFrame`; None for a frameset that lacks a
        stream asked for (the syncer sends those while the streams settle)."""
        rs, s = self._rs, self.settings
        depth_frame = None
        if raw.is_frameset():
            frameset = raw.as_frameset()
            if self._align is not None:
                frameset = self._align.process(frameset)
            color = frameset.get_color_frame()
            if s.depth:
                depth_frame = frameset.get_depth_frame()
                if not depth_frame:
                    return None
        else:
            if s.depth:
                return None
            color = raw
        if not color:
            return None
        rgb = np.array(np.asanyarray(color.get_data()), dtype=np.uint8, copy=True)
        if rgb.shape != (s.height, s.width, 3):
            raise DeviceError(
                f"{self.name} sent a colour frame of shape {rgb.shape}, expected "
                f"({s.height}, {s.width}, 3) rgb8"
            )
        depth: npt.NDArray[np.float32] | None = None
        if depth_frame is not None:
            z = np.asanyarray(depth_frame.get_data())
            if z.shape != (s.height, s.width) or z.dtype != np.uint16:
                raise DeviceError(
                    f"{self.name} sent an aligned depth frame of shape {z.shape} and type "
                    f"{z.dtype}, expected ({s.height}, {s.width}) uint16 (z16)"
                )
            assert self.depth_scale is not None
            depth = (z.astype(np.float64) * self.depth_scale).astype(np.float32)
        if color.get_frame_timestamp_domain() == rs.timestamp_domain.global_time:
            t = float(color.get_timestamp()) / 1000.0
        else:
            t = float(arrival)
            self.arrival_times = True
        self._seen += 1
        return CameraFrame(time=t, rgb=rgb, depth=depth, number=int(color.get_frame_number()))

    def describe(self) -> dict[str, Any]:
        """What ``heapgrasp robot check`` prints: the device, the stream, the intrinsics,
        the depth scale and the timestamps' source."""
        self._require_started()
        s, spec = self.settings, self.spec
        return {
            **self._info,
            "stream": f"{s.width}x{s.height} rgb8 at {s.fps} fps"
            + (" + z16 depth" if s.depth else ""),
            "intrinsics": {
                "fx": spec.fx,
                "fy": spec.fy,
                "cx": spec.cx,
                "cy": spec.cy,
                "model": self.distortion_model,
                "coeffs": [float(c) for c in self._distortion],
            },
            "depth_scale": self.depth_scale,
            "timestamps": (
                "arrival (host clock)"
                if self.arrival_times
                else ("global time" if self._seen else "unknown (no frame yet)")
            ),
            "dropped": self.dropped,
        }

    def __repr__(self) -> str:
        state = "streaming" if self.started else "stopped"
        return f"RealSenseCamera({self.name}, {state}, {self.settings})"


def _stop_quietly(pipe: Any) -> None:
    try:
        pipe.stop()
    except RuntimeError:
        pass
