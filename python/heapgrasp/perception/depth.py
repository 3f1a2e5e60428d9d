"""The VGN baseline's perception: sensor depth fused into a TSDF."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from heapgrasp import TSDFVolume
from heapgrasp.geometry.grid import GridFrame
from heapgrasp.perception.frames import Frame

__all__ = ["DepthPerception", "tsdf_occupancy", "tsdf_surface"]

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]


def tsdf_occupancy(values: F32, weights: F32) -> F32:
    """Occupancy read off a TSDF: 1 where a voxel was observed at or behind a surface
    (``weight > 0`` and ``value <= 0``), else 0. Unobserved space counts as free, as
    for a depth camera that never saw it."""
    return ((weights > 0) & (values <= 0)).astype(np.float32)


def tsdf_surface(values: F32, frame: GridFrame, weights: F32 | None = None) -> tuple[F64, F64]:
    """The surface a TSDF shows: its zero crossings and their outward unit normals,
    ``(P, 3)`` each (world), the point cloud VGN samples its grasps on
    (``TSDFVolume.extract_point_cloud`` in VGN's data generation).

    A crossing lies between two face neighbours that were both observed
    (``weights > 0``; without ``weights``, a value other than 0, the TSDF's initial
    value) and whose values have opposite signs, where the linear interpolation of the
    two values is 0. Its normal is the TSDF's gradient (central differences, linearly
    interpolated between the two voxels), normalised: it points from behind the surface
    to in front of it. Crossings whose gradient vanishes are left out.
    """
    v = np.asarray(values, dtype=np.float64)
    r = frame.resolution
    if v.shape != (r, r, r):
        raise ValueError(f"values must be {(r, r, r)} for this frame, got {v.shape}")
    seen = (v != 0) if weights is None else (np.asarray(weights) > 0)
    if seen.shape != v.shape:
        raise ValueError(f"weights must be {v.shape}, got {seen.shape}")
    gradient = np.stack(list(np.gradient(v)), axis=-1)
    points, normals = [], []
    for axis in range(3):
        lo = [slice(None)] * 3
        hi = [slice(None)] * 3
        lo[axis], hi[axis] = slice(0, r - 1), slice(1, r)
        a, b = v[tuple(lo)], v[tuple(hi)]
        cross = seen[tuple(lo)] & seen[tuple(hi)] & (a * b < 0)
        idx = np.argwhere(cross)
        t = a[cross] / (a[cross] - b[cross])
        step = np.zeros(3, dtype=np.int64)
        step[axis] = 1
        first = frame.centers(idx)
        points.append(first + t[:, None] * step * frame.voxel_size)
        g0 = gradient[tuple(idx.T)]
        g1 = gradient[tuple((idx + step).T)]
        normals.append(g0 + t[:, None] * (g1 - g0))
    p = np.concatenate(points)
    n = np.concatenate(normals)
    norm = np.linalg.norm(n, axis=1)
    keep = norm > 1e-9
    return p[keep], n[keep] / norm[keep, None]


@dataclass
class DepthPerception:
    """The VGN baseline's perception: sensor depth fused into a TSDF."""

    frame: GridFrame
    truncation: float = 0.03

    def __post_init__(self) -> None:
        if not self.truncation > 0:
            raise ValueError(f"truncation must be > 0, got {self.truncation}")
        self.tsdf = TSDFVolume(
            self.frame.origin, self.frame.size, self.frame.resolution, self.truncation
        )
        self.frames_seen = 0

    def reset(self) -> None:
        """Forgets every frame."""
        self.tsdf.reset()
        self.frames_seen = 0

    def update(self, frames: Sequence[Frame]) -> None:
        """Fuses the frames' sensor depth (they must have been captured with depth)."""
        for f in frames:
            if f.depth is None:
                raise ValueError("DepthPerception needs frames captured with depth=True")
            self.tsdf.integrate(f.depth, f.camera.core(), f.cam2world)
            self.frames_seen += 1

    def tsdf_values(self) -> F32:
        """The TSDF (VGN's network input)."""
        return self.tsdf.values()

    def grasp_input(self) -> F32:
        """Occupancy for an occupancy-based grasp planner (:func:`tsdf_occupancy`)."""
        return tsdf_occupancy(self.tsdf.values(), self.tsdf.weights())
