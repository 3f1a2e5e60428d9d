"""The learned grasp planner of HEAPGrasp §IV-B (eq. 11): a VGN-style
:class:`heapgrasp.nets.GraspNet` run on the high-confidence occupancy grid ``Ŝ≥λ``
(or on a TSDF for the VGN baseline, ``input_kind = "tsdf"``).

PyTorch is imported when a planner is built, not when this module is imported; without
it, building one raises :class:`ImportError` asking to install ``heapgrasp[nets]``.
"""

from __future__ import annotations

import importlib
import os
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from heapgrasp.geometry.grid import GridFrame
from heapgrasp.planning.volumes import GraspVolumes

if TYPE_CHECKING:
    import torch

    from heapgrasp.nets.models import GraspNet

__all__ = ["NetworkGraspPlanner", "validate_grid"]

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


class NetworkGraspPlanner:
    """:class:`heapgrasp.planning.volumes.GraspPlanner` backed by a :class:`GraspNet`.

    Parameters
    ----------
    net_or_path : GraspNet or path-like
        A network (moved to ``device`` and put in eval mode) or a weights file
        (:func:`heapgrasp.nets.load_grasp_net`, which checks it whole: a bad file raises
        :class:`~heapgrasp.geometry.errors.WeightsError` naming it and the problem).
    device : str or torch.device
        Where the network runs (``"cpu"``, ``"cuda"``, ...).

    Notes
    -----
    The grid axes are world-aligned, so the network's quaternions (``x, y, z, w`` in the
    grid's axes) are world quaternions as :class:`GraspVolumes` wants them; widths are in
    metres.
    """

    name = "vgn-net"

    def __init__(
        self,
        net_or_path: GraspNet | str | os.PathLike[str],
        device: str | torch.device = "cpu",
    ) -> None:
        # heapgrasp.nets first: without PyTorch it raises the "install heapgrasp[nets]" hint.
        importlib.import_module("heapgrasp.nets")
        import torch

        from heapgrasp.nets.models import GraspNet
        from heapgrasp.nets.weights import load_grasp_net

        self.device = torch.device(device)
        if isinstance(net_or_path, GraspNet):
            net = net_or_path.to(self.device).eval()
        elif isinstance(net_or_path, str | os.PathLike):
            net = load_grasp_net(net_or_path, self.device)
        else:
            raise TypeError(
                f"net_or_path must be a GraspNet or a weights path, got "
                f"{type(net_or_path).__name__}"
            )
        self.net: GraspNet = net
        self.input_kind: str = "occupancy"
        """``"occupancy"`` (``Ŝ≥λ``, HEAPGrasp) or ``"tsdf"`` (the VGN baseline)."""

    @property
    def resolution(self) -> int:
        """Grid side ``R`` the network reads."""
        return self.net.resolution

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
        import torch

        with torch.inference_mode():
            # A copy: the caller's array may be read-only (from_numpy would warn).
            x = torch.tensor(grids, device=self.device)
            quality, rotation, width = self.net(x[:, None])
            q = quality[:, 0].cpu().numpy()
            rot = rotation.permute(0, 2, 3, 4, 1).cpu().numpy()
            w = width[:, 0].cpu().numpy()
        return [
            GraspVolumes(
                frame=f,
                quality=np.ascontiguousarray(q[i], dtype=np.float32),
                quaternions=np.ascontiguousarray(rot[i], dtype=np.float32),
                widths=np.ascontiguousarray(w[i], dtype=np.float32),
            )
            for i, f in enumerate(frames)
        ]
