"""The Robotiq 2F-140 over the UR's Robotiq URCap socket, as the loop's
:class:`~heapgrasp.robot.interfaces.Gripper`.

The Robotiq Grippers URCap, installed on the UR controller, serves the gripper's registers
on TCP port 63352 in plain ASCII, one request and one reply at a time:

* ``SET VAR value [VAR value ...]\\n`` sets one or more registers and is answered ``ack``;
  ``SET POS 128 SPE 255 FOR 100 GTO 1`` starts a motion to register 128;
* ``GET VAR\\n`` is answered ``VAR value``, e.g. ``GET POS`` → ``POS 128``.

The registers this driver reads and writes (Robotiq 2F-85/2F-140 instruction manual §4):
``ACT`` (1 activates, 0 resets and clears faults), ``ATR`` (automatic release, kept 0),
``GTO`` (1: go to the requested position), ``POS`` (the requested position when set, the
measured one when read, 0 = open … 255 = closed), ``SPE`` and ``FOR`` (speed and force,
0-255), ``PRE`` (the echo of the requested position), ``STA`` (0 reset, 1 activating,
3 activated), ``OBJ`` (0 moving; 1 stopped on contact while opening; 2 stopped on contact
while closing; 3 at the requested position) and ``FLT`` (0: no fault).

Widths are metres between the pads; registers map to widths linearly between the
registers the fingers reach fully open and fully closed (:class:`WidthCalibration`,
measured by :meth:`Robotiq2F140.activate`: the fingers stop a few counts short of 0 and
255). A width outside ``[0, max_width]`` is refused before anything is sent
(:class:`~heapgrasp.robot.errors.SafetyError`); a refused, dropped or silent connection
is :class:`~heapgrasp.robot.errors.ConnectionLost`, an unexpected reply or a gripper
fault :class:`~heapgrasp.robot.errors.DeviceError`. Only the standard library is used.
"""

from __future__ import annotations

import math
import re
import socket
import threading
import time
from collections.abc import Mapping
from dataclasses import dataclass
from types import TracebackType
from typing import Any

from heapgrasp.geometry.gripper import ROBOTIQ_2F140, GripperGeometry
from heapgrasp.robot.errors import ConnectionLost, DeviceError, SafetyError

__all__ = [
    "ACTIVATION_TIMEOUT",
    "OBJ_AT_POSITION",
    "OBJ_CONTACT_CLOSING",
    "OBJ_CONTACT_OPENING",
    "OBJ_MOVING",
    "PORT",
    "STA_ACTIVE",
    "Robotiq2F140",
    "WidthCalibration",
]

#: The Robotiq URCap's socket on the UR controller.
PORT = 63352

#: ``OBJ``: the fingers are moving toward the requested position.
OBJ_MOVING = 0
#: ``OBJ``: the fingers stopped on a contact while opening.
OBJ_CONTACT_OPENING = 1
#: ``OBJ``: the fingers stopped on a contact while closing (an object is held).
OBJ_CONTACT_CLOSING = 2
#: ``OBJ``: the fingers are at the requested position (nothing met).
OBJ_AT_POSITION = 3
#: ``STA``: activation done.
STA_ACTIVE = 3
#: Seconds the activation may take at least (it moves the fingers through the stroke).
ACTIVATION_TIMEOUT = 10.0

_REPLY = re.compile(r"^([A-Z]{3}) (\S+)$")
_PARTIAL = re.compile(r"^(a|ac|[A-Z]{1,3})$")
_POLL_S = 0.005
_CALIBRATION_SPEED = 64
_CALIBRATION_FORCE = 1
_MIN_CALIBRATED_SPAN = 32


def _register(name: str, value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 255:
        raise ValueError(f"{name} must be an integer register in [0, 255], got {value!r}")
    return int(value)


@dataclass(frozen=True)
class WidthCalibration:
    """The opening (m) ↔ position register (0-255) map: linear between the register the
    fingers reach fully open (``max_width``) and fully closed (0 m).

    :meth:`Robotiq2F140.activate` measures both registers; the defaults are the nominal
    ends of the register range.
    """

    open_position: int = 0
    closed_position: int = 255
    max_width: float = 0.14
    """Opening between the pads at ``open_position`` (m): the 2F-140's 140 mm stroke."""

    def __post_init__(self) -> None:
        _register("WidthCalibration.open_position", self.open_position)
        _register("WidthCalibration.closed_position", self.closed_position)
        if not self.open_position < self.closed_position:
            raise ValueError(
                "WidthCalibration needs open_position < closed_position, got "
                f"{self.open_position} and {self.closed_position}"
            )
        w = self.max_width
        if (
            isinstance(w, bool)
            or not isinstance(w, int | float)
            or not (math.isfinite(w) and w > 0)
        ):
            raise ValueError(f"WidthCalibration.max_width must be finite and > 0 m, got {w!r}")
        object.__setattr__(self, "max_width", float(w))

    def to_register(self, width: float) -> int:
        """The register that opens the fingers to ``width`` (m, in ``[0, max_width]``)."""
        w = float(width)
        if not (math.isfinite(w) and 0.0 <= w <= self.max_width):
            raise SafetyError(
                f"gripper width {width!r} m is outside [0, {self.max_width}] m; nothing was sent"
            )
        span = self.closed_position - self.open_position
        return round(self.closed_position - w / self.max_width * span)

    def to_width(self, register: int) -> float:
        """The opening (m) at position ``register``, clamped to ``[0, max_width]`` (the
        fingers stop a little beyond the calibrated ends)."""
        span = self.closed_position - self.open_position
        w = (self.closed_position - float(register)) / span * self.max_width
        return min(max(w, 0.0), self.max_width)

    def to_dict(self) -> dict[str, Any]:
        """The calibration as plain values (for ``robot.toml``)."""
        return {
            "open_position": self.open_position,
            "closed_position": self.closed_position,
            "max_width": self.max_width,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> WidthCalibration:
        """The inverse of :meth:`to_dict` (missing keys take the defaults; unknown keys
        are an error)."""
        known = {"open_position", "closed_position", "max_width"}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ValueError(f"WidthCalibration: unknown keys {unknown} (known: {sorted(known)})")
        return cls(**{k: data[k] for k in known if k in data})


class Robotiq2F140:
    """A Robotiq 2F-140 on a UR arm, through the Robotiq URCap's socket.

    Parameters
    ----------
    host, port
        The UR controller (the URCap serves the gripper there) and the URCap's port.
    timeout
        Seconds to wait to connect and for each reply; past it the connection counts as
        lost (:class:`ConnectionLost`) and is closed.
    speed, force
        Default finger speed and grip force registers (0-255) of every motion.
    calibration
        The width map; None: the nominal one until :meth:`activate` measures it.
    geometry
        The hand's shape for the planners (:data:`~heapgrasp.geometry.gripper.ROBOTIQ_2F140`).
    motion_timeout
        Seconds a motion (and the activation) may take before it is a
        :class:`DeviceError`.
    """

    def __init__(
        self,
        host: str,
        port: int = PORT,
        *,
        timeout: float = 2.0,
        speed: int = 255,
        force: int = 100,
        calibration: WidthCalibration | None = None,
        geometry: GripperGeometry = ROBOTIQ_2F140,
        motion_timeout: float = 5.0,
    ) -> None:
        if not isinstance(host, str) or not host:
            raise ValueError(f"Robotiq2F140 host must be a non-empty string, got {host!r}")
        if isinstance(port, bool) or not isinstance(port, int) or not 1 <= port <= 65535:
            raise ValueError(f"Robotiq2F140 port must be in [1, 65535], got {port!r}")
        for name, value in (("timeout", timeout), ("motion_timeout", motion_timeout)):
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ValueError(f"Robotiq2F140 {name} must be finite and > 0 s, got {value!r}")
        self.host = host
        self.port = port
        self.timeout = float(timeout)
        self.speed = _register("speed", speed)
        self.force = _register("force", force)
        self.calibration = calibration if calibration is not None else WidthCalibration()
        self._geometry = geometry
        self.motion_timeout = float(motion_timeout)
        self._sock: socket.socket | None = None
        self._rx = b""
        self._lock = threading.Lock()
        self._closed = False

    # -- connection -------------------------------------------------------------------

    @property
    def address(self) -> str:
        """``host:port``."""
        return f"{self.host}:{self.port}"

    @property
    def connected(self) -> bool:
        """Whether the socket is open."""
        return self._sock is not None

    def connect(self) -> None:
        """Opens the socket (a no-op when open); :class:`ConnectionLost` if refused."""
        with self._lock:
            if self._sock is not None:
                return
            try:
                sock = socket.create_connection((self.host, self.port), timeout=self.timeout)
            except OSError as e:
                raise ConnectionLost(
                    f"cannot connect to the Robotiq URCap at {self.address}: {e}"
                ) from e
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            sock.settimeout(self.timeout)
            self._sock = sock
            self._rx = b""

    def disconnect(self) -> None:
        """Closes the socket (a no-op when closed)."""
        with self._lock:
            self._drop()

    def __enter__(self) -> Robotiq2F140:
        self.connect()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.disconnect()

    def _drop(self) -> None:
        if self._sock is not None:
            try:
                self._sock.close()
            finally:
                self._sock = None
                self._rx = b""

    def _lost(self, command: str, why: str, cause: BaseException | None = None) -> ConnectionLost:
        self._drop()
        err = ConnectionLost(f"Robotiq URCap at {self.address}, command {command!r}: {why}")
        if cause is not None:
            err.__cause__ = cause
        return err

    def _request(self, command: str) -> str:
        """Sends one command line and returns its reply (stripped)."""
        with self._lock:
            if self._sock is None:
                raise ConnectionLost(
                    f"Robotiq URCap at {self.address}: not connected (command {command!r}); "
                    "call connect()"
                )
            try:
                self._sock.sendall(command.encode("ascii") + b"\n")
            except OSError as e:
                raise self._lost(command, f"sending failed ({e})", e) from e
            deadline = time.monotonic() + self.timeout
            while True:
                reply = self._take_reply()
                if reply is not None:
                    return reply
                left = deadline - time.monotonic()
                if left <= 0:
                    raise self._lost(command, f"no reply within {self.timeout} s")
                try:
                    self._sock.settimeout(left)
                    chunk = self._sock.recv(1024)
                except TimeoutError as e:
                    raise self._lost(command, f"no reply within {self.timeout} s", e) from e
                except OSError as e:
                    raise self._lost(command, f"connection failed ({e})", e) from e
                if not chunk:
                    raise self._lost(command, "the connection was closed")
                self._rx += chunk

    def _take_reply(self) -> str | None:
        """One reply from the receive buffer, or None while it is incomplete. A reply ends
        at a newline or, as the URCap sends ``ack`` without one, when the buffer holds a
        whole ``ack`` or ``VAR value``."""
        buf = self._rx.lstrip()
        if not buf:
            self._rx = b""
            return None
        if b"\n" in buf:
            line, _, rest = buf.partition(b"\n")
            self._rx = rest
            return line.decode("ascii", "replace").strip()
        text = buf.decode("ascii", "replace").strip()
        if text != "ack" and not _REPLY.match(text) and _PARTIAL.match(text):
            self._rx = buf  # the start of a reply: wait for the rest
            return None
        self._rx = b""  # a whole reply, or garbage that no more bytes would mend
        return text

    # -- registers --------------------------------------------------------------------

    def _set(self, **registers: int) -> None:
        parts = " ".join(f"{k} {_register(k, v)}" for k, v in registers.items())
        command = f"SET {parts}"
        reply = self._request(command)
        if reply != "ack":
            raise DeviceError(
                f"Robotiq URCap at {self.address} answered {reply!r} to {command!r} "
                "(expected 'ack')"
            )

    def _get(self, name: str) -> int:
        command = f"GET {name}"
        reply = self._request(command)
        m = _REPLY.match(reply)
        value: int | None = None
        if m is not None and m.group(1) == name:
            try:
                value = int(m.group(2))
            except ValueError:
                if name == "FLT":  # a fault code may come as two hex digits
                    try:
                        value = int(m.group(2), 16)
                    except ValueError:
                        value = None
        if value is None:
            raise DeviceError(
                f"Robotiq URCap at {self.address} answered {reply!r} to {command!r} "
                f"(expected '{name} <integer>')"
            )
        return value

    def _check_fault(self, during: str) -> None:
        fault = self._get("FLT")
        if fault != 0:
            raise DeviceError(
                f"Robotiq gripper at {self.address} reports fault FLT {fault} {during} "
                "(see the Robotiq manual's fault table; activate() clears it)"
            )

    def _wait_until(self, what: str, done: Any, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while not done():
            if time.monotonic() > deadline:
                raise DeviceError(
                    f"Robotiq gripper at {self.address}: {what} did not happen within {timeout} s"
                )
            time.sleep(_POLL_S)

    # -- gripper ----------------------------------------------------------------------

    @property
    def geometry(self) -> GripperGeometry:
        """The hand's shape, widest opening and finger depth."""
        return self._geometry

    def activate(
        self, *, auto_calibrate: bool = True, timeout: float | None = None
    ) -> WidthCalibration:
        """Resets and activates the gripper (clearing any fault) and waits until it reports
        ``STA 3`` (for ``timeout`` s; None: ``motion_timeout``, at least
        :data:`ACTIVATION_TIMEOUT` — the activation moves the fingers). With
        ``auto_calibrate`` it then opens, closes fully and opens fully (slowly, at the
        least force), reading ``POS`` at each end: the registers of the new
        :attr:`calibration`, which it returns. Activation closes and opens fully: nothing
        may be between or around the fingers."""
        if timeout is None:
            limit = max(self.motion_timeout, ACTIVATION_TIMEOUT)
        elif isinstance(timeout, int | float) and math.isfinite(timeout) and timeout > 0:
            limit = float(timeout)
        else:
            raise ValueError(f"activation timeout must be finite and > 0 s, got {timeout!r}")
        self._set(ACT=0, ATR=0)
        self._wait_until("the reset (STA 0)", lambda: self._get("STA") == 0, limit)
        self._set(ACT=1)
        self._wait_until("the activation (STA 3)", lambda: self._get("STA") == STA_ACTIVE, limit)
        self._check_fault("after activation")
        self._set(GTO=1)
        self._closed = False
        if not auto_calibrate:
            return self.calibration
        positions = {}
        for end, target in (("open", 0), ("closed", 255), ("open", 0)):
            obj = self._move_register(target, _CALIBRATION_SPEED, _CALIBRATION_FORCE, wait=True)
            if obj != OBJ_AT_POSITION:
                raise DeviceError(
                    f"Robotiq gripper at {self.address}: calibration stopped on a contact "
                    f"while moving {end} (OBJ {obj}); clear the fingers and activate again"
                )
            positions[end] = self._get("POS")
        open_pos, closed_pos = positions["open"], positions["closed"]
        if closed_pos - open_pos < _MIN_CALIBRATED_SPAN:
            raise DeviceError(
                f"Robotiq gripper at {self.address}: calibration measured open {open_pos} and "
                f"closed {closed_pos}, which is not a full stroke"
            )
        self.calibration = WidthCalibration(open_pos, closed_pos, self.calibration.max_width)
        return self.calibration

    def _move_register(self, target: int, speed: int, force: int, *, wait: bool) -> int:
        self._set(POS=target, SPE=speed, FOR=force, GTO=1)
        if not wait:
            return OBJ_MOVING
        deadline = time.monotonic() + self.motion_timeout
        obj = OBJ_MOVING
        # First the echo of the request (the gripper took it), then the end of the motion.
        while self._get("PRE") != target or (obj := self._get("OBJ")) == OBJ_MOVING:
            if time.monotonic() > deadline:
                raise DeviceError(
                    f"Robotiq gripper at {self.address}: the motion to register {target} did "
                    f"not end within {self.motion_timeout} s"
                )
            time.sleep(_POLL_S)
        self._check_fault(f"after moving to register {target}")
        return obj

    def move(
        self,
        width: float,
        *,
        speed: int | None = None,
        force: int | None = None,
        wait: bool = True,
    ) -> int:
        """Moves the fingers to ``width`` (m) and, with ``wait``, returns how the motion
        ended (``OBJ``: :data:`OBJ_AT_POSITION`, :data:`OBJ_CONTACT_CLOSING`, …); without,
        returns :data:`OBJ_MOVING` at once. A width outside ``[0, max_width]`` is a
        :class:`SafetyError`, raised before anything is sent."""
        register = self.calibration.to_register(width)
        spe = self.speed if speed is None else _register("speed", speed)
        frc = self.force if force is None else _register("force", force)
        return self._move_register(register, spe, frc, wait=wait)

    def open(self) -> None:
        """Opens fully (to the calibrated open register)."""
        self._closed = False
        self._move_register(self.calibration.open_position, self.speed, self.force, wait=True)

    def close(self, width: float | None = None) -> None:
        """Closes to ``width`` (m), or with None as far as the fingers go (they stop on
        what they meet, at the grip force)."""
        if width is None:
            register = 255
        else:
            register = self.calibration.to_register(width)
        self._closed = True
        self._move_register(register, self.speed, self.force, wait=True)

    def holding(self) -> bool:
        """Whether the fingers, last closed, stopped on something and still do (``OBJ`` 1
        or 2; the gripper reports 3 once a held object slips out)."""
        if not self._closed:
            return False
        return self._get("OBJ") in (OBJ_CONTACT_OPENING, OBJ_CONTACT_CLOSING)

    def position(self) -> int:
        """The measured position register (0 open … 255 closed)."""
        return self._get("POS")

    def width(self) -> float:
        """The measured opening (m) through :attr:`calibration`."""
        return self.calibration.to_width(self.position())

    def status(self) -> dict[str, int]:
        """The status registers ``STA``, ``OBJ``, ``FLT``, ``POS``, ``PRE`` (for
        ``heapgrasp robot check``)."""
        return {name: self._get(name) for name in ("STA", "OBJ", "FLT", "POS", "PRE")}

    def __repr__(self) -> str:
        state = "connected" if self.connected else "not connected"
        return f"Robotiq2F140({self.address}, {state}, {self.calibration})"
