"""Benchmark scenes shared by the ``heapgrasp bench`` commands.

The fixtures mirror ``benches/src/lib.rs`` (the criterion benchmarks) so that the Rust
and the Python benchmarks measure the same work: the 0.30 m VGN workspace cube with its
minimum corner at the world origin, a ring of cameras looking at it and the exact
silhouettes of three spheres standing on the table.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from heapgrasp.geometry.motion import look_at

__all__ = [
    "CUBE",
    "SPHERES",
    "CameraSpec",
    "camera_spec",
    "look_at",
    "ring",
    "sphere_masks",
]

CUBE: float = 0.30
"""Side of the VGN workspace cube, metres (its minimum corner is the world origin)."""

SPHERES: tuple[tuple[tuple[float, float, float], float], ...] = (
    ((0.10, 0.12, 0.04), 0.04),
    ((0.19, 0.17, 0.03), 0.03),
    ((0.15, 0.08, 0.035), 0.035),
)
"""Spheres ``(centre, radius)`` standing on the table inside the cube, metres."""


@dataclass(frozen=True)
class CameraSpec:
    """Pinhole intrinsics of a benchmark camera.

    Attributes
    ----------
    width, height : int
        Image size in pixels.
    fx, fy, cx, cy : float
        Focal lengths and principal point in pixels (OpenCV convention).
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @property
    def shape(self) -> tuple[int, int]:
        """``(height, width)``, the shape of a mask of this camera."""
        return (self.height, self.width)

    def matrix(self) -> npt.NDArray[np.float64]:
        """The ``(3, 3)`` intrinsic matrix ``K``."""
        return np.array(
            [[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]],
            dtype=np.float64,
        )


def camera_spec(width: int, height: int) -> CameraSpec:
    """VGN's camera scaled to ``width x height``.

    Parameters
    ----------
    width, height : int
        Image size in pixels.

    Returns
    -------
    CameraSpec
        ``fx = fy = 540 * width / 640``, ``cx = width / 2 - 0.5``, ``cy = height / 2 - 0.5``.
    """
    s = width / 640.0
    return CameraSpec(width, height, 540.0 * s, 540.0 * s, width / 2.0 - 0.5, height / 2.0 - 0.5)


def ring(n: int) -> npt.NDArray[np.float64]:
    """``n`` cameras on a circle around the cube, looking at a point near its floor.

    The circle has radius 0.45 m around the cube's vertical axis, 0.35 m above the
    table; every camera looks at ``(0.15, 0.15, 0.05)``.

    Parameters
    ----------
    n : int
        Number of cameras.

    Returns
    -------
    numpy.ndarray, shape (n, 4, 4), float64
        The ``cam2world`` poses.
    """
    c = CUBE / 2.0
    poses = np.empty((n, 4, 4), dtype=np.float64)
    for k in range(n):
        phi = 2.0 * np.pi * k / n
        poses[k] = look_at([c + 0.45 * np.cos(phi), c + 0.45 * np.sin(phi), 0.35], [c, c, 0.05])
    return poses


def sphere_masks(cam: CameraSpec, poses: npt.NDArray[np.float64]) -> npt.NDArray[np.uint8]:
    """Exact silhouettes of :data:`SPHERES` seen from ``poses``.

    A pixel is set iff the ray through its centre hits a sphere in front of the camera.

    Parameters
    ----------
    cam : CameraSpec
        The camera.
    poses : numpy.ndarray, shape (N, 4, 4)
        ``cam2world`` poses.

    Returns
    -------
    numpy.ndarray, shape (N, H, W), uint8
        One 0/1 mask per pose.
    """
    u = (np.arange(cam.width, dtype=np.float64) - cam.cx) / cam.fx
    v = (np.arange(cam.height, dtype=np.float64) - cam.cy) / cam.fy
    rays = np.stack(np.broadcast_arrays(u[None, :], v[:, None], np.ones((1, 1))), axis=-1)
    rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
    out = np.zeros((len(poses), cam.height, cam.width), dtype=np.uint8)
    for k, pose in enumerate(poses):
        rot, eye = pose[:3, :3], pose[:3, 3]
        hit = np.zeros(cam.shape, dtype=bool)
        for centre, radius in SPHERES:
            c = rot.T @ (np.asarray(centre) - eye)  # sphere centre in camera coordinates
            t = rays @ c
            d2 = np.sum((c - rays * t[..., None]) ** 2, axis=-1)  # squared centre-ray distance
            hit |= (t > 0.0) & (d2 <= radius * radius)
        out[k] = hit
    return out
