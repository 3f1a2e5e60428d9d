"""What a camera delivers: frames and the frames captured along a path.

A :class:`Frame` is what any camera — the simulator's or a RealSense on a UR5e — gives
the loop: the image(s), when they were taken, and where the camera was (``cam2world``,
OpenCV axes, README "Poses"). Nothing in it is ground truth: the simulator's exact
silhouettes and object labels live in its own frame type and reach perception only
through the scene truth (:class:`heapgrasp.perception.segmenters.MaskSource`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from heapgrasp.geometry.camera import CameraSpec

__all__ = ["Capture", "Frame"]

F64 = npt.NDArray[np.float64]


@dataclass
class Frame:
    """One captured frame. Images are ``(H, W)`` (``(H, W, 3)`` for RGB) indexed ``[v, u]``."""

    cam2world: F64
    """``(4, 4)`` camera pose when the frame was taken (world, OpenCV axes)."""
    camera: CameraSpec
    """The intrinsics the frame was taken with."""
    time: float = 0.0
    """Timestamp (s) on the robot's clock (the simulator's: simulated time)."""
    rgb: npt.NDArray[np.uint8] | None = None
    """Colour image ``(H, W, 3)``, where the camera delivers one."""
    depth: npt.NDArray[np.float32] | None = None
    """Depth (m), 0 where missing; only where depth was asked for."""


@dataclass
class Capture:
    """Frames captured while the camera moved along a timed path."""

    times: F64
    """Timestamp (s) of each frame."""
    frames: list[Frame]
    duration: float = 0.0
    """How long the motion took (s)."""
    timing_kept: bool = True
    """False where the arm could not keep the path's timing within its limits and
    followed the path more slowly (the simulated Panda: its joint limits)."""

    def __len__(self) -> int:
        return len(self.frames)

    @property
    def poses(self) -> F64:
        """``(N, 4, 4)`` ``cam2world`` of the frames."""
        return np.stack([f.cam2world for f in self.frames]) if self.frames else np.zeros((0, 4, 4))

    @property
    def positions(self) -> F64:
        """``(N, 3)`` camera positions (world, m)."""
        return self.poses[:, :3, 3]
