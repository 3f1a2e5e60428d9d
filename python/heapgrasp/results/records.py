"""A run directory: its configuration, its scene records, and who is writing it.

A run writes, in its directory:

* ``config.json`` — the full :class:`~heapgrasp.loop.config.RunConfig`;
* ``scenes.jsonl`` — one JSON record per finished scene, keyed by ``"scene"`` (its
  index in the run), appended, flushed and synced as the scene ends;
* ``results.json`` — the aggregate, rewritten (atomically) after every scene;
* ``.lock`` — held (``flock``) by the process writing the directory, with its pid.

:class:`RunDir` reads them strictly: a record that is not a JSON object with an integer
``scene`` inside the run, or a scene recorded twice, is an error naming the file and the
line, never a count. The one exception is a torn last line (a write cut short by a
kill): it is ignored on reading and cut off before the next append, so every record
starts on a clean line.
"""

from __future__ import annotations

import fcntl
import json
import os
import socket
import sys
import time
from pathlib import Path
from types import TracebackType
from typing import Any

from heapgrasp.loop.config import ConfigError, RunConfig

__all__ = [
    "CONFIG_FILE",
    "LOCK_FILE",
    "RESULTS_FILE",
    "SCENES_FILE",
    "SETTINGS_BEFORE_THEY_EXISTED",
    "RecordError",
    "RunDir",
    "RunLockedError",
    "write_json",
]

SCENES_FILE = "scenes.jsonl"
RESULTS_FILE = "results.json"
CONFIG_FILE = "config.json"
LOCK_FILE = ".lock"
#: Settings added after runs were saved whose default is not the behaviour those runs
#: had: a ``config.json`` without the key is read with this value (the run's own), so
#: that ``--resume``, ``show`` and ``replay`` run it as it ran. Settings whose default
#: is the old behaviour need no entry.
SETTINGS_BEFORE_THEY_EXISTED: dict[str, Any] = {"look_again": 0, "fine_width": False}


class RecordError(ValueError):
    """A run directory's records cannot be trusted (the message names file and line)."""


class RunLockedError(RuntimeError):
    """Another process is writing the run directory."""


class RunDir:
    """The files of one run (see the module docstring)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._lock_fd: int | None = None

    @property
    def scenes_file(self) -> Path:
        return self.path / SCENES_FILE

    @property
    def config_file(self) -> Path:
        return self.path / CONFIG_FILE

    @property
    def results_file(self) -> Path:
        return self.path / RESULTS_FILE

    # ------------------------------------------------------------------ config
    def read_config(self) -> RunConfig | None:
        """The saved configuration; None where there is no ``config.json``. A file that
        cannot be read as a configuration is a :class:`ConfigError` naming it."""
        path = self.config_file
        if not path.exists():
            return None
        try:
            data = json.loads(path.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise ConfigError(f"{path}: cannot be read as a run's configuration: {exc}") from None
        if not isinstance(data, dict):
            raise ConfigError(f"{path}: a run's configuration is a JSON object, not {data!r:.40}")
        # a run saved before a setting existed ran with that setting's "off" value
        missing = {k: v for k, v in SETTINGS_BEFORE_THEY_EXISTED.items() if k not in data}
        return RunConfig.from_mapping({**data, **missing}, source=str(path))

    def write_config(self, config: RunConfig) -> None:
        """Writes ``config.json`` atomically."""
        write_json(self.config_file, config.to_dict())

    # ------------------------------------------------------------------ records
    def records(self, scenes: int | None = None) -> list[dict[str, Any]]:
        """The scene records in file order. ``scenes``: the run's scene count (default:
        the saved configuration's, if any); a record outside ``[0, scenes)`` is an error,
        and so is a scene recorded twice. A torn last line is ignored with a warning."""
        path = self.scenes_file
        if not path.exists():
            return []
        if scenes is None:
            saved = self.read_config()
            scenes = None if saved is None else saved.scenes
        text = path.read_text()
        lines = text.split("\n")
        torn = lines.pop() if lines else ""  # after the last newline: "" or a torn tail
        if torn.strip():
            print(f"heapgrasp: ignoring a torn last record in {path}", file=sys.stderr)
        records: list[dict[str, Any]] = []
        seen: dict[int, int] = {}
        for number, line in enumerate(lines, start=1):
            if not line.strip():
                continue
            where = f"{path}:{number}"
            try:
                record = json.loads(line)
            except json.JSONDecodeError as exc:
                raise RecordError(f"{where}: not a JSON record ({exc})") from None
            scene = record.get("scene") if isinstance(record, dict) else None
            if isinstance(scene, bool) or not isinstance(scene, int):
                raise RecordError(f"{where}: not a scene record (no integer 'scene'): {line:.60}")
            if scenes is not None and not 0 <= scene < scenes:
                raise RecordError(
                    f"{where}: scene {scene} is not in this run (scenes 0 to {scenes - 1})"
                )
            if scene in seen:
                raise RecordError(
                    f"{where}: scene {scene} is recorded twice (first on line {seen[scene]})"
                )
            seen[scene] = number
            records.append(record)
        return records

    def repair_tail(self) -> bool:
        """Cuts a torn last line off ``scenes.jsonl`` (so that the next record starts on a
        clean line); returns whether there was one."""
        path = self.scenes_file
        if not path.exists():
            return False
        data = path.read_bytes()
        if not data or data.endswith(b"\n"):
            return False
        keep = data.rfind(b"\n") + 1
        with path.open("r+b") as fh:
            fh.truncate(keep)
            fh.flush()
            os.fsync(fh.fileno())
        return True

    def rewrite_records(self, records: list[dict[str, Any]]) -> None:
        """Replaces ``scenes.jsonl`` with ``records`` (atomically)."""
        tmp = self.scenes_file.with_suffix(".jsonl.tmp")
        tmp.write_text("".join(json.dumps(r) + "\n" for r in records))
        tmp.replace(self.scenes_file)

    def append(self, record: dict[str, Any]) -> None:
        """Appends one record as one line, flushed and synced to disk."""
        with self.scenes_file.open("a") as fh:
            fh.write(json.dumps(record) + "\n")
            fh.flush()
            os.fsync(fh.fileno())

    # ------------------------------------------------------------------ lock
    def lock(self) -> RunDir:
        """Takes the directory for this process (created if need be); a second writer
        fails at once with :class:`RunLockedError` naming the holder. The lock is the
        operating system's: it goes with the process, however that ends."""
        self.path.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.path / LOCK_FILE, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 4096, 0).decode(errors="replace").strip() or "another process"
            os.close(fd)
            raise RunLockedError(
                f"{self.path} is being written by {holder}; wait for it to finish, or "
                "choose another --out"
            ) from None
        os.ftruncate(fd, 0)
        holder = (
            f"pid {os.getpid()} on {socket.gethostname()} since "
            f"{time.strftime('%Y-%m-%d %H:%M:%S')} ({' '.join(sys.argv[:3])})"
        )
        os.pwrite(fd, holder.encode(), 0)
        self._lock_fd = fd
        return self

    def unlock(self) -> None:
        """Releases the directory."""
        if self._lock_fd is not None:
            os.ftruncate(self._lock_fd, 0)
            fcntl.flock(self._lock_fd, fcntl.LOCK_UN)
            os.close(self._lock_fd)
            self._lock_fd = None

    def __enter__(self) -> RunDir:
        return self.lock()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.unlock()


def write_json(path: Path, data: dict[str, Any]) -> None:
    """Writes ``data`` to ``path`` atomically (a temporary file, then a rename)."""
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(data, indent=2))
    tmp.replace(path)
