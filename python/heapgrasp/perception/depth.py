"""The VGN baseline's perception: sensor depth fused into a TSDF."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from heapgrasp import TSDFVolume
from heapgrasp.geometry.grid import GridFrame
from heapgrasp.perception.frames import Frame

__all__ = ["DepthPerception", "tsdf_occupancy"]

F32 = npt.NDArray[np.float32]


def tsdf_occupancy(values: F32, weights: F32) -> F32:
    """Occupancy read off a TSDF: 1 where a voxel was observed at or behind a surface
    (``weight > 0`` and ``value <= 0``), else 0. Unobserved space counts as free, as
    for a depth camera that never saw it."""
    return ((weights > 0) & (values <= 0)).astype(np.float32)


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
