"""The learned view scorer of HEAPGrasp §IV-B (eq. 13): the view network maps the
occupancy grid ``Ŝ_{0-1}`` (eq. 10) to the ``U × V`` view scores, its estimate of the
exact eq. 14 score that :class:`heapgrasp.planning.views.OracleViewScorer` computes from
the true meshes (the network's training labels, Algorithm 1).

Score ``[u, v]`` belongs to the view-waypoint candidate at azimuth ``φ = 2π u / U`` and
polar angle ``θ = θ_max v / V`` (eq. 12, 0-based indices), the layout of
:class:`heapgrasp.planning.views.ViewContext.candidates`.

The network runs from its ONNX file with onnxruntime (:mod:`heapgrasp.inference`);
PyTorch is never imported. Its input (:func:`network_input`) has one or two channels:

0. the occupancy ``Ŝ_{0-1}`` (``grid.occupancy()``), the paper's input;
1. (two-channel networks) the voxels eq. 14 is counted on, 0/1: the target's column
   (:func:`~heapgrasp.planning.views.target_region`, ``target_radius`` around the target
   grasp) where the context has a target and ``target_radius > 0``, else every voxel
   (the paper's eq. 14 over the whole grid), as the oracle counts it;
2. (three-channel networks) where the camera is: each voxel centre's distance to the
   current camera position ``p̄^ℓ`` over 0.5 m
   (:meth:`~heapgrasp.geometry.grid.GridFrame.distance_field`). Eq. 14 scores the
   trajectory ``f(p̄^ℓ, p̄^{u,v})``, so the labels depend on where the camera is; the
   paper's network has to guess it from the carving. Not in the paper.
"""

from __future__ import annotations

import math
import os

import numpy as np
import numpy.typing as npt

from heapgrasp.geometry.grid import GridFrame
from heapgrasp.inference import OnnxNetwork
from heapgrasp.inference.errors import WeightsError
from heapgrasp.planning.grasp_network import validate_grid
from heapgrasp.planning.views import ViewContext, target_region

__all__ = ["NetworkViewScorer", "network_input"]

F32 = npt.NDArray[np.float32]


def network_input(
    occupancy: npt.ArrayLike,
    region: npt.ArrayLike | None,
    in_channels: int,
    camera: npt.ArrayLike | None = None,
) -> F32:
    """The view network's input for one grid: ``(in_channels, R, R, R)`` float32.

    Parameters
    ----------
    occupancy : array_like
        ``(R, R, R)`` occupancy ``Ŝ_{0-1}`` (eq. 10), indexed ``[x, y, z]``.
    region : array_like or None
        ``(R, R, R)`` mask of the voxels eq. 14 is counted on (bool or 0/1), or None for
        all of them; used by two-channel networks only.
    in_channels : {1, 2, 3}
        The network's input channels.
    camera : array_like or None
        ``(R, R, R)`` camera channel (three-channel networks only, required there).
    """
    occ = np.asarray(occupancy, dtype=np.float32)
    if in_channels == 1:
        return np.ascontiguousarray(occ[None])
    if in_channels not in (2, 3):
        raise ValueError(f"view networks read 1, 2 or 3 channels, not {in_channels}")
    mask = np.ones_like(occ) if region is None else np.asarray(region, dtype=np.float32)
    if mask.shape != occ.shape:
        raise ValueError(f"region must have the grid's shape {occ.shape}, got {mask.shape}")
    if in_channels == 2:
        return np.ascontiguousarray(np.stack([occ, mask]))
    if camera is None:
        raise ValueError("a three-channel view network needs the camera channel")
    cam = np.asarray(camera, dtype=np.float32)
    if cam.shape != occ.shape:
        raise ValueError(f"camera must have the grid's shape {occ.shape}, got {cam.shape}")
    return np.ascontiguousarray(np.stack([occ, mask, cam]))


class NetworkViewScorer:
    """:class:`heapgrasp.planning.views.ViewScorer` backed by the view network (eq. 13).

    Parameters
    ----------
    path : path-like
        The network's ONNX file (``kind`` ``view-network``), checked whole when the
        scorer is built: a missing file raises :class:`FileNotFoundError`, a bad one a
        :class:`~heapgrasp.inference.errors.WeightsError` naming it and the problem.
    device : str
        ``cpu``, ``cuda``, ``cuda:N`` or ``auto`` (:func:`heapgrasp.inference.resolve_device`).
    target_radius : float
        Radius (m) of the target's column (module docstring) for two-channel networks;
        0 counts every voxel. A one-channel network cannot be told a region: it scores
        the whole grid whatever this is.
    """

    name = "view-net"

    def __init__(
        self,
        path: str | os.PathLike[str],
        device: str = "cpu",
        *,
        target_radius: float = 0.0,
    ) -> None:
        if not isinstance(path, str | os.PathLike):
            raise TypeError(
                f"path must be the view network's ONNX file, got {type(path).__name__} "
                f"(export a ViewNet with heapgrasp.training.export_onnx)"
            )
        if not (isinstance(target_radius, int | float) and math.isfinite(target_radius)):
            raise ValueError(f"target_radius must be a finite number >= 0, got {target_radius!r}")
        if target_radius < 0:
            raise ValueError(f"target_radius must be >= 0, got {target_radius!r}")
        self.network = OnnxNetwork(path, kind="view-network", device=device)
        self.target_radius = float(target_radius)
        channels = self.network.input.shape[1]
        assert channels is not None
        if channels not in (1, 2, 3):
            raise WeightsError(
                self.network.path,
                f"the view network reads {channels} channels; heapgrasp feeds 1 (occupancy), "
                f"2 (occupancy, region) or 3 (occupancy, region, camera)",
            )
        self.in_channels: int = channels

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

    @property
    def view_shape(self) -> tuple[int, int]:
        """``(U, V)`` of the score map."""
        _, u, v = self.network.outputs[0].shape
        assert u is not None and v is not None
        return (u, v)

    def region(self, ctx: ViewContext) -> npt.NDArray[np.bool_] | None:
        """The voxels eq. 14 is counted on for ``ctx``: the target's column, or None (all)."""
        if self.target_radius <= 0 or ctx.target is None:
            return None
        target = np.asarray(ctx.target, dtype=np.float64)
        return target_region(ctx.grid, target[:3, 3], self.target_radius)

    def scores(self, occupancy: F32 | ViewContext) -> F32:
        """``(U, V)`` float32 view scores in [0, 1] (eq. 13).

        Parameters
        ----------
        occupancy : ndarray or ViewContext
            A :class:`ViewContext` (its grid's ``occupancy()`` and, for two-channel
            networks, the region of :meth:`region`; its ``candidates`` must have the
            map's shape), or the ``(R, R, R)`` float32 occupancy grid ``Ŝ_{0-1}``
            (eq. 10; a two-channel network then counts every voxel).
        """
        region = camera = None
        if isinstance(occupancy, ViewContext):
            grid = occupancy.grid.occupancy()
            want = tuple(occupancy.candidates.shape[:2])
            if want != self.view_shape:
                raise ValueError(
                    f"the view network scores {self.view_shape[0]}×{self.view_shape[1]} "
                    f"candidates, the context has {want[0]}×{want[1]}"
                )
            if self.in_channels >= 2:
                region = self.region(occupancy)
            if self.in_channels == 3:
                g = occupancy.grid
                frame = GridFrame(g.origin, g.size, g.resolution)
                camera = frame.distance_field(np.asarray(occupancy.current_pose)[:3, 3])
        elif self.in_channels == 3:
            raise ValueError(
                "a three-channel view network needs the camera pose: pass a ViewContext"
            )
        else:
            grid = occupancy
        x = validate_grid(grid, self.resolution, "occupancy")
        (scores,) = self.network.run(network_input(x, region, self.in_channels, camera)[None])
        return np.ascontiguousarray(scores[0], dtype=np.float32)
