"""A fake ``pyrealsense2`` module: the subset :mod:`heapgrasp.robot.realsense` uses.

:class:`FakeRealSense` is a module-like object (pass it as ``rs=``) whose attributes carry
pyrealsense2's names — ``pipeline``, ``config``, ``align``, the enums ``stream``,
``format``, ``option``, ``camera_info``, ``timestamp_domain``, ``distortion``, the frame,
profile, device and sensor classes — and nothing else public except the test controls
listed in :data:`CONTROLS`. ``test_realsense.py`` checks that every other public name,
and every public attribute of its classes and enums, exists on the installed
``pyrealsense2`` 2.59, so the driver cannot lean on anything the real module lacks.

Frames come from ``render(t) -> (rgb uint8 (H, W, 3), depth_m float32 (H, W) | None)`` at
``t = clock()``. Started with a callback, the pipeline delivers composite frames (colour,
and raw z16 depth at twice the colour resolution that only ``align`` maps back to colour)
from a thread at the stream's rate while :attr:`FakeRealSense.delivering` is true, or
synchronously through :meth:`FakeRealSense.emit`. Timestamps are in ``domain``:
``global_time`` stamps ``clock()`` in ms, the others a device clock unrelated to the host.
"""

from __future__ import annotations

import enum
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

Render = Callable[[float], tuple[npt.NDArray[np.uint8], npt.NDArray[np.float32] | None]]

#: The fake's test controls: names the real module does not have.
CONTROLS = frozenset(
    {
        "auto",
        "clock",
        "coeffs",
        "delivering",
        "depth_scale",
        "domain",
        "emit",
        "firmware",
        "modes",
        "model_name",
        "options_set",
        "pipelines",
        "render",
        "serial",
        "start_error",
    }
)


class stream(enum.Enum):
    color = 2
    depth = 1


class format(enum.Enum):
    rgb8 = 5
    z16 = 1


class timestamp_domain(enum.Enum):
    hardware_clock = 0
    system_time = 1
    global_time = 2


class option(enum.Enum):
    global_time_enabled = 53


class camera_info(enum.Enum):
    name = 0
    serial_number = 1
    firmware_version = 2


class distortion(enum.Enum):
    none = 0
    inverse_brown_conrady = 2
    brown_conrady = 4


class intrinsics:
    width: int = 0
    height: int = 0
    ppx: float = 0.0
    ppy: float = 0.0
    fx: float = 0.0
    fy: float = 0.0
    model: distortion = distortion.none
    coeffs: list[float] = [0.0] * 5


class frame:
    """A colour or depth frame (``video_frame``/``depth_frame`` share it)."""

    def __init__(
        self, data: npt.NDArray[Any], ts_ms: float, domain: timestamp_domain, number: int
    ) -> None:
        self._data = data
        self._ts = ts_ms
        self._domain = domain
        self._number = number
        self._kept = False

    def __bool__(self) -> bool:
        return True

    def get_data(self) -> npt.NDArray[Any]:
        return self._data

    def get_timestamp(self) -> float:
        return self._ts

    def get_frame_timestamp_domain(self) -> timestamp_domain:
        return self._domain

    def get_frame_number(self) -> int:
        return self._number

    def keep(self) -> None:
        self._kept = True

    def is_frameset(self) -> bool:
        return False


video_frame = frame
depth_frame = frame


class _Empty:
    def __bool__(self) -> bool:
        return False


class composite_frame(frame):
    def __init__(self, color: frame, depth: frame | None, *, aligned: bool = False) -> None:
        super().__init__(color._data, color._ts, color._domain, color._number)
        self._color = color
        self._depth = depth
        self._aligned = aligned

    def is_frameset(self) -> bool:
        return True

    def as_frameset(self) -> composite_frame:
        return self

    def get_color_frame(self) -> frame:
        return self._color

    def get_depth_frame(self) -> frame:
        return self._depth if self._depth is not None else _Empty()  # type: ignore[return-value]

    def size(self) -> int:
        return 1 if self._depth is None else 2


class align:
    def __init__(self, align_to: stream) -> None:
        if align_to is not stream.color:
            raise RuntimeError("the fake aligns to colour only")

    def process(self, frames: composite_frame) -> composite_frame:
        if frames._depth is None or frames._aligned:
            return frames
        z = frames._depth._data[::2, ::2].copy()  # the raw depth is 2x the colour size
        d = frames._depth
        return composite_frame(frames._color, frame(z, d._ts, d._domain, d._number), aligned=True)


class stream_profile:
    def __init__(self, intr: intrinsics) -> None:
        self._intr = intr

    def as_video_stream_profile(self) -> video_stream_profile:
        return video_stream_profile(self._intr)


class video_stream_profile(stream_profile):
    def get_intrinsics(self) -> intrinsics:
        return self._intr


class sensor:
    def __init__(self, fake: FakeRealSense) -> None:
        self._fake = fake

    def supports(self, what: option | camera_info) -> bool:
        return what is option.global_time_enabled

    def set_option(self, what: option, value: float) -> None:
        if not self.supports(what):
            raise RuntimeError(f"option {what} not supported")
        self._fake.options_set.append((what.name, float(value)))


class depth_sensor(sensor):
    def get_depth_scale(self) -> float:
        return self._fake.depth_scale


class device:
    def __init__(self, fake: FakeRealSense) -> None:
        self._fake = fake

    def supports(self, info: camera_info) -> bool:
        return isinstance(info, camera_info)

    def get_info(self, info: camera_info) -> str:
        return {
            camera_info.name: self._fake.model_name,
            camera_info.serial_number: self._fake.serial,
            camera_info.firmware_version: self._fake.firmware,
        }[info]

    def query_sensors(self) -> list[sensor]:
        return [depth_sensor(self._fake), sensor(self._fake)]

    def first_depth_sensor(self) -> depth_sensor:
        return depth_sensor(self._fake)


class pipeline_profile:
    def __init__(self, fake: FakeRealSense, intr: intrinsics) -> None:
        self._fake = fake
        self._intr = intr

    def get_device(self) -> device:
        return device(self._fake)

    def get_stream(self, stream_type: stream, stream_index: int = -1) -> stream_profile:
        if stream_type is not stream.color:
            raise RuntimeError("the fake profiles colour only")
        return stream_profile(self._intr)


class config:
    def __init__(self) -> None:
        self._serial: str | None = None
        self._streams: dict[stream, tuple[Any, ...]] = {}

    def enable_device(self, serial: str) -> None:
        self._serial = serial

    def enable_stream(self, stream_type: stream, *args: Any) -> None:
        # The overloads the driver may use: (stream, width, height, format, fps) and
        # (stream, format, fps).
        if len(args) == 4:
            w, h, fmt, fps = args
        elif len(args) == 2:
            w, h = 0, 0
            fmt, fps = args
        else:
            raise TypeError(f"enable_stream(): the fake has no overload for {args}")
        if not isinstance(stream_type, stream) or not isinstance(fmt, format):
            raise TypeError("enable_stream(): incompatible function arguments")
        self._streams[stream_type] = (int(w), int(h), fmt, int(fps))


class pipeline:
    """Bound to a :class:`FakeRealSense` through ``_fake`` (set by a subclass)."""

    _fake: FakeRealSense

    def __init__(self) -> None:
        self._callback: Callable[[frame], None] | None = None
        self._thread: threading.Thread | None = None
        self._running = threading.Event()
        self._size = (0, 0)
        self._fps = 0
        self._depth = False

    def start(self, cfg: config, callback: Callable[[frame], None]) -> pipeline_profile:
        fake = self._fake
        if self._callback is not None:
            raise RuntimeError("start() cannot be called before stop()")
        if fake.start_error is not None:
            raise RuntimeError(fake.start_error)
        if cfg._serial is not None and cfg._serial != fake.serial:
            raise RuntimeError("No device connected")
        color = cfg._streams.get(stream.color)
        if color is None:
            raise RuntimeError("Couldn't resolve requests")
        w, h, fmt, fps = color
        if (w, h) not in fake.modes or fmt is not format.rgb8 or fps not in (6, 15, 30, 60):
            raise RuntimeError("Couldn't resolve requests")
        depth = cfg._streams.get(stream.depth)
        if depth is not None and (depth[2] is not format.z16 or depth[3] != fps):
            raise RuntimeError("Couldn't resolve requests")
        self._size, self._fps, self._depth = (w, h), fps, depth is not None
        self._callback = callback
        fake.pipelines.append(self)
        intr = intrinsics()
        intr.width, intr.height = w, h
        intr.fx = intr.fy = 0.95 * w
        intr.ppx, intr.ppy = (w - 1) / 2 + 1.25, (h - 1) / 2 - 0.75
        intr.model = distortion.inverse_brown_conrady
        intr.coeffs = list(fake.coeffs)
        self._running.set()
        if fake.auto:
            self._thread = threading.Thread(target=self._run, daemon=True)
            self._thread.start()
        return pipeline_profile(fake, intr)

    def stop(self) -> None:
        if self._callback is None:
            raise RuntimeError("stop() cannot be called before start()")
        self._running.clear()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
        self._callback = None

    def _run(self) -> None:
        period = 1.0 / self._fps
        while self._running.is_set():
            if self._fake.delivering:
                self._deliver()
            time.sleep(period)

    def _deliver(self) -> None:
        fake, cb = self._fake, self._callback
        if cb is None or not self._running.is_set():
            return
        t = fake.clock()
        rgb, depth_m = fake.render(t)
        w, h = self._size
        rgb = np.ascontiguousarray(rgb, dtype=np.uint8)
        if rgb.shape != (h, w, 3):
            raise AssertionError(f"render gave {rgb.shape}, the stream is {h}x{w}")
        with fake._lock:
            fake._number += 1
            number = fake._number
        if fake.domain is timestamp_domain.global_time:
            ts = t * 1000.0
        else:
            ts = 5.0e6 + number * 1000.0 / self._fps  # a device clock, not the host's
        color = frame(rgb, ts, fake.domain, number)
        depth = None
        if self._depth:
            d = np.zeros((h, w), np.float32) if depth_m is None else np.asarray(depth_m)
            z = np.clip(np.round(d / fake.depth_scale), 0, 65535).astype(np.uint16)
            z = np.repeat(np.repeat(z, 2, axis=0), 2, axis=1)  # the depth sensor's own size
            depth = frame(z, ts, fake.domain, number)
        cb(composite_frame(color, depth))


class FakeRealSense:
    """The fake module. ``render`` and ``clock`` make the frames; ``domain`` is their
    timestamps' domain; ``depth_scale`` the depth sensor's metres per unit (0.001 on a
    D400, 0.00025 on an L515); ``delivering`` False stops the frames; ``auto`` False
    delivers none but those :meth:`emit` makes."""

    stream = stream
    format = format
    timestamp_domain = timestamp_domain
    option = option
    camera_info = camera_info
    distortion = distortion
    intrinsics = intrinsics
    frame = frame
    video_frame = video_frame
    depth_frame = depth_frame
    composite_frame = composite_frame
    align = align
    config = config
    pipeline_profile = pipeline_profile
    video_stream_profile = video_stream_profile
    stream_profile = stream_profile
    device = device
    sensor = sensor
    depth_sensor = depth_sensor

    def __init__(
        self,
        render: Render,
        clock: Callable[[], float] = time.time,
        *,
        domain: str = "global_time",
        depth_scale: float = 0.001,
        auto: bool = True,
        modes: tuple[tuple[int, int], ...] = ((320, 240), (640, 480), (1280, 720)),
        coeffs: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0),
        serial: str = "012345678901",
    ) -> None:
        self.render = render
        self.clock = clock
        self.domain = timestamp_domain[domain]
        self.depth_scale = depth_scale
        self.auto = auto
        self.modes = modes
        self.coeffs = coeffs
        self.serial = serial
        self.model_name = "Intel RealSense D435"
        self.firmware = "5.16.0.1"
        self.delivering = True
        self.start_error: str | None = None
        self.options_set: list[tuple[str, float]] = []
        self.pipelines: list[pipeline] = []
        self._lock = threading.Lock()
        self._number = 0
        self.pipeline = type("pipeline", (pipeline,), {"_fake": self})

    def emit(self, n: int = 1) -> None:
        """Delivers ``n`` frames now, on the caller's thread, to every started pipeline."""
        for _ in range(n):
            for p in self.pipelines:
                p._deliver()
