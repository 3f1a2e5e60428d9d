"""The Robotiq 2F-140 driver against the fake URCap server (no hardware, loopback only)."""

from __future__ import annotations

import math
import socket
import time
from collections.abc import Iterator

import pytest
from fake_robotiq import FakeRobotiq
from heapgrasp.geometry.gripper import PANDA_HAND, ROBOTIQ_2F140, GripperGeometry
from heapgrasp.robot.errors import ConnectionLost, DeviceError, RobotError, SafetyError
from heapgrasp.robot.interfaces import Gripper
from heapgrasp.robot.robotiq import (
    OBJ_AT_POSITION,
    OBJ_CONTACT_CLOSING,
    OBJ_MOVING,
    Robotiq2F140,
    WidthCalibration,
)


@pytest.fixture
def fake() -> Iterator[FakeRobotiq]:
    with FakeRobotiq() as f:
        yield f


def gripper(fake: FakeRobotiq, **kwargs: object) -> Robotiq2F140:
    kw: dict[str, object] = {"timeout": 1.0, "motion_timeout": 2.0}
    kw.update(kwargs)
    return Robotiq2F140(fake.host, fake.port, **kw)  # type: ignore[arg-type]


def test_geometry_constant() -> None:
    g = ROBOTIQ_2F140
    assert isinstance(g, GripperGeometry)
    assert g.max_opening == pytest.approx(0.14)
    assert g.finger_tip == pytest.approx(0.0325)  # TCP at the centre of the 65 mm pads
    assert g.palm_back < g.palm_split < g.palm_front < g.finger_split < g.finger_tip
    assert g.finger_depth > PANDA_HAND.finger_depth  # long linkage fingers
    assert g.inflated(0.005).max_opening == g.max_opening


def test_satisfies_gripper_protocol(fake: FakeRobotiq) -> None:
    g = gripper(fake)
    assert isinstance(g, Gripper)
    assert g.geometry is ROBOTIQ_2F140


def test_activation_calibrates(fake: FakeRobotiq) -> None:
    with gripper(fake) as g:
        cal = g.activate()
        assert cal == WidthCalibration(fake.open_stop, fake.closed_stop, 0.14)
        assert g.calibration == cal
        assert g.status() == {"STA": 3, "OBJ": 3, "FLT": 0, "POS": fake.open_stop, "PRE": 0}
        assert g.width() == pytest.approx(0.14)
    sent = fake.sent()
    # reset, activate, then close fully and open fully, reading POS at each end
    assert sent[0] == "SET ACT 0 ATR 0"
    assert "SET ACT 1" in sent
    moves = [c for c in sent if c.startswith("SET POS")]
    assert [m.split()[2] for m in moves] == ["0", "255", "0"]
    assert all(m.endswith("GTO 1") for m in moves)
    i_close = sent.index(moves[1])
    assert "GET POS" in sent[i_close:]


def test_activation_without_calibration_keeps_given(fake: FakeRobotiq) -> None:
    given = WidthCalibration(10, 200, 0.14)
    with gripper(fake, calibration=given) as g:
        assert g.activate(auto_calibrate=False) is given
    assert not any(c.startswith("SET POS") for c in fake.sent())


def test_calibration_refuses_an_object(fake: FakeRobotiq) -> None:
    fake.object_at = 120
    with gripper(fake) as g, pytest.raises(DeviceError, match="calibration"):
        g.activate()


def test_activation_timeout(fake: FakeRobotiq) -> None:
    fake.activation_time = 60.0
    with gripper(fake) as g, pytest.raises(DeviceError, match="STA 3"):
        g.activate(timeout=0.2)


def test_width_mapping_both_ways() -> None:
    cal = WidthCalibration(3, 229, 0.14)
    assert cal.to_register(0.14) == 3
    assert cal.to_register(0.0) == 229
    assert cal.to_register(0.07) == 116
    assert cal.to_width(3) == pytest.approx(0.14)
    assert cal.to_width(229) == pytest.approx(0.0)
    assert cal.to_width(116) == pytest.approx(0.07, abs=0.14 / 226)
    assert cal.to_width(255) == 0.0 and cal.to_width(0) == pytest.approx(0.14)  # clamped
    for w in (0.0, 0.013, 0.05, 0.1, 0.139):
        assert cal.to_width(cal.to_register(w)) == pytest.approx(w, abs=0.5 * 0.14 / 226)
    assert WidthCalibration.from_dict(cal.to_dict()) == cal
    assert WidthCalibration.from_dict({}) == WidthCalibration()


@pytest.mark.parametrize(
    "kwargs",
    [
        {"open_position": -1},
        {"closed_position": 256},
        {"open_position": 200, "closed_position": 100},
        {"open_position": 1.5},
        {"max_width": 0.0},
        {"max_width": math.nan},
        {"open_position": True},
    ],
)
def test_calibration_validation(kwargs: dict[str, object]) -> None:
    with pytest.raises(ValueError, match="WidthCalibration"):
        WidthCalibration(**kwargs)  # type: ignore[arg-type]


def test_calibration_from_dict_unknown_key() -> None:
    with pytest.raises(ValueError, match="closed_pos"):
        WidthCalibration.from_dict({"closed_pos": 230})


def test_move_reaches_width(fake: FakeRobotiq) -> None:
    with gripper(fake) as g:
        g.activate()
        assert g.move(0.07) == OBJ_AT_POSITION
        assert g.width() == pytest.approx(0.07, abs=0.001)
        assert g.move(0.02, speed=10, force=5, wait=False) == OBJ_MOVING
        assert fake.sent()[-1] == f"SET POS {g.calibration.to_register(0.02)} SPE 10 FOR 5 GTO 1"


def test_close_on_object_is_holding(fake: FakeRobotiq) -> None:
    with gripper(fake) as g:
        g.activate()
        fake.object_at = 150
        g.close()
        assert g.holding()
        assert g.position() == 150
        assert g.status()["OBJ"] == OBJ_CONTACT_CLOSING
        g.open()
        assert not g.holding()
        assert g.position() == fake.open_stop


def test_close_on_nothing_is_not_holding(fake: FakeRobotiq) -> None:
    with gripper(fake) as g:
        g.activate()
        assert not g.holding()  # open: nothing held
        g.close()
        assert not g.holding()
        assert g.position() == fake.closed_stop
        assert g.width() == 0.0
        g.open()
        g.close(0.05)  # a width, reached: nothing held
        assert not g.holding()


def test_fault_is_device_error(fake: FakeRobotiq) -> None:
    with gripper(fake) as g:
        g.activate()
        fake.fault = 7
        with pytest.raises(DeviceError, match="FLT 7"):
            g.move(0.1)


def test_refused_connection() -> None:
    with socket.socket() as s:  # a port with no listener
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    g = Robotiq2F140("127.0.0.1", port, timeout=1.0)
    with pytest.raises(ConnectionLost, match=f"127.0.0.1:{port}"):
        g.connect()


def test_not_connected(fake: FakeRobotiq) -> None:
    with pytest.raises(ConnectionLost, match="not connected"):
        gripper(fake).position()


def test_dropped_connection(fake: FakeRobotiq) -> None:
    fake.drop_on = "GET POS"
    with gripper(fake) as g:
        g.activate(auto_calibrate=False)
        with pytest.raises(ConnectionLost, match=f"{fake.port}.*'GET POS'"):
            g.position()
        assert not g.connected


def test_stalled_reply(fake: FakeRobotiq) -> None:
    with gripper(fake, timeout=0.3) as g:
        g.activate(auto_calibrate=False)
        fake.stall_on = "GET STA"
        t0 = time.monotonic()
        with pytest.raises(ConnectionLost, match=r"'GET STA'.*0\.3 s"):
            g.status()
        elapsed = time.monotonic() - t0
        assert 0.25 <= elapsed < 5.0
        assert not g.connected


def test_stalled_motion_reply(fake: FakeRobotiq) -> None:
    with gripper(fake, timeout=0.3) as g:
        g.activate(auto_calibrate=False)
        fake.stall_on = "GET OBJ"
        with pytest.raises(ConnectionLost, match="GET OBJ"):
            g.close()


@pytest.mark.parametrize(
    ("on", "garbage"),
    [("SET", b"nak\n"), ("GET POS", b"POS abc\n"), ("GET POS", b"PRE 12\n"), ("GET", b"?\n")],
)
def test_garbage_reply(fake: FakeRobotiq, on: str, garbage: bytes) -> None:
    with gripper(fake) as g:
        g.activate(auto_calibrate=False)
        fake.garbage_on, fake.garbage = on, garbage
        with pytest.raises(DeviceError, match="answered"):
            if on == "SET":
                g.move(0.1)
            else:
                g.position()


def test_garbage_without_newline(fake: FakeRobotiq) -> None:
    with gripper(fake, timeout=0.5) as g:
        g.activate(auto_calibrate=False)
        fake.garbage_on, fake.garbage = "GET POS", b"hello?"
        with pytest.raises(DeviceError, match="hello"):
            g.position()


@pytest.mark.parametrize("newlines", [(False, True), (True, True), (False, False)])
def test_reply_framing(newlines: tuple[bool, bool]) -> None:
    with FakeRobotiq(newline_after_ack=newlines[0], newline_after_get=newlines[1]) as fake:
        with gripper(fake) as g:
            g.activate()
            assert g.move(0.1) == OBJ_AT_POSITION
            assert g.status()["STA"] == 3


@pytest.mark.parametrize("width", [0.2, -0.001, math.nan, math.inf])
def test_bad_width_sends_nothing(fake: FakeRobotiq, width: float) -> None:
    with gripper(fake) as g:
        g.activate()
        before = fake.sent()
        with pytest.raises(SafetyError, match="width") as info:
            g.move(width)
        assert isinstance(info.value, RobotError) and isinstance(info.value, ValueError)
        with pytest.raises(SafetyError):
            g.close(width)
        g.position()  # a synchronous request: everything sent before it has arrived
        assert fake.sent() == [*before, "GET POS"]


def test_bad_arguments_send_nothing(fake: FakeRobotiq) -> None:
    with gripper(fake) as g:
        g.activate()
        before = fake.sent()
        with pytest.raises(ValueError, match="speed"):
            g.move(0.1, speed=300)
        with pytest.raises(ValueError, match="force"):
            g.move(0.1, force=-1)
        g.position()
        assert fake.sent() == [*before, "GET POS"]


@pytest.mark.parametrize(
    "kwargs",
    [{"host": ""}, {"port": 0}, {"timeout": 0.0}, {"speed": 256}, {"motion_timeout": math.nan}],
)
def test_constructor_validation(kwargs: dict[str, object]) -> None:
    args: dict[str, object] = {"host": "127.0.0.1"}
    args.update(kwargs)
    with pytest.raises(ValueError):
        Robotiq2F140(**args)  # type: ignore[arg-type]
