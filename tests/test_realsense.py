"""The RealSense driver against a fake pyrealsense2 (no camera needed).

The fake is held to the real module: every name it provides must exist on the installed
``pyrealsense2`` (which imports without a device).
"""

from __future__ import annotations

import builtins
import enum
import sys
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest
from fake_realsense import CONTROLS, FakeRealSense
from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.robot.errors import ConnectionLost, DeviceError
from heapgrasp.robot.interfaces import Camera
from heapgrasp.robot.realsense import CameraFrame, RealSenseCamera, RealSenseSettings

Image = tuple[npt.NDArray[np.uint8], npt.NDArray[np.float32] | None]


class Counter:
    """A clock that ticks 1 s per call (the time is its own, not the wall's)."""

    def __init__(self, start: float) -> None:
        self.t = start

    def __call__(self) -> float:
        self.t += 1.0
        return self.t


def scene(width: int, height: int) -> Any:
    """Frames whose pixels encode ``t`` (so order can be read back) and depth a ramp from
    0.3 m, with a hole (0) in the corner."""

    def render(t: float) -> Image:
        rgb = np.zeros((height, width, 3), np.uint8)
        rgb[..., 0] = int(t) % 256
        rgb[..., 1] = np.arange(width, dtype=np.uint8)[None, :]
        depth = (0.3 + 0.001 * np.arange(width, dtype=np.float32))[None, :].repeat(height, 0)
        depth[:4, :4] = 0.0
        return rgb, depth.astype(np.float32)

    return render


def camera(fake: FakeRealSense, clock: Any = None, **settings: Any) -> RealSenseCamera:
    s = RealSenseSettings(**settings)
    if clock is None:
        return RealSenseCamera(s, rs=fake)
    return RealSenseCamera(s, rs=fake, clock=clock)


# -- settings ------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "named"),
    [
        ({"width": 0}, "width"),
        ({"height": -240}, "height"),
        ({"width": 320.0}, "width"),
        ({"width": True}, "width"),
        ({"fps": 25}, "fps"),
        ({"fps": 0}, "fps"),
        ({"timeout_s": 0.0}, "timeout_s"),
        ({"timeout_s": float("nan")}, "timeout_s"),
        ({"depth": "yes"}, "depth"),
        ({"serial": 1234}, "serial"),
    ],
)
def test_settings_validation(kwargs: dict[str, Any], named: str) -> None:
    with pytest.raises(ValueError, match=named):
        RealSenseSettings(**kwargs)


def test_settings_defaults() -> None:
    s = RealSenseSettings()
    assert (s.width, s.height, s.fps, s.depth, s.serial, s.timeout_s) == (
        320,
        240,
        30,
        False,
        None,
        1.0,
    )
    assert RealSenseSettings(serial="").serial is None


# -- start ---------------------------------------------------------------------------


@pytest.mark.parametrize(("w", "h"), [(640, 480), (320, 240)])
def test_start_reads_intrinsics(w: int, h: int) -> None:
    fake = FakeRealSense(scene(w, h), auto=False, coeffs=(0.01, -0.02, 0.0, 0.0, 0.003))
    cam = camera(fake, width=w, height=h, fps=15)
    with pytest.raises(DeviceError, match="not started"):
        _ = cam.spec
    with cam:
        assert isinstance(cam, Camera)
        spec = cam.spec
        assert spec == CameraSpec(
            width=w,
            height=h,
            fx=0.95 * w,
            fy=0.95 * w,
            cx=(w - 1) / 2 + 1.25,
            cy=(h - 1) / 2 - 0.75,
            fps=15.0,
        )
        assert not cam.depth
        np.testing.assert_allclose(cam.distortion, [0.01, -0.02, 0.0, 0.0, 0.003])
        assert cam.distortion_model == "inverse_brown_conrady"
        info = cam.describe()
        assert info["serial"] == fake.serial and info["name"] == fake.model_name
        assert info["firmware"] == fake.firmware
        assert info["intrinsics"]["fx"] == pytest.approx(0.95 * w)
        assert info["depth_scale"] is None
        assert f"{w}x{h}" in info["stream"]
    assert ("global_time_enabled", 1.0) in fake.options_set


def test_start_errors_are_device_errors() -> None:
    fake = FakeRealSense(scene(424, 240), auto=False, modes=((320, 240),))
    with pytest.raises(DeviceError, match="424x240"):
        camera(fake, width=424, height=240).start()
    fake = FakeRealSense(scene(320, 240), auto=False)
    with pytest.raises(DeviceError, match="No device"):
        camera(fake, serial="999").start()
    fake.start_error = "Device or resource busy"
    with pytest.raises(DeviceError, match="busy"):
        camera(fake).start()


def test_not_started() -> None:
    cam = camera(FakeRealSense(scene(320, 240), auto=False))
    with pytest.raises(DeviceError, match="start"):
        cam.poll()
    with pytest.raises(DeviceError, match="start"):
        cam.wait()


# -- frames --------------------------------------------------------------------------


@pytest.mark.parametrize("scale", [0.001, 0.00025, 0.0001])
def test_depth_in_metres(scale: float) -> None:
    w, h = 320, 240
    fake = FakeRealSense(scene(w, h), auto=False, depth_scale=scale)
    with camera(fake, depth=True) as cam:
        assert cam.depth and cam.depth_scale == scale
        fake.emit(1)
        (frame,) = cam.poll()
        assert frame.depth is not None
        assert frame.depth.dtype == np.float32 and frame.depth.shape == (h, w)
        _, truth = scene(w, h)(0.0)
        assert truth is not None
        np.testing.assert_allclose(frame.depth, truth, atol=scale / 2 + 1e-6)
        assert (frame.depth[:4, :4] == 0).all()
        assert cam.describe()["depth_scale"] == scale


def test_rgb_channels_in_rgb_order() -> None:
    fake = FakeRealSense(scene(320, 240), Counter(10.0), auto=False)
    with camera(fake) as cam:
        fake.emit(1)
        (frame,) = cam.poll()
        assert frame.rgb.dtype == np.uint8 and frame.rgb.shape == (240, 320, 3)
        assert frame.rgb[0, 0, 0] == 11 and frame.rgb[0, 5, 1] == 5 and frame.rgb[0, 5, 2] == 0
        assert frame.depth is None


def test_global_time_stamps_are_used() -> None:
    device_clock = Counter(1000.0)
    host_clock = Counter(-50.0)  # never read for global-time frames
    fake = FakeRealSense(scene(320, 240), device_clock, auto=False, domain="global_time")
    with camera(fake, host_clock) as cam:
        fake.emit(3)
        frames = cam.poll()
        assert [f.time for f in frames] == pytest.approx([1001.0, 1002.0, 1003.0])
        assert not cam.arrival_times
        assert cam.describe()["timestamps"] == "global time"


@pytest.mark.parametrize("domain", ["hardware_clock", "system_time"])
def test_other_domains_are_stamped_on_arrival(domain: str) -> None:
    fake = FakeRealSense(scene(320, 240), Counter(1000.0), auto=False, domain=domain)
    host_clock = Counter(-50.0)
    with camera(fake, host_clock) as cam:
        fake.emit(3)
        frames = cam.poll()
        assert [f.time for f in frames] == pytest.approx([-49.0, -48.0, -47.0])
        assert cam.arrival_times
        assert "arrival" in cam.describe()["timestamps"]


def test_poll_returns_all_frames_oldest_first() -> None:
    fake = FakeRealSense(scene(320, 240), Counter(0.0), auto=False)
    with camera(fake) as cam:
        assert cam.poll() == []
        fake.emit(5)
        frames = cam.poll()
        assert all(isinstance(f, CameraFrame) for f in frames)
        assert [f.number for f in frames] == [1, 2, 3, 4, 5]
        assert [int(f.rgb[0, 0, 0]) for f in frames] == [1, 2, 3, 4, 5]
        assert cam.poll() == []
        fake.emit(2)
        assert [f.number for f in cam.poll()] == [6, 7]
        fake.emit(2)
        assert cam.wait().number == 8  # wait hands over the oldest not yet handed over
        assert [f.number for f in cam.poll()] == [9]


def test_queue_drops_the_oldest_beyond_its_capacity() -> None:
    fake = FakeRealSense(scene(320, 240), Counter(0.0), auto=False)
    with camera(fake, fps=6) as cam:  # 2 s at 6 fps: 12 frames
        fake.emit(15)
        frames = cam.poll()
        assert [f.number for f in frames] == list(range(4, 16))
        assert cam.dropped == 3


def test_wait_streams_frames() -> None:
    fake = FakeRealSense(scene(320, 240))  # a delivery thread at the stream's rate
    with camera(fake, fps=60) as cam:
        numbers = [cam.wait(timeout=2.0).number for _ in range(3)]
        assert numbers == sorted(numbers) and len(set(numbers)) == 3


def test_wait_timeout_is_connection_lost() -> None:
    fake = FakeRealSense(scene(320, 240), auto=False)
    with camera(fake, timeout_s=0.1) as cam:
        with pytest.raises(ConnectionLost, match=r"RealSense 012345678901.*0\.1 s"):
            cam.wait()
    fake = FakeRealSense(scene(320, 240))
    with camera(fake, fps=60) as cam:
        cam.wait(timeout=2.0)
        fake.delivering = False
        cam.poll()
        with pytest.raises(ConnectionLost, match=r"no frame within 0\.05 s"):
            cam.wait(timeout=0.05)


def test_stop_and_restart() -> None:
    fake = FakeRealSense(scene(320, 240), auto=False)
    cam = camera(fake)
    cam.start()
    cam.start()  # a no-op
    assert len(fake.pipelines) == 1
    fake.emit(1)
    cam.stop()
    cam.stop()
    with pytest.raises(DeviceError):
        cam.poll()
    cam.start()
    assert cam.poll() == []  # frames from before the stop are gone


# -- the library ---------------------------------------------------------------------


def test_missing_library_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    real_import = builtins.__import__

    def no_realsense(name: str, *args: Any, **kwargs: Any) -> Any:
        if name == "pyrealsense2" or name.startswith("pyrealsense2."):
            raise ImportError("libusb-1.0.so.0: cannot open shared object file")
        return real_import(name, *args, **kwargs)

    monkeypatch.delitem(sys.modules, "pyrealsense2", raising=False)
    monkeypatch.setattr(builtins, "__import__", no_realsense)
    with pytest.raises(DeviceError, match=r"heapgrasp\[robot\]") as info:
        RealSenseCamera()
    assert isinstance(info.value, ValueError)
    assert "libusb" in str(info.value)


def _public(obj: Any) -> set[str]:
    return {n for n in dir(obj) if not n.startswith("_")}


def test_fake_names_exist_on_the_real_module() -> None:
    import pyrealsense2 as rs

    fake = FakeRealSense(scene(320, 240), auto=False)
    names = _public(fake) - CONTROLS
    assert {"pipeline", "config", "align", "stream", "frame", "intrinsics"} <= names
    missing = sorted(n for n in names if not hasattr(rs, n))
    assert missing == []
    for name in sorted(names):
        fake_obj, real_obj = getattr(fake, name), getattr(rs, name)
        assert isinstance(fake_obj, type), name
        if issubclass(fake_obj, enum.Enum):
            members = [m.name for m in fake_obj]
        else:
            members = sorted(_public(fake_obj))
        lacking = [m for m in members if not hasattr(real_obj, m)]
        assert lacking == [], f"rs.{name} has no {lacking}"
    # the enum members are the real ones' (their values too)
    for enum_name in (
        "stream",
        "format",
        "timestamp_domain",
        "option",
        "camera_info",
        "distortion",
    ):
        for member in getattr(fake, enum_name):
            real = getattr(getattr(rs, enum_name), member.name)
            assert int(real) == member.value, f"rs.{enum_name}.{member.name}"


def test_fake_strictness_catches_unknown_names() -> None:
    """The check above can fail: a name the real module lacks is found."""
    import pyrealsense2 as rs

    assert not hasattr(rs.frame, "get_width")  # video_frame only
    assert not hasattr(rs.sensor, "get_depth_scale")  # depth_sensor only
    fake = FakeRealSense(scene(320, 240), auto=False)
    assert not hasattr(fake.frame, "get_width")
    assert not hasattr(fake.sensor, "get_depth_scale")
    assert not hasattr(fake, "wait_for_frames")
