"""A phase observer that records to a ``.rrd`` file with rerun-sdk.

Entities (world frame, metres, z up):

* ``world/scene`` — the scene cube;
* ``world/camera`` — the hand-eye camera (pose and intrinsics), with its ``image`` (RGB,
  where the camera delivers one) and ``mask`` (the silhouette carved);
* ``world/camera_path`` — the camera's path in the phase so far;
* ``world/grid/occupancy`` and ``world/grid/high_confidence`` — eq. 10's grid after each
  frame (the voxels at occupancy ≥ 0.5, blue to red with it) and ``Ŝ≥λ`` (boxes);
* ``world/waypoints`` — the waypoints visited (view, fixed or sweep);
* ``world/grasps/candidates``, ``world/grasps/target``, ``world/grasps/executed`` —
  approach arrows 5 cm long ending at the TCP; the executed one is green on success;
* ``log`` — one line per event.

Timelines: ``phase`` (its index in the scene), ``frame`` (frames so far) and ``time``
(the robot's clock, s), so each phase plays back frame by frame.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import numpy.typing as npt

from heapgrasp import OccupancyGrid
from heapgrasp.geometry.grid import GridFrame
from heapgrasp.loop.observe import PhaseObserver
from heapgrasp.perception.frames import Frame
from heapgrasp.planning.volumes import GraspCandidate
from heapgrasp.robot.grasping import Grasp, GraspOutcome

__all__ = ["ENTITIES", "RerunRecorder", "import_rerun", "recorded_entities"]

F64 = npt.NDArray[np.float64]

#: Every entity a recording of a phase with a grasp holds.
ENTITIES = (
    "/world/scene",
    "/world/camera",
    "/world/camera/mask",
    "/world/camera_path",
    "/world/grid/occupancy",
    "/world/grid/high_confidence",
    "/world/waypoints",
    "/world/grasps/candidates",
    "/world/grasps/target",
    "/world/grasps/executed",
    "/log",
)

_ARROW = 0.05  # length of a grasp's approach arrow (m)


def import_rerun() -> ModuleType:
    """rerun-sdk, or an ImportError that says how to install it."""
    try:
        import rerun
    except ImportError as err:  # pragma: no cover - depends on the install
        raise ImportError(
            "recording a run needs rerun-sdk: pip install 'heapgrasp[viz]' "
            "(or pip install rerun-sdk)"
        ) from err
    return rerun


def _arrows(poses: Sequence[F64]) -> tuple[F64, F64]:
    """Origins and vectors of approach arrows ending at each TCP (z = approach)."""
    if not poses:
        return np.zeros((0, 3)), np.zeros((0, 3))
    p = np.stack(poses)
    vectors = _ARROW * p[:, :3, 2]
    return p[:, :3, 3] - vectors, vectors


class RerunRecorder(PhaseObserver):
    """Records every event of the phases it observes (see the module docstring)."""

    def __init__(self, path: str | Path, frame: GridFrame, lam: float, *, name: str = "") -> None:
        self.rr = import_rerun()
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.grid_frame = frame
        self.lam = lam
        self.rec: Any = self.rr.RecordingStream("heapgrasp", recording_id=name or None)
        self.rec.save(str(self.path))
        self.frames = 0
        self._intrinsics: object = None
        self.phase = -1
        self._path: list[F64] = []
        self._waypoints: list[F64] = []
        rr = self.rr
        self.rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        half = 0.5 * frame.size
        centre = np.asarray(frame.origin) + half
        self.rec.log(
            "world/scene",
            rr.Boxes3D(centers=[centre], half_sizes=[[half, half, half]], colors=[[160, 160, 160]]),
            static=True,
        )

    # ------------------------------------------------------------------ events
    def _log(self, text: str) -> None:
        self.rec.log("log", self.rr.TextLog(text))

    def phase_started(self, index: int, start: F64) -> None:
        self.phase = index
        self._path = [np.asarray(start[:3, 3], dtype=np.float64)]
        self._waypoints = []
        self.rec.set_time("phase", sequence=index)
        self._log(f"phase {index}: start at {np.round(start[:3, 3], 3).tolist()}")

    def frame(
        self, frame: Frame, mask: npt.NDArray[np.bool_] | None, grid: OccupancyGrid | None
    ) -> None:
        rr, rec = self.rr, self.rec
        self.frames += 1
        rec.set_time("frame", sequence=self.frames)
        rec.set_time("time", duration=float(frame.time))
        pose = frame.cam2world
        cam = frame.camera
        rec.log("world/camera", rr.Transform3D(translation=pose[:3, 3], mat3x3=pose[:3, :3]))
        if cam != self._intrinsics:  # the intrinsics change only with the camera
            self._intrinsics = cam
            rec.log(
                "world/camera",
                rr.Pinhole(
                    focal_length=[cam.fx, cam.fy],
                    principal_point=[cam.cx, cam.cy],
                    width=cam.width,
                    height=cam.height,
                    camera_xyz=rr.ViewCoordinates.RDF,
                    image_plane_distance=0.05,
                ),
                static=True,
            )
        if frame.rgb is not None:
            # JPEG: a phase's hundred frames stay a few MB
            rec.log("world/camera/image", rr.Image(frame.rgb).compress(jpeg_quality=85))
        if mask is not None:
            rec.log("world/camera/mask", rr.SegmentationImage(mask.astype(np.uint8)))
        self._path.append(np.asarray(pose[:3, 3], dtype=np.float64))
        rec.log("world/camera_path", rr.LineStrips3D([np.stack(self._path)]))
        if grid is not None:
            self._grid(grid)

    def _grid(self, grid: OccupancyGrid) -> None:
        rr = self.rr
        occupancy = grid.occupancy()
        # At least even odds: every voxel a silhouette ever covered would be ten times more.
        seen = np.argwhere(occupancy >= 0.5)
        centres = self.grid_frame.centers(seen)
        shade = (255 * (2.0 * occupancy[tuple(seen.T)] - 1.0)).astype(np.uint8)
        colors = np.stack([shade, 64 * np.ones_like(shade), 255 - shade], axis=1)
        radius = 0.35 * self.grid_frame.voxel_size
        self.rec.log("world/grid/occupancy", rr.Points3D(centres, colors=colors, radii=radius))
        high = np.argwhere(grid.high_confidence(self.lam) > 0)
        half = 0.5 * self.grid_frame.voxel_size
        self.rec.log(
            "world/grid/high_confidence",
            rr.Boxes3D(
                centers=self.grid_frame.centers(high),
                half_sizes=np.full((len(high), 3), half),
                colors=[[230, 160, 40]],
            ),
        )

    def waypoint(self, pose: F64, kind: str) -> None:
        self._waypoints.append(np.asarray(pose[:3, 3], dtype=np.float64))
        self.rec.log(
            "world/waypoints",
            self.rr.Points3D(np.stack(self._waypoints), radii=0.01, colors=[[40, 120, 255]]),
        )
        self._log(f"phase {self.phase}: {kind} waypoint {np.round(pose[:3, 3], 3).tolist()}")

    def candidates(self, candidates: Sequence[GraspCandidate]) -> None:
        origins, vectors = _arrows([c.pose for c in candidates])
        scores = np.asarray([c.score for c in candidates], dtype=np.float64)
        shade = (255 * np.clip(scores, 0.0, 1.0)).astype(np.uint8)
        colors = np.stack([255 - shade, shade, np.zeros_like(shade)], axis=1)
        self.rec.log(
            "world/grasps/candidates",
            self.rr.Arrows3D(origins=origins, vectors=vectors, colors=colors),
        )

    def target(self, target: GraspCandidate | None) -> None:
        origins, vectors = _arrows([] if target is None else [target.pose])
        self.rec.log(
            "world/grasps/target",
            self.rr.Arrows3D(origins=origins, vectors=vectors, colors=[[255, 255, 0]], radii=0.004),
        )

    def phase_ended(self, grasp: Grasp | None) -> None:
        self._log(f"phase {self.phase}: " + ("no candidate" if grasp is None else "grasp planned"))

    def grasp(self, grasp: Grasp, outcome: GraspOutcome) -> None:
        origins, vectors = _arrows([grasp.pose])
        color = [40, 200, 40] if outcome == GraspOutcome.SUCCESS else [220, 40, 40]
        self.rec.log(
            "world/grasps/executed",
            self.rr.Arrows3D(
                origins=origins,
                vectors=vectors,
                colors=[color],
                radii=0.005,
                labels=[outcome.value],
            ),
        )
        self._log(f"phase {self.phase}: grasp {outcome.value}")

    def close(self) -> None:
        """Writes everything to the file."""
        self.rec.flush()
        self.rec.disconnect()


def recorded_entities(path: str | Path) -> set[str]:
    """The entity paths a ``.rrd`` file holds."""
    import rerun.chunk

    store = rerun.chunk.RrdReader(str(path)).store()
    return {str(chunk.entity_path) for chunk in store.stream()}
