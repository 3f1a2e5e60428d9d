"""Camera intrinsics for simulation and the projection matrices PyBullet needs.

Conventions are the package's (see :mod:`heapgrasp`): OpenCV camera axes, pixel
centres at integer coordinates, ``u = fx * x / z + cx`` maps a camera point to the
continuous image coordinate whose ``floor(. + 0.5)`` is its pixel.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from heapgrasp import PinholeCamera

__all__ = ["CameraSpec"]


@dataclass(frozen=True)
class CameraSpec:
    """Pinhole intrinsics plus the capture rate.

    Parameters
    ----------
    width, height
        Image size in pixels.
    fx, fy
        Focal lengths in pixels.
    cx, cy
        Principal point in pixels (pixel centres at integers).
    fps
        Capture rate for continuous capture along a trajectory, frames per second.
    near, far
        Clipping planes of PyBullet's renderer, metres (RGB only; depth and masks come
        from the Rust core and are not clipped).
    """

    width: int = 320
    height: int = 240
    fx: float = 270.0
    fy: float = 270.0
    cx: float = 159.5
    cy: float = 119.5
    fps: float = 30.0
    near: float = 0.01
    far: float = 3.0

    def __post_init__(self) -> None:
        if self.width <= 0 or self.height <= 0:
            raise ValueError(f"camera size must be positive, got {self.width}x{self.height}")
        if not (self.fx > 0 and self.fy > 0):
            raise ValueError(f"focal lengths must be > 0, got fx={self.fx}, fy={self.fy}")
        if not self.fps > 0:
            raise ValueError(f"fps must be > 0, got {self.fps}")
        if not 0 < self.near < self.far:
            raise ValueError(f"need 0 < near < far, got near={self.near}, far={self.far}")

    @classmethod
    def continuous(cls) -> CameraSpec:
        """320×240 at 30 fps, VGN's focal length scaled (HEAPGrasp §VI-B)."""
        return cls()

    @classmethod
    def still(cls) -> CameraSpec:
        """VGN's 640×480 camera, fx = fy = 540."""
        return cls(width=640, height=480, fx=540.0, fy=540.0, cx=319.5, cy=239.5)

    def core(self) -> PinholeCamera:
        """The Rust core's camera."""
        return PinholeCamera(self.width, self.height, self.fx, self.fy, self.cx, self.cy)

    def intrinsics(self) -> npt.NDArray[np.float64]:
        """``[width, height, fx, fy, cx, cy]``."""
        return np.array([self.width, self.height, self.fx, self.fy, self.cx, self.cy])

    def gl_projection(self, renderer: str = "tiny") -> list[float]:
        """OpenGL projection matrix (column-major, as PyBullet takes it) whose pixel grid
        matches this camera: pixel ``(u, v)`` of PyBullet's image (row 0 at the top) is
        sampled on the ray ``((u - cx) / fx, (v - cy) / fy, 1)``.

        ``renderer="tiny"`` (PyBullet's ``ER_TINY_RENDERER``) samples triangles at pixel
        corners and flips rows, so the principal point is shifted by (0, 1) pixel; with
        this shift its segmentation equals :meth:`heapgrasp.MeshScene.render_mask`
        exactly (tested). ``renderer="opengl"`` (``ER_BULLET_HARDWARE_OPENGL``) samples at
        pixel centres (shift (0.5, 0.5)).
        """
        if renderer == "tiny":
            ox, oy = 0.0, 1.0
        elif renderer == "opengl":
            ox, oy = 0.5, 0.5
        else:
            raise ValueError(f"renderer must be 'tiny' or 'opengl', got {renderer!r}")
        w, h, n, f = self.width, self.height, self.near, self.far
        m = np.zeros((4, 4))
        m[0, 0] = 2.0 * self.fx / w
        m[0, 2] = 1.0 - 2.0 * (self.cx + ox) / w
        m[1, 1] = 2.0 * self.fy / h
        m[1, 2] = 2.0 * (self.cy + oy) / h - 1.0
        m[2, 2] = -(f + n) / (f - n)
        m[2, 3] = -2.0 * f * n / (f - n)
        m[3, 2] = -1.0
        return [float(x) for x in m.T.reshape(-1)]

    @staticmethod
    def gl_view(cam2world: npt.NDArray[np.float64]) -> list[float]:
        """OpenGL view matrix (column-major) of an OpenCV ``cam2world`` pose."""
        world2cam = np.linalg.inv(cam2world)
        flip = np.diag([1.0, -1.0, -1.0, 1.0])  # OpenCV (y down, z forward) -> OpenGL
        return [float(x) for x in (flip @ world2cam).T.reshape(-1)]
