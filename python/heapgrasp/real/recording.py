"""Every frame a real run captures, saved as it is taken, and read back for a replay.

Layout under the run directory::

    frames/scene_000/phase_000/000_look.npz
    frames/scene_000/phase_000/001_follow.npz
    ...

Each file holds one :meth:`~heapgrasp.robot.interfaces.Arm.look` frame or one
:meth:`~heapgrasp.robot.interfaces.Arm.follow` capture: ``rgb`` ``(N, H, W, 3)``,
``depth`` ``(N, H, W)`` where the camera gave depth, ``poses`` ``(N, 4, 4)``
(``cam2world``), ``times`` ``(N,)``, ``intrinsics`` (``CameraSpec`` fields) and the
motion's ``duration``; a rehearsal's (``robot run --sim``) also ``silhouettes``
``(N, H, W)``, the simulator's exact masks, which a replay segments with. Files are
written to a temporary name and renamed, so a crash never leaves a torn file under a
final name.
"""

from __future__ import annotations

import dataclasses
import os
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.geometry.motion import TimedPath
from heapgrasp.perception.frames import Capture, Frame
from heapgrasp.perception.segmenters import MaskSource
from heapgrasp.robot.errors import RobotConfigError
from heapgrasp.robot.interfaces import Arm, Contact

__all__ = [
    "ArmWrapper",
    "Recorded",
    "RecordedSilhouettes",
    "RecordingArm",
    "load_phase",
    "phase_dirs",
    "save_frames",
]

F64 = npt.NDArray[np.float64]


def save_frames(
    path: Path,
    frames: list[Frame],
    kind: str,
    duration: float,
    silhouettes: list[npt.NDArray[np.bool_]] | None = None,
) -> None:
    """Writes ``frames`` (one look or one capture) to ``path`` atomically, with each
    frame's exact silhouette where a rehearsal gives them."""
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays: dict[str, Any] = {
        "kind": np.array(kind),
        "duration": np.array(float(duration)),
        "poses": np.stack([f.cam2world for f in frames]) if frames else np.zeros((0, 4, 4)),
        "times": np.array([f.time for f in frames], dtype=np.float64),
    }
    if frames:
        spec = frames[0].camera
        arrays["intrinsics"] = np.array(
            [spec.width, spec.height, spec.fx, spec.fy, spec.cx, spec.cy, spec.fps]
        )
        if all(f.rgb is not None for f in frames):
            arrays["rgb"] = np.stack([f.rgb for f in frames])  # type: ignore[misc]
        if all(f.depth is not None for f in frames):
            arrays["depth"] = np.stack([f.depth for f in frames])  # type: ignore[misc]
        if silhouettes is not None:
            arrays["silhouettes"] = np.stack(silhouettes).astype(bool)
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as fh:
        np.savez_compressed(fh, **arrays)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)


@dataclass
class Recorded:
    """One saved look or capture."""

    kind: str
    """``look`` or ``follow``."""
    frames: list[Frame]
    duration: float
    path: Path
    silhouettes: list[npt.NDArray[np.bool_]] | None = None
    """Each frame's exact silhouette (a rehearsal's recording), or None."""

    def capture(self) -> Capture:
        """As the :class:`Capture` the arm returned."""
        times = np.array([f.time for f in self.frames], dtype=np.float64)
        return Capture(times, self.frames, self.duration)


def _load(path: Path) -> Recorded:
    """One saved look or capture; a file that cannot be read is a
    :class:`~heapgrasp.robot.errors.RobotConfigError` naming it."""
    try:
        return _read(path)
    except (OSError, EOFError, ValueError, KeyError, zipfile.BadZipFile, zlib.error) as exc:
        raise RobotConfigError(
            f"{path}: a recorded frame file that cannot be read ({type(exc).__name__}: {exc})"
        ) from None


def _read(path: Path) -> Recorded:
    # the file opened here and closed here, whatever np.load makes of it
    with open(path, "rb") as fh, np.load(fh) as z:
        kind = str(z["kind"])
        poses, times = z["poses"], z["times"]
        frames: list[Frame] = []
        if len(poses):
            w, h, fx, fy, cx, cy, fps = z["intrinsics"]
            spec = CameraSpec(
                int(w), int(h), float(fx), float(fy), float(cx), float(cy), float(fps)
            )
            rgb = z["rgb"] if "rgb" in z else None
            depth = z["depth"] if "depth" in z else None
            masks = z["silhouettes"] if "silhouettes" in z else None
            for i in range(len(poses)):
                frames.append(
                    Frame(
                        np.asarray(poses[i], dtype=np.float64),
                        spec,
                        float(times[i]),
                        None if rgb is None else rgb[i],
                        None if depth is None else depth[i],
                    )
                )
            if masks is not None:
                if masks.shape[0] != len(frames):
                    raise ValueError(f"{masks.shape[0]} silhouettes for {len(frames)} frames")
                silhouettes = [np.asarray(m, dtype=bool) for m in masks]
                return Recorded(kind, frames, float(z["duration"]), path, silhouettes)
        return Recorded(kind, frames, float(z["duration"]), path)


def phase_dirs(frames_dir: Path, scene: int) -> list[Path]:
    """The recorded phases of ``scene``, in order."""
    root = frames_dir / f"scene_{scene:03d}"
    return sorted(p for p in root.glob("phase_*") if p.is_dir())


def load_phase(phase_dir: Path) -> list[Recorded]:
    """The looks and captures of one recorded phase, in the order they were taken. They
    are numbered from ``000`` without a gap (:class:`RecordingArm`): a missing one is a
    :class:`~heapgrasp.robot.errors.RobotConfigError` naming it, as is a file that
    cannot be read."""
    files = sorted(phase_dir.glob("*.npz"))
    for k, path in enumerate(files):
        number = path.name.split("_", 1)[0]
        if number != f"{k:03d}":
            raise RobotConfigError(
                f"{phase_dir}: recording {k:03d} is missing (found {path.name} in its place); "
                "the phase cannot be replayed as it was taken"
            )
    return [_load(p) for p in files]


class RecordedSilhouettes:
    """The silhouettes a rehearsal recorded with its frames, by frame time (a
    :class:`~heapgrasp.perception.segmenters.MaskSource` for the replay's segmenter)."""

    def __init__(self, items: list[Recorded]) -> None:
        self._masks: dict[float, npt.NDArray[np.bool_]] = {}
        self.replace(items)

    def replace(self, items: list[Recorded]) -> None:
        """Holds the silhouettes of ``items`` (one phase's) instead."""
        self._masks = {}
        for item in items:
            if item.silhouettes is None:
                continue
            for frame, mask in zip(item.frames, item.silhouettes, strict=True):
                self._masks[frame.time] = mask

    def __bool__(self) -> bool:
        return bool(self._masks)

    def silhouette(self, frame: Frame) -> npt.NDArray[np.bool_]:
        try:
            return self._masks[frame.time]
        except KeyError:
            raise RobotConfigError(
                f"no recorded silhouette for the frame at {frame.time:.4f} s"
            ) from None


class ArmWrapper:
    """An :class:`~heapgrasp.robot.interfaces.Arm` that hands every call to ``arm``;
    subclasses change what they need (:class:`RecordingArm`, the dry run's arm)."""

    def __init__(self, arm: Any) -> None:
        self.arm = arm

    @property
    def camera(self) -> Any:
        return self.arm.camera

    @property
    def clock(self) -> float:
        return float(self.arm.clock)

    @property
    def tcp(self) -> F64:
        return np.asarray(self.arm.tcp, dtype=np.float64)

    def park(self) -> None:
        self.arm.park()

    def look(self, cam2world: F64) -> Frame:
        frame: Frame = self.arm.look(cam2world)
        return frame

    def follow(self, path: TimedPath) -> Capture:
        cap: Capture = self.arm.follow(path)
        return cap

    def move_to(self, tcp: F64, *, opening: float) -> None:
        self.arm.move_to(tcp, opening=opening)

    def move_linear(self, tcp: F64, *, speed: float = 0.1, stop_on_contact: bool = False) -> bool:
        return bool(self.arm.move_linear(tcp, speed=speed, stop_on_contact=stop_on_contact))

    def contact(self) -> Contact | None:
        touching: Contact | None = self.arm.contact()
        return touching


class RecordingArm(ArmWrapper):
    """An arm that saves every frame it returns (:func:`save_frames`) under
    ``frames_dir/scene_SSS/phase_PPP/``; call :meth:`begin_phase` before each phase.
    ``silhouettes``: a rehearsal's exact masks, saved with each frame."""

    def __init__(
        self,
        arm: Arm | ArmWrapper,
        frames_dir: Path,
        scene: int,
        silhouettes: MaskSource | None = None,
    ) -> None:
        super().__init__(arm)
        self.silhouettes = silhouettes
        self.frames_dir = frames_dir
        self.scene = scene
        self.phase = -1
        self._count = 0
        self.saved: list[Path] = []

    def _masks(self, frames: list[Frame]) -> list[npt.NDArray[np.bool_]] | None:
        if self.silhouettes is None or not frames:
            return None
        return [self.silhouettes.silhouette(f) for f in frames]

    def begin_phase(self) -> None:
        """The next frames belong to a new phase."""
        self.phase += 1
        self._count = 0

    def _path(self, kind: str) -> Path:
        phase = max(self.phase, 0)
        name = f"scene_{self.scene:03d}/phase_{phase:03d}/{self._count:03d}_{kind}.npz"
        self._count += 1
        return self.frames_dir / name

    def look(self, cam2world: F64) -> Frame:
        frame = super().look(cam2world)
        path = self._path("look")
        save_frames(path, [frame], "look", 0.0, self._masks([frame]))
        self.saved.append(path)
        return frame

    def follow(self, path: TimedPath) -> Capture:
        cap = super().follow(path)
        out = self._path("follow")
        save_frames(out, cap.frames, "follow", cap.duration, self._masks(cap.frames))
        self.saved.append(out)
        return cap


def spec_dict(spec: CameraSpec) -> dict[str, Any]:
    """A camera's intrinsics as plain data."""
    return dataclasses.asdict(spec)
