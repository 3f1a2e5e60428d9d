"""HEAPGrasp's view scoring (eq. 14) as a policy on Natarajan et al.'s viewsphere: neither paper
has it.

The views visited so far are carved into an occupancy grid from their silhouettes
(eq. 9–10; no depth, so transparent and specular objects are measured as opaque ones),
and each next view (the 8 directions, less those whose step falls back onto another's)
is scored by eq. 14: the share of the grid's high-confidence voxels (``Ŝ ≥ λ``) the
view's silhouette would carve away. The grid is HEAPGrasp's (Table I: a 0.30 m cube at
40³, λ = 0.9) standing on the table at the viewsphere's centre; a view is one frame (the
benchmark captures at its poses only, not along the moves).

Two scorers:

- ``oracle`` — the exact eq. 14 from the true meshes (:func:`heapgrasp.score_views`):
  privileged, an upper bound on what the view scoring can do, as the oracle is in
  HEAPGrasp's own benchmark.
- ``network`` — the shipped view network (eq. 13,
  :class:`~heapgrasp.planning.view_network.NetworkViewScorer`), which scores HEAPGrasp's
  ``U × V`` candidates (azimuth ``2πu/U``, polar ``θ_max v/V``, θ_max = 36°, on a
  0.33 m sphere). A viewsphere view takes the score of the candidate nearest its
  direction: ``u = round(φ U / 2π) mod U``, ``v = min(round(θ V / θ_max), V − 1)``. The
  viewsphere's 0.40 m radius and its polar angles up to 85° are outside what the
  network was trained on (views below 34° all read the lowest ring's score); the bench
  measures what that costs as the share of decisions where the network's choice is the
  oracle's.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import numpy.typing as npt

from heapgrasp import MeshScene, OccupancyGrid, score_views
from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.geometry.motion import ViewSphere
from heapgrasp.planning.view_network import NetworkViewScorer
from heapgrasp.planning.views import ViewContext
from heapgrasp.viewsphere.heuristics import ViewsphereScorer
from heapgrasp.viewsphere.policies import ViewState, pose_key
from heapgrasp.viewsphere.sphere import DiscreteViewsphere, SpherePose

__all__ = ["HeapgraspViewPolicy"]

F32 = npt.NDArray[np.float32]
Silhouette = Callable[[SpherePose], npt.NDArray[np.bool_]]


@dataclass
class HeapgraspViewPolicy:
    """Eq. 14 over the next views (module doc). ``silhouette(pose)`` is the object's
    mask seen from ``pose`` (``(H, W)`` bool, the camera's size); ``scene`` the true
    meshes, which the oracle reads and the network's measurement compares against."""

    sphere: DiscreteViewsphere
    camera: CameraSpec
    silhouette: Silhouette
    scorer: Literal["oracle", "network"]
    scene: MeshScene | None = None
    network: NetworkViewScorer | None = None
    cube_size: float = 0.30
    resolution: int = 40
    lam: float = 0.9
    candidate_radius: float = 0.33
    theta_max: float = math.pi / 5
    name: str = ""
    agreement: list[bool] = field(default_factory=list)
    """Per decision of the network scorer with a ``scene``: whether the oracle would
    have chosen the same direction."""

    def __post_init__(self) -> None:
        if self.scorer == "oracle" and self.scene is None:
            raise ValueError("the oracle scorer reads the true meshes: pass scene")
        if self.scorer == "network" and self.network is None:
            raise ValueError("the network scorer needs network (a NetworkViewScorer)")
        if self.scorer not in ("oracle", "network"):
            raise ValueError(f"scorer must be 'oracle' or 'network', got {self.scorer!r}")
        if self.network is not None and self.network.resolution != self.resolution:
            self.resolution = self.network.resolution
        self.name = self.name or f"heapgrasp-{'oracle' if self.scorer == 'oracle' else 'net'}"
        c = np.asarray(self.sphere.centre)
        self._origin = (c[0] - self.cube_size / 2, c[1] - self.cube_size / 2, c[2])
        self._views = ViewsphereScorer(self.sphere, self.camera)
        self._core_camera = self.camera.core()
        self.reset(0)

    def reset(self, seed: int) -> None:
        self._grid = OccupancyGrid(self._origin, self.cube_size, self.resolution)
        self._carved: set[tuple[float, float]] = set()

    @property
    def grid(self) -> OccupancyGrid:
        """The episode's grid (the views carved so far)."""
        return self._grid

    def carve(self, poses: tuple[SpherePose, ...]) -> None:
        """Carves the silhouettes of ``poses`` not yet carved."""
        for p in poses:
            key = pose_key(p)
            if key not in self._carved:
                mask = np.ascontiguousarray(self.silhouette(p), dtype=bool)
                self._grid.integrate(mask, self._core_camera, self.sphere.camera_pose(p))
                self._carved.add(key)

    def oracle_scores(self, poses: list[SpherePose]) -> F32:
        """Exact eq. 14 of one frame at each of ``poses``."""
        assert self.scene is not None
        frames = [self.sphere.camera_pose(p)[None] for p in poses]
        out: F32 = score_views(self._grid, self.scene, self._core_camera, frames, self.lam)
        return out

    def network_scores(self, current: SpherePose, poses: list[SpherePose]) -> F32:
        """The view network's score of the candidate nearest each of ``poses``."""
        assert self.network is not None
        u_n, v_n = self.network.view_shape
        centre = self.sphere.centre
        view_sphere = ViewSphere(
            centre, (centre[0], centre[1], centre[2] + self.cube_size / 2), self.candidate_radius
        )
        ctx = ViewContext(
            self._grid,
            self.sphere.camera_pose(current),
            view_sphere.candidates(u_n, v_n, self.theta_max),
            view_sphere,
            self.camera,
            self.lam,
        )
        scores = self.network.scores(ctx)
        out = np.empty(len(poses), dtype=np.float32)
        for i, p in enumerate(poses):
            u = round(p.azimuth * u_n / (2 * math.pi)) % u_n
            v = min(round(p.polar * v_n / self.theta_max), v_n - 1)
            out[i] = scores[u, v]
        return out

    def choose(self, state: ViewState) -> int:
        self.carve(state.visited)
        views = self._views.next_views(state.pose)
        poses = [p for _, p in views]
        if self.scorer == "oracle":
            scores = self.oracle_scores(poses)
        else:
            scores = self.network_scores(state.pose, poses)
        best = _best(views, scores)
        if self.scorer == "network" and self.scene is not None:
            self.agreement.append(best == _best(views, self.oracle_scores(poses)))
        return best


def _best(views: list[tuple[int, SpherePose]], scores: F32) -> int:
    """The direction of the highest score (ties: the first in direction order)."""
    k = int(np.argmax(scores))
    return views[k][0]
