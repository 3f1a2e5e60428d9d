"""The learned view scorer of HEAPGrasp §IV-B (eq. 13): a :class:`heapgrasp.nets.ViewNet`
maps the occupancy grid ``Ŝ_{0-1}`` (eq. 10) to the ``U × V`` view scores, its estimate of
the exact eq. 14 score that :class:`heapgrasp.planning.views.OracleViewScorer` computes from the
true meshes (the network's training labels, Algorithm 1).

Score ``[u, v]`` belongs to the view-waypoint candidate at azimuth ``φ = 2π u / U`` and
polar angle ``θ = θ_max v / V`` (eq. 12, 0-based indices), the layout of
:class:`heapgrasp.planning.views.ViewContext.candidates`.

PyTorch is imported when a scorer is built, not when this module is imported; without it,
building one raises :class:`ImportError` asking to install ``heapgrasp[nets]``.
"""

from __future__ import annotations

import importlib
import os
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from heapgrasp.planning.grasp_network import validate_grid
from heapgrasp.planning.views import ViewContext

if TYPE_CHECKING:
    import torch

    from heapgrasp.nets.models import ViewNet

__all__ = ["NetworkViewScorer"]

F32 = npt.NDArray[np.float32]


class NetworkViewScorer:
    """:class:`heapgrasp.planning.views.ViewScorer` backed by a :class:`ViewNet` (eq. 13).

    Parameters
    ----------
    net_or_path : ViewNet or path-like
        A network (moved to ``device`` and put in eval mode) or a weights file
        (:func:`heapgrasp.nets.load_view_net`, which checks it whole: a bad file raises
        :class:`~heapgrasp.geometry.errors.WeightsError` naming it and the problem).
    device : str or torch.device
        Where the network runs.
    """

    name = "view-net"

    def __init__(
        self,
        net_or_path: ViewNet | str | os.PathLike[str],
        device: str | torch.device = "cpu",
    ) -> None:
        # heapgrasp.nets first: without PyTorch it raises the "install heapgrasp[nets]" hint.
        importlib.import_module("heapgrasp.nets")
        import torch

        from heapgrasp.nets.models import ViewNet
        from heapgrasp.nets.weights import load_view_net

        self.device = torch.device(device)
        if isinstance(net_or_path, ViewNet):
            net = net_or_path.to(self.device).eval()
        elif isinstance(net_or_path, str | os.PathLike):
            net = load_view_net(net_or_path, self.device)
        else:
            raise TypeError(
                f"net_or_path must be a ViewNet or a weights path, got {type(net_or_path).__name__}"
            )
        self.net: ViewNet = net

    @property
    def resolution(self) -> int:
        """Grid side ``R`` the network reads."""
        return self.net.resolution

    @property
    def view_shape(self) -> tuple[int, int]:
        """``(U, V)`` of the score map."""
        return self.net.view_shape

    def scores(self, occupancy: F32 | ViewContext) -> F32:
        """``(U, V)`` float32 view scores in [0, 1] (eq. 13).

        Parameters
        ----------
        occupancy : ndarray or ViewContext
            The ``(R, R, R)`` float32 occupancy grid ``Ŝ_{0-1}`` (eq. 10), or a
            :class:`ViewContext` (its grid's ``occupancy()`` is used, and the map must
            match the shape of its ``candidates``).
        """
        import torch

        if isinstance(occupancy, ViewContext):
            grid = occupancy.grid.occupancy()
            want = tuple(occupancy.candidates.shape[:2])
            if want != self.view_shape:
                raise ValueError(
                    f"the view network scores {self.view_shape[0]}×{self.view_shape[1]} "
                    f"candidates, the context has {want[0]}×{want[1]}"
                )
        else:
            grid = occupancy
        x = validate_grid(grid, self.resolution, "occupancy")
        with torch.inference_mode():
            out = self.net(torch.tensor(x, device=self.device)[None, None])
            scores = out[0].cpu().numpy()
        return np.ascontiguousarray(scores, dtype=np.float32)
