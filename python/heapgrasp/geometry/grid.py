"""The scene cube and its voxel grid (README "Grids"): where a grid lies in the world."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ["GridFrame"]

F64 = npt.NDArray[np.float64]


@dataclass(frozen=True)
class GridFrame:
    """Where a grid lies in the world: minimum corner, side and resolution."""

    origin: tuple[float, float, float]
    size: float
    resolution: int

    def __post_init__(self) -> None:
        if not (math.isfinite(self.size) and self.size > 0):
            raise ValueError(f"GridFrame.size must be finite and > 0, got {self.size}")
        if not 1 <= self.resolution <= 512:
            raise ValueError(f"GridFrame.resolution must be in [1, 512], got {self.resolution}")
        if len(self.origin) != 3 or not all(math.isfinite(v) for v in self.origin):
            raise ValueError(f"GridFrame.origin must be 3 finite numbers, got {self.origin}")

    @property
    def voxel_size(self) -> float:
        """Edge of a voxel (m)."""
        return self.size / self.resolution

    def centers(self, index: npt.ArrayLike) -> F64:
        """World positions of voxel centres ``origin + (index + 0.5) * voxel_size``."""
        idx = np.asarray(index, dtype=np.float64)
        return np.asarray(self.origin) + (idx + 0.5) * self.voxel_size

    def distance_field(self, point: npt.ArrayLike, scale: float = 0.5) -> npt.NDArray[np.float32]:
        """``(R, R, R)`` float32: each voxel centre's distance to ``point`` (m), divided
        by ``scale`` (the view network's camera channel)."""
        p = np.asarray(point, dtype=np.float64).reshape(3)
        c = (np.arange(self.resolution) + 0.5) * self.voxel_size
        o = np.asarray(self.origin)
        dx = (c + o[0] - p[0])[:, None, None]
        dy = (c + o[1] - p[1])[None, :, None]
        dz = (c + o[2] - p[2])[None, None, :]
        field: npt.NDArray[np.float32] = (np.sqrt(dx * dx + dy * dy + dz * dz) / scale).astype(
            np.float32
        )
        return field

    def index(self, points: npt.ArrayLike) -> npt.NDArray[np.int64]:
        """Voxel index containing each world point (may lie outside ``[0, R)``)."""
        p = np.asarray(points, dtype=np.float64)
        idx: npt.NDArray[np.int64] = np.floor(
            (p - np.asarray(self.origin)) / self.voxel_size
        ).astype(np.int64)
        return idx
