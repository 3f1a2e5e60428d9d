"""A fake Robotiq URCap server: the gripper's ASCII register protocol on 127.0.0.1.

It keeps the registers a 2F-140 reports (``ACT GTO ATR POS SPE FOR`` written, ``STA OBJ
FLT PRE`` and the measured ``POS`` read), simulates the activation (``STA`` 0 → 1 → 3)
and the motion (the position moves toward the request over ``stroke_time`` for the whole
stroke, stops at the mechanical ends ``open_stop``/``closed_stop`` with ``OBJ 3``, or on
an object at ``object_at`` with ``OBJ 2`` while closing and ``OBJ 1`` while opening past
``outer_object_at``). It records every command line received, and can be told to drop the
connection, to stall (never reply) or to reply garbage on a given command.

Replies are sent as the URCap sends them: ``ack`` with no newline, ``VAR value`` with one
(``newline_after_ack`` and ``newline_after_get`` change that).
"""

from __future__ import annotations

import socket
import threading
import time
from dataclasses import dataclass, field


@dataclass
class _Motion:
    start: int
    target: int
    stop: int
    t0: float
    obj_at_stop: int


@dataclass
class FakeRobotiq:
    """The fake server; ``with FakeRobotiq() as fake:`` serves on ``fake.port``."""

    open_stop: int = 3
    closed_stop: int = 229
    stroke_time: float = 0.05
    activation_time: float = 0.02
    object_at: int | None = None
    """Closing stops here with ``OBJ 2`` (an object between the fingers)."""
    outer_object_at: int | None = None
    """Opening stops here with ``OBJ 1`` (something around the fingers)."""
    newline_after_ack: bool = False
    newline_after_get: bool = True
    drop_on: str | None = None
    stall_on: str | None = None
    garbage_on: str | None = None
    garbage: bytes = b"ERR what\n"
    fault: int = 0
    commands: list[str] = field(default_factory=list)
    host: str = "127.0.0.1"
    port: int = 0

    def __post_init__(self) -> None:
        self.regs: dict[str, int] = {
            "ACT": 0,
            "GTO": 0,
            "ATR": 0,
            "MOD": 0,
            "SPE": 0,
            "FOR": 0,
            "PRE": 0,
            "STA": 0,
        }
        self._pos = self.open_stop
        self._motion: _Motion | None = None
        self._activated_at: float | None = None
        self._lock = threading.Lock()
        self._server: socket.socket | None = None
        self._clients: list[socket.socket] = []
        self._threads: list[threading.Thread] = []
        self._stop = threading.Event()

    # -- serving ----------------------------------------------------------------------

    def start(self) -> FakeRobotiq:
        server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        server.bind((self.host, 0))
        server.listen(4)
        server.settimeout(0.05)
        self.port = server.getsockname()[1]
        self._server = server
        t = threading.Thread(target=self._accept, daemon=True)
        t.start()
        self._threads.append(t)
        return self

    def close(self) -> None:
        self._stop.set()
        with self._lock:
            clients = list(self._clients)
        for c in clients:
            _close(c)
        if self._server is not None:
            _close(self._server)
        for t in list(self._threads):
            t.join(timeout=2.0)
        # a connection accepted while closing: its thread closed it, or this does
        with self._lock:
            late = [c for c in self._clients if c not in clients]
        for c in late:
            _close(c)

    def __enter__(self) -> FakeRobotiq:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _accept(self) -> None:
        assert self._server is not None
        while not self._stop.is_set():
            try:
                conn, _ = self._server.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            conn.settimeout(0.05)
            with self._lock:
                self._clients.append(conn)
            t = threading.Thread(target=self._serve, args=(conn,), daemon=True)
            t.start()
            self._threads.append(t)

    def _serve(self, conn: socket.socket) -> None:
        try:
            self._serve_lines(conn)
        finally:  # every accepted socket is closed when its thread ends
            _close(conn)

    def _serve_lines(self, conn: socket.socket) -> None:
        buf = b""
        while not self._stop.is_set():
            try:
                chunk = conn.recv(1024)
            except TimeoutError:
                continue
            except OSError:
                return
            if not chunk:
                _close(conn)
                return
            buf += chunk
            while b"\n" in buf:
                raw, _, buf = buf.partition(b"\n")
                line = raw.decode("ascii", "replace").strip()
                with self._lock:
                    self.commands.append(line)
                if self.drop_on is not None and line.startswith(self.drop_on):
                    _close(conn)
                    return
                if self.stall_on is not None and line.startswith(self.stall_on):
                    continue
                if self.garbage_on is not None and line.startswith(self.garbage_on):
                    reply = self.garbage
                else:
                    reply = self._handle(line)
                try:
                    conn.sendall(reply)
                except OSError:
                    return

    # -- the gripper ------------------------------------------------------------------

    def _handle(self, line: str) -> bytes:
        words = line.split()
        with self._lock:
            self._advance()
            if len(words) >= 3 and words[0] == "SET" and len(words) % 2 == 1:
                pairs = list(zip(words[1::2], words[2::2], strict=True))
                for name, value in pairs:
                    self._set(name, int(value))
                if "GTO" in dict(pairs) or "POS" in dict(pairs):
                    self._go()
                return b"ack\n" if self.newline_after_ack else b"ack"
            if len(words) == 2 and words[0] == "GET":
                value = self._get(words[1])
                if value is not None:
                    text = f"{words[1]} {value}"
                    return (text + "\n" if self.newline_after_get else text).encode()
            return b"?\n"

    def _set(self, name: str, value: int) -> None:
        if name == "POS":
            self.regs["PRE"] = value
        elif name == "ACT":
            if value == 0:
                self.regs.update(ACT=0, STA=0, GTO=0)
                self._motion = None
                self._activated_at = None
                self.fault = 0
            elif self.regs["ACT"] == 0:
                self.regs.update(ACT=1, STA=1)
                self._activated_at = time.monotonic()
        else:
            self.regs[name] = value

    def _get(self, name: str) -> int | None:
        if name == "POS":
            return self._pos
        if name == "OBJ":
            return self._obj()
        if name == "FLT":
            return self.fault
        return self.regs.get(name)

    def _go(self) -> None:
        if self.regs["GTO"] != 1 or self.regs["STA"] != 3:
            return
        target = self.regs["PRE"]
        start = self._pos
        stop = min(max(target, self.open_stop), self.closed_stop)
        obj = 3
        if target > start and self.object_at is not None and start < self.object_at <= stop:
            stop, obj = self.object_at, 2
        if target < start and self.outer_object_at is not None:
            if stop <= self.outer_object_at < start:
                stop, obj = self.outer_object_at, 1
        self._motion = _Motion(start, target, stop, time.monotonic(), obj)

    def _advance(self) -> None:
        now = time.monotonic()
        if self._activated_at is not None and self.regs["STA"] == 1:
            if now - self._activated_at >= self.activation_time:
                self.regs["STA"] = 3
                self._pos = self.open_stop
        m = self._motion
        if m is None:
            return
        counts = int((now - m.t0) / self.stroke_time * 255)
        if m.stop >= m.start:
            self._pos = min(m.start + counts, m.stop)
        else:
            self._pos = max(m.start - counts, m.stop)

    def _obj(self) -> int:
        m = self._motion
        if m is None:
            return 3 if self.regs["STA"] == 3 else 0
        return m.obj_at_stop if self._pos == m.stop else 0

    def sent(self) -> list[str]:
        """A copy of the commands received so far."""
        with self._lock:
            return list(self.commands)


def _close(s: socket.socket) -> None:
    try:
        s.shutdown(socket.SHUT_RDWR)
    except OSError:
        pass
    s.close()
