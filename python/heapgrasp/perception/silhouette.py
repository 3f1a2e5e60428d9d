"""Shape from Silhouette (HEAPGrasp §IV-A, eq. 9-10): every captured frame's silhouette
carved into the occupancy grid (Rust core), serving the high-confidence grid ``Ŝ≥λ`` —
roofs trimmed and checked against the silhouettes (:mod:`heapgrasp.perception.roofs`),
and, as an extension, remembered from one phase to the next."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy import ndimage

from heapgrasp import OccupancyGrid, PinholeCamera
from heapgrasp.geometry.grid import GridFrame
from heapgrasp.perception.frames import Frame
from heapgrasp.perception.roofs import SilhouetteView, keep_silhouettes, trim_roofs
from heapgrasp.perception.segmenters import Segmenter

__all__ = ["SilhouettePerception", "grid_agreement"]

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]

#: Visibility count given to the voxels a remembered phase carved: no number of frames
#: that see them segmented brings them back over λ.
_CARVED_FOR_GOOD = 1 << 24

#: Voxels within this many of a remembered hull are remembered as occupied, not carved:
#: an object that settles by less than this when its neighbour is taken stays inside.
MEMORY_MARGIN = 1


@dataclass(frozen=True)
class _Remembered:
    occupied: npt.NDArray[np.bool_]
    carved: npt.NDArray[np.bool_]
    views: list[SilhouetteView]


@dataclass
class SilhouettePerception:
    """Shape from Silhouette over every captured frame (eq. 9-10).

    ``roof_radius`` > 0 trims the roofs of the grasp planner's input
    (:func:`heapgrasp.perception.roofs.trim_roofs`, disc radius in metres) and puts back what the
    silhouettes of ``silhouette_views`` of the frames (evenly spaced; 0: none) show to be
    real (:func:`heapgrasp.perception.roofs.keep_silhouettes`); ``roof_radius`` = 0 serves ``Ŝ≥λ``
    as it is.

    ``memory`` (not in the paper) carries what a phase carved into the next one, see
    :meth:`remember`."""

    frame: GridFrame
    segmenter: Segmenter
    lam: float = 0.9
    roof_radius: float = 0.0
    silhouette_views: int = 24
    memory: bool = False
    memory_tolerance: int = 8
    """With ``memory``: at most this many voxels may be missing from the remembered hull
    to explain the new phase's first silhouettes before the memory is dropped."""

    def __post_init__(self) -> None:
        if (
            isinstance(self.silhouette_views, bool)
            or not isinstance(self.silhouette_views, int)
            or self.silhouette_views < 0
        ):
            raise ValueError(
                f"silhouette_views must be an integer >= 0, got {self.silhouette_views!r}"
            )
        if not 0.0 <= self.lam <= 1.0:
            raise ValueError(f"lam must be in [0, 1], got {self.lam}")
        if not (np.isfinite(self.roof_radius) and self.roof_radius >= 0):
            raise ValueError(f"roof_radius must be >= 0, got {self.roof_radius}")
        self.grid = OccupancyGrid(self.frame.origin, self.frame.size, self.frame.resolution)
        if isinstance(self.memory_tolerance, bool) or not (
            isinstance(self.memory_tolerance, int) and self.memory_tolerance >= 0
        ):
            raise ValueError(
                f"memory_tolerance must be an integer >= 0, got {self.memory_tolerance!r}"
            )
        self.frames_seen = 0
        self.last_mask: npt.NDArray[np.bool_] | None = None
        """The silhouette of the last frame integrated."""
        self.views: list[SilhouetteView] = []
        self._positions: list[npt.NDArray[np.float64]] = []
        self._remembered: _Remembered | None = None
        self._unchecked = False
        self.memory_record: dict[str, Any] | None = None
        """How the phase began with ``memory``: None without a remembered hull, else
        ``{"restored_voxels": n, "kept": bool}`` (:meth:`remember`)."""

    def reset(self) -> None:
        """Forgets every frame (a new phase). With ``memory`` and a hull remembered
        (:meth:`remember`), the grid starts from it instead of from nothing."""
        self.grid.reset()
        self.frames_seen = 0
        self.views = []
        self._positions = []
        self.memory_record = None
        self._unchecked = False
        if self.memory and self._remembered is not None:
            self._install(self._remembered)
            self._unchecked = True

    def remember(self) -> None:
        """With ``memory``: keeps what the grid has carved so far for the next phase.

        The scene between two phases differs by what the grasp did: the object it took
        is gone and others may have moved. What a phase carved stays empty unless an
        object moved there, so the next phase's grid starts with those voxels carved for
        good (their visibility count set beyond any number of frames), and with the
        remembered hull's voxels occupied as if seen once: the first frame that sees
        one as background carves it (the object that was taken, an object that moved
        away). Whether an object moved *into* remembered free space is checked against
        the first silhouettes of the next phase (:meth:`update`): a part of the mask that
        the remembered hull cannot explain drops the memory, and the phase goes on from
        its own frames alone. The silhouettes are remembered with the hull (for the
        check after roof trimming), the camera positions are not: the critic reads them
        as the views the hull near a grasp was carved from, and where an object was taken
        only the new phase's views have carved."""
        if not self.memory:
            return
        _, visible = self.grid.counts()
        seen = visible > 0
        high = self.grid.high_confidence(self.lam) > 0
        occupied = seen & ndimage.binary_dilation(high, iterations=MEMORY_MARGIN)
        carved = seen & ~occupied
        self._remembered = _Remembered(occupied, carved, list(self.views))

    def forget(self) -> None:
        """Drops the remembered hull (a new scene)."""
        self._remembered = None

    def _install(self, remembered: _Remembered) -> None:
        occupied, carved = remembered.occupied, remembered.carved
        segmented = occupied.astype(np.uint32)
        visible = segmented + carved.astype(np.uint32) * np.uint32(_CARVED_FOR_GOOD)
        self.grid = OccupancyGrid.from_counts(
            self.frame.origin, self.frame.size, segmented, visible
        )
        self.views = list(remembered.views)

    def camera_positions(self) -> npt.NDArray[np.float64]:
        """``(frames, 3)`` camera positions of the phase's frames (world, m)."""
        if not self._positions:
            return np.zeros((0, 3))
        return np.concatenate(self._positions)

    def update(self, frames: Sequence[Frame]) -> None:
        """Segments and carves ``frames`` (all with the same camera)."""
        if not frames:
            return
        camera: PinholeCamera = frames[0].camera.core()
        masks = np.stack([self.segmenter.segment(f) for f in frames])
        self.last_mask = masks[-1]
        poses = np.stack([f.cam2world for f in frames])
        self.grid.integrate_many(masks, camera, np.ascontiguousarray(poses))
        self.frames_seen += len(frames)
        if self._unchecked:
            self._check_memory(camera, masks, poses)
        self._positions.append(poses[:, :3, 3].astype(np.float64))
        if self.roof_radius > 0 and self.silhouette_views > 0:
            self.views.extend(
                SilhouetteView(camera, p, m) for p, m in zip(poses, masks, strict=True)
            )

    def _check_memory(
        self, camera: PinholeCamera, masks: npt.NDArray[np.bool_], poses: F64
    ) -> None:
        """The first frames of a phase begun from a remembered hull: the voxels of the
        new frames' own hull needed to explain their silhouettes beyond what the
        remembered hull explains (:func:`~heapgrasp.perception.roofs.keep_silhouettes`) count what
        moved into remembered free space; more than ``memory_tolerance`` drop the
        memory. Voxels that no remembered frame saw explain nothing here: the new frames
        fill them in any case."""
        assert self._remembered is not None
        self._unchecked = False
        fresh = OccupancyGrid(self.frame.origin, self.frame.size, self.frame.resolution)
        fresh.integrate_many(masks, camera, np.ascontiguousarray(poses))
        own = fresh.high_confidence(self.lam) > 0
        known = self._remembered.occupied
        views = [SilhouetteView(camera, p, m) for p, m in zip(poses, masks, strict=True)]
        restored = keep_silhouettes(
            own | known, known, self.frame.origin, self.grid.voxel_size, views
        )
        missing = int(np.count_nonzero(restored > 0) - np.count_nonzero(known))
        kept = missing <= self.memory_tolerance
        self.memory_record = {"restored_voxels": missing, "kept": kept}
        if not kept:
            self.grid = fresh
            self.views = []

    def occupancy(self) -> F32:
        """``Ŝ_{0-1}`` (eq. 10)."""
        return self.grid.occupancy()

    def local_grid(
        self, centre: npt.ArrayLike, size: float, resolution: int
    ) -> tuple[OccupancyGrid, GridFrame]:
        """The phase's silhouettes (the frames of :attr:`views`) carved again into a cube
        of side ``size`` (m) centred at ``centre`` (world, m), ``resolution`` voxels per
        axis, kept above the table (``z >= 0``): the counts and where the cube lies.
        Without silhouettes kept (``roof_radius`` = 0 keeps none) nothing is carved."""
        c = np.asarray(centre, dtype=np.float64).reshape(3)
        if not np.isfinite(c).all():
            raise ValueError(f"centre must be 3 finite numbers, got {centre!r}")
        origin = c - size / 2
        origin[2] = max(float(origin[2]), 0.0)
        frame = GridFrame((float(origin[0]), float(origin[1]), float(origin[2])), size, resolution)
        grid = OccupancyGrid(frame.origin, frame.size, frame.resolution)
        by_camera: dict[tuple[float, ...], list[SilhouetteView]] = {}
        for v in self.views:
            cam = v.camera
            key = (cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy)
            by_camera.setdefault(key, []).append(v)
        for views in by_camera.values():
            grid.integrate_many(
                np.stack([v.mask for v in views]),
                views[0].camera,
                np.ascontiguousarray(np.stack([v.cam2world for v in views])),
            )
        return grid, frame

    def local_input(
        self, centre: npt.ArrayLike, size: float = 0.16, resolution: int = 64
    ) -> tuple[F32, GridFrame]:
        """The grasp planner's input (:meth:`grasp_input`) of the cube of
        :meth:`local_grid` (a finer one, or one reaching beyond the grid), and where it
        lies; empty without silhouettes kept."""
        grid, frame = self.local_grid(centre, size, resolution)
        if not self.views:
            return np.zeros((resolution,) * 3, dtype=np.float32), frame
        return self.planner_input(grid.high_confidence(self.lam), frame), frame

    def planner_input(self, high: F32, frame: GridFrame) -> F32:
        """``high`` (``Ŝ≥λ`` of a grid at ``frame``, e.g. of :meth:`local_grid`) as the
        planner reads it: roofs trimmed and what the silhouettes show put back
        (:meth:`grasp_input`)."""
        if self.roof_radius <= 0:
            return high
        trimmed = trim_roofs(high, frame.voxel_size, self.roof_radius)
        if self.silhouette_views == 0 or not self.views:
            return trimmed
        n = len(self.views)
        pick = np.unique(np.linspace(0, n - 1, min(n, self.silhouette_views)).round().astype(int))
        return keep_silhouettes(
            high, trimmed, frame.origin, frame.voxel_size, [self.views[i] for i in pick]
        )

    def grasp_input(self) -> F32:
        """The grasp planner's input: the high-confidence grid ``Ŝ≥λ``; when
        ``roof_radius`` > 0 with its roofs trimmed (:func:`~heapgrasp.perception.roofs.trim_roofs`)
        and, when ``silhouette_views`` > 0, what the trimming cut that up to that many of
        the phase's silhouettes (evenly spaced) show to be real put back
        (:func:`~heapgrasp.perception.roofs.keep_silhouettes`)."""
        return self.planner_input(self.grid.high_confidence(self.lam), self.frame)


def grid_agreement(measured: npt.ArrayLike, reference: npt.ArrayLike) -> dict[str, float | None]:
    """How far an occupancy grid is from a reference grid of the same shape (HEAPGrasp
    Table V: the high-confidence grids of noisy and noise-free masks):
    ``mse_percent``, the mean squared difference of the binary grids in percent of the
    voxels (Table V's MSE column, whose 1.63 at an IoU of 0.03 fits this scale: a 5-object
    hull fills ~1.6 % of a 40³ grid), and ``iou``, intersection over union of the
    occupied voxels (None where both are empty)."""
    a = np.asarray(measured, dtype=bool)
    b = np.asarray(reference, dtype=bool)
    if a.shape != b.shape:
        raise ValueError(f"grids of shapes {a.shape} and {b.shape} cannot be compared")
    union = int(np.count_nonzero(a | b))
    inter = int(np.count_nonzero(a & b))
    return {
        "mse_percent": 100.0 * float(np.count_nonzero(a ^ b)) / max(a.size, 1),
        "iou": inter / union if union else None,
    }
