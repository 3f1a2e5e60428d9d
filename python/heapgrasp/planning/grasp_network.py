"""The learned grasp planner of HEAPGrasp §IV-B (eq. 11): a VGN-style grasp network
(:class:`heapgrasp.training.GraspNet`, exported to ONNX) run on the high-confidence occupancy
grid ``Ŝ≥λ`` (or on a TSDF for the VGN baseline, ``input_kind = "tsdf"``).

The network runs from its ONNX file with onnxruntime (:mod:`heapgrasp.inference`);
PyTorch is never imported.

As VGN's detection masks out the voxels too far from the measured surface, the planner
zeroes the quality of a TSDF network outside VGN's mask (:func:`tsdf_valid`), and that of
an occupancy network outside the region its grasps were labelled in: within
:attr:`NetworkGraspPlanner.hull_margin` and a voxel of the occupied grid, and, for a
network whose voxels hold the palm's face (``grasp_origin = "palm"``), not deep inside
it; elsewhere its quality is an extrapolation (``docs/experiments.md``, "The grasp
network").
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
from scipy import ndimage

from heapgrasp.geometry.grid import GridFrame
from heapgrasp.geometry.gripper import GRASP_DEPTH_RANGE, GRIPPERS
from heapgrasp.inference import OnnxNetwork
from heapgrasp.inference.errors import WeightsError
from heapgrasp.planning.volumes import GraspVolumes

__all__ = ["GRASP_ORIGINS", "INPUT_KINDS", "NetworkGraspPlanner", "tsdf_valid", "validate_grid"]

INPUT_KINDS = ("occupancy", "tsdf")
"""The grids a grasp network reads."""
GRASP_ORIGINS = ("palm", "tcp")
"""Where a network's voxel holds its grasp: VGN's grasp origin (the palm's face) or the
TCP."""

F32 = npt.NDArray[np.float32]


def validate_grid(grid: object, resolution: int, what: str = "grid") -> F32:
    """``grid`` checked to be a finite float32 ``(R, R, R)`` array (``ValueError``
    naming the problem otherwise); returned C-contiguous."""
    r = resolution
    if not isinstance(grid, np.ndarray):
        raise ValueError(f"{what} must be a numpy array, got {type(grid).__name__}")
    if grid.shape != (r, r, r):
        raise ValueError(f"{what} must have shape ({r}, {r}, {r}), got {grid.shape}")
    if grid.dtype != np.float32:
        raise ValueError(f"{what} must be float32, got {grid.dtype}")
    if not np.isfinite(grid).all():
        raise ValueError(f"{what} holds NaN or infinity")
    return np.ascontiguousarray(grid)


def tsdf_valid(values: F32, iterations: int = 2) -> npt.NDArray[np.bool_]:
    """Where a TSDF network's grasp centres may lie: VGN's detection mask (Breyer et
    al. 2020, ``vgn.detection.process``) on heapgrasp's TSDF convention
    (:meth:`heapgrasp.perception.depth.DepthPerception.tsdf_values`: values in
    ``[-1, 1]``, 1 in free space, 0 where unobserved).

    The observed band in front of a surface (``0 < value < 0.98``) grown by
    ``iterations`` voxels, never into the band behind a surface (``value < 0``)."""
    outside = (values > 0) & (values < 0.98)
    inside = values < 0
    if not outside.any():
        return outside
    grown = ndimage.binary_dilation(outside, iterations=iterations, mask=~inside)
    return np.asarray(grown, dtype=bool)


class NetworkGraspPlanner:
    """:class:`heapgrasp.planning.volumes.GraspPlanner` backed by the grasp network.

    Parameters
    ----------
    path : path-like
        The network's ONNX file (``kind`` ``grasp-network``), checked whole when the
        planner is built: a missing file raises :class:`FileNotFoundError`, a bad one a
        :class:`~heapgrasp.inference.errors.WeightsError` naming it and the problem.
    device : str
        ``cpu``, ``cuda``, ``cuda:N`` or ``auto`` (:func:`heapgrasp.inference.resolve_device`).

    Notes
    -----
    The grid axes are world-aligned, so the network's quaternions (``x, y, z, w`` in the
    grid's axes) are world quaternions as :class:`GraspVolumes` wants them; widths are in
    metres.
    """

    name = "vgn-net"
    sigma = 1.0
    """Eq. 15's smoothing of its quality (σ, voxels): VGN's."""
    epsilon = 0.8
    """Eq. 15's threshold (ε): VGN's detection threshold."""
    needs_hull_check = True
    """Its poses are regressed, not checked against the grid it read."""

    def __init__(self, path: str | os.PathLike[str], device: str = "cpu") -> None:
        if not isinstance(path, str | os.PathLike):
            raise TypeError(
                f"path must be the grasp network's ONNX file, got {type(path).__name__} "
                f"(export a GraspNet with heapgrasp.training.export_onnx)"
            )
        self.network = OnnxNetwork(path, kind="grasp-network", device=device)
        if self.network.input.shape[1] != 1:
            raise WeightsError(
                self.network.path,
                f"the grasp network reads {self.network.input.shape[1]} channels; "
                f"heapgrasp feeds 1 (the grid)",
            )
        kind = self._hparam("input_kind", "occupancy", INPUT_KINDS)
        self.input_kind: str = kind
        """The grid the network was trained on (its file's ``input_kind``): ``"occupancy"``
        (``Ŝ≥λ``, HEAPGrasp and no-vp) or ``"tsdf"`` (the VGN baseline)."""
        self.opens_fully: bool = True
        """Its grasps are executed with the hand fully open, as they were labelled (VGN's
        execution; the predicted width is kept in the candidates): opening to the width
        + 1 cm instead took no-vp's success from 48 % to 19 % on 40 scenes
        (``docs/experiments.md``, "The grasp network")."""
        origin = self._hparam("grasp_origin", "tcp", GRASP_ORIGINS)
        self.grasp_origin: str = origin
        """Where a voxel's grasp lies (its file's ``grasp_origin``): ``"palm"``, VGN's
        grasp frame, the centre of the palm's face (the networks trained since
        ``heapgrasp grasps data`` format 2), or ``"tcp"`` (older files)."""
        name = self._hparam("gripper", "panda", tuple(GRIPPERS))
        self.gripper: str = name
        """The hand the network's grasps were labelled for (its file's ``gripper``):
        ``"panda"`` (the shipped networks, and files made before the option) or
        ``"robotiq-2f140"`` (``heapgrasp grasps data --gripper robotiq-2f140``)."""
        hand = GRIPPERS[name]
        self.tcp_offset: float = -hand.palm_front if origin == "palm" else 0.0
        """The TCP's distance ahead of a voxel along the approach (m,
        :attr:`~heapgrasp.planning.volumes.GraspVolumes.tcp_offset`), for :attr:`gripper`."""
        self.hull_margin: float = (
            GRASP_DEPTH_RANGE[1] * hand.finger_depth if origin == "palm" else 0.0
        )
        """How far in front of the occupied grid grasps may lie, m, plus one voxel
        (``occupancy`` input; a TSDF network's output is masked by :func:`tsdf_valid`
        instead): a palm's face lies up to 1.1 finger depths in front of the surface it
        grasps (VGN's sampling), a TCP within the hull."""

    def _hparam(self, name: str, default: str, choices: tuple[str, ...]) -> str:
        """The file's hyper-parameter ``name`` (``default`` where it has none), one of
        ``choices``; a :class:`WeightsError` naming the file otherwise."""
        value = self.network.hparams.get(name, default)
        if value not in choices:
            raise WeightsError(
                self.network.path,
                f"hparams {name} is {value!r}, not one of {', '.join(choices)}",
            )
        return str(value)

    @property
    def device(self) -> str:
        """Where the network runs (``cpu`` or ``cuda[:N]``)."""
        return self.network.device

    @property
    def resolution(self) -> int:
        """Grid side ``R`` the network reads."""
        r = self.network.input.shape[2]
        assert r is not None
        return r

    def _check_frame(self, frame: GridFrame) -> None:
        if not isinstance(frame, GridFrame):
            raise ValueError(f"frame must be a GridFrame, got {type(frame).__name__}")
        if frame.resolution != self.resolution:
            raise ValueError(
                f"frame.resolution is {frame.resolution}, the grasp network reads "
                f"{self.resolution}³ grids"
            )

    def predict(self, grid: F32, frame: GridFrame) -> GraspVolumes:
        """Grasp volumes (eq. 11) of one ``(R, R, R)`` float32 grid."""
        self._check_frame(frame)
        x = validate_grid(grid, self.resolution, "grid")
        (out,) = self._run(x[None], [frame])
        return out

    def predict_batch(
        self, grids: F32, frame: GridFrame | Sequence[GridFrame]
    ) -> list[GraspVolumes]:
        """Grasp volumes of ``B`` grids ``(B, R, R, R)`` float32 in one forward pass.

        ``frame``: one :class:`GridFrame` for all grids, or one per grid."""
        r = self.resolution
        if not isinstance(grids, np.ndarray) or grids.ndim != 4 or len(grids) == 0:
            got = getattr(grids, "shape", type(grids).__name__)
            raise ValueError(f"grids must be a (B >= 1, {r}, {r}, {r}) array, got {got}")
        frames = [frame] * len(grids) if isinstance(frame, GridFrame) else list(frame)
        if len(frames) != len(grids):
            raise ValueError(f"{len(grids)} grids but {len(frames)} frames")
        for f in frames:
            self._check_frame(f)
        for i in range(len(grids)):
            validate_grid(grids[i], r, f"grids[{i}]")
        return self._run(grids, frames)

    def _run(self, grids: F32, frames: Sequence[GridFrame]) -> list[GraspVolumes]:
        quality, rotation, width = self.network.run(grids[:, None])
        rot = rotation.transpose(0, 2, 3, 4, 1)
        for i in range(len(grids)):
            if self.input_kind == "tsdf":
                valid = tsdf_valid(grids[i])
            else:
                occupied = grids[i] > 0
                valid = occupied
                if valid.any():
                    margin = math.ceil(self.hull_margin / frames[i].voxel_size) + 1
                    valid = ndimage.binary_dilation(occupied, iterations=margin)
                if self.grasp_origin == "palm":  # a palm never lies deep in the hull
                    valid &= ~ndimage.binary_erosion(occupied)
            quality[i, 0][~valid] = 0.0
        return [
            GraspVolumes(
                frame=f,
                quality=np.ascontiguousarray(quality[i, 0], dtype=np.float32),
                quaternions=np.ascontiguousarray(rot[i], dtype=np.float32),
                widths=np.ascontiguousarray(width[i, 0], dtype=np.float32),
                tcp_offset=self.tcp_offset,
            )
            for i, f in enumerate(frames)
        ]
