"""View planning over the U×V spherical candidates (HEAPGrasp eq. 12-14).

A :class:`ViewScorer` scores every view-waypoint candidate ``p̄^{u,v}`` of eq. 12 for
the current grid; :func:`heapgrasp.planning.selection.select_next_waypoint` then applies eq. 18.

* :class:`OracleViewScorer` — the exact eq. 14 score of each candidate: the grid is
  hypothetically carved with the silhouettes of the simulator's true meshes seen along
  ``f(p̄^ℓ, p̄^{u,v})`` (Rust :func:`heapgrasp.score_views`). An upper bound the paper
  never had, and the label generator of the learned scorer (Algorithm 1). With
  ``target_radius > 0`` it scores the *target column* instead (:func:`target_region`):
  eq. 14 counted only on the voxels within ``target_radius`` (horizontally) of the target
  grasp ``p^ℓ_grasp`` of eq. 16, i.e. the share of the target's measured volume a
  candidate would carve. Views within θ_max of the vertical leave a roof of phantom
  volume on top of each object (as high as 0.7 × its width even from all around; up to
  1.4 × from one side), and a grasp planned on the roof closes above the object; the
  global eq. 14 spreads the gain over the whole scene, so the views that would carve the
  target's roof rank no higher than the ones that refine objects never grasped in this
  phase. Not in the paper; ``target_radius = 0`` is its eq. 14.
* ``heapgrasp.planning.view_network.NetworkViewScorer`` — the view network (eq. 13).

The baselines use fixed waypoints instead (:func:`fixed_waypoints`): ``circle`` ("w/o
VP" and VGN: L waypoints evenly spaced around the scene, once around) and ``hemisphere6``
(GraspNeRF: six waypoints on a hemisphere centred in the workspace, r = 0.5 m,
θ = π/6, φ ~ U(0, 2π), looking at the workspace centre).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from heapgrasp import MeshScene, OccupancyGrid, score_views
from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.geometry.motion import (
    ViewSphere,
    arc_length_samples,
    circle_waypoints,
    hemisphere_waypoints,
    interpolate_sampled,
)

__all__ = [
    "OracleViewScorer",
    "ViewContext",
    "ViewScorer",
    "fixed_waypoints",
    "subsample_path",
    "sweep_waypoints",
    "target_region",
]

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]


@dataclass
class ViewContext:
    """What a view scorer may look at when the camera reaches a view waypoint."""

    grid: OccupancyGrid
    """SfS grid after every frame so far (eq. 10)."""
    current_pose: F64
    """Camera pose at the current view waypoint ``p̄^ℓ``."""
    candidates: F64
    """``(U, V, 4, 4)`` candidates of eq. 12."""
    sphere: ViewSphere
    camera: CameraSpec
    lam: float
    scene: MeshScene | None = None
    """The true meshes at their current poses (only the oracle may use them)."""
    target: F64 | None = None
    """``(4, 4)`` pose of the target grasp ``p^ℓ_grasp`` (eq. 16) the next waypoint is
    chosen for, or None (no candidate, or the first waypoint, where γ2 = 0 because the
    grasps are unreliable)."""


@runtime_checkable
class ViewScorer(Protocol):
    """Scores the U×V candidates (eq. 13): higher = better next waypoint."""

    name: str

    def scores(self, ctx: ViewContext) -> F32:
        """``(U, V)`` float32 scores."""
        ...


def subsample_path(poses: F64, n: int) -> F64:
    """At most ``n`` poses of a geometric path, evenly spaced in arc length, the first
    (already seen) pose excluded and the last included."""
    if len(poses) <= 1:
        return poses
    return np.asarray(poses[arc_length_samples(poses[:, :3, 3], n)], dtype=np.float64)


def target_region(
    grid: OccupancyGrid, position: npt.ArrayLike, radius: float
) -> npt.NDArray[np.bool_]:
    """The voxels whose centre lies within ``radius`` (m) of ``position`` in x–y: the
    vertical column over a target grasp, roof and all, as an ``(R, R, R)`` mask."""
    p = np.asarray(position, dtype=np.float64).reshape(-1)
    if p.shape != (3,) or not np.isfinite(p).all():
        raise ValueError(f"position must be 3 finite numbers, got {position!r}")
    if not (math.isfinite(radius) and radius > 0):
        raise ValueError(f"radius must be > 0, got {radius!r}")
    r = grid.resolution
    centres = (np.arange(r) + 0.5) * grid.voxel_size
    ox, oy, _ = grid.origin
    d2 = (centres[:, None] + ox - p[0]) ** 2 + (centres[None, :] + oy - p[1]) ** 2
    column = d2 <= radius * radius
    return np.ascontiguousarray(np.broadcast_to(column[:, :, None], (r, r, r)))


class OracleViewScorer:
    """Exact eq. 14 scores from the true meshes (see the module docstring).

    Parameters
    ----------
    frames_per_candidate
        Silhouettes per hypothetical trajectory ``f(p̄^ℓ, p̄^{u,v})``, evenly spaced in arc
        length (the real capture at 30 fps takes more; the score saturates well before).
    step
        Sample spacing of the interpolated path (m).
    target_radius
        When > 0 and the context has a target grasp, eq. 14 is counted on the column of
        this radius (m) around it (:func:`target_region`); 0 is the paper's eq. 14 over
        the whole grid.
    """

    name = "oracle"

    def __init__(
        self,
        frames_per_candidate: int = 10,
        step: float = 0.01,
        target_radius: float = 0.0,
    ) -> None:
        if frames_per_candidate < 1:
            raise ValueError(f"frames_per_candidate must be >= 1, got {frames_per_candidate}")
        if not step > 0:
            raise ValueError(f"step must be > 0, got {step}")
        if not (math.isfinite(target_radius) and target_radius >= 0):
            raise ValueError(f"target_radius must be >= 0, got {target_radius!r}")
        self.frames_per_candidate = int(frames_per_candidate)
        self.step = float(step)
        self.target_radius = float(target_radius)

    def region(self, ctx: ViewContext) -> npt.NDArray[np.bool_] | None:
        """The voxels eq. 14 is counted on: the target's column, or None (all)."""
        if self.target_radius <= 0 or ctx.target is None:
            return None
        target = np.asarray(ctx.target, dtype=np.float64)
        return target_region(ctx.grid, target[:3, 3], self.target_radius)

    def trajectories(self, ctx: ViewContext) -> list[F64]:
        """The hypothetical frames of every candidate, flattened ``u``-major."""
        return interpolate_sampled(
            ctx.current_pose,
            ctx.candidates.reshape(-1, 4, 4),
            ctx.sphere,
            step=self.step,
            frames=self.frames_per_candidate,
        )

    def scores(self, ctx: ViewContext) -> F32:
        """Eq. 14 for every candidate."""
        if ctx.scene is None:
            raise ValueError("OracleViewScorer needs the true meshes (ViewContext.scene)")
        u, v = ctx.candidates.shape[:2]
        # Candidates at theta = 0 coincide for every u: score that column once.
        top = bool(np.allclose(ctx.candidates[:, 0, :3, 3], ctx.candidates[0, 0, :3, 3]))
        if top and v > 1:
            rest = np.ascontiguousarray(ctx.candidates[:, 1:]).reshape(-1, 4, 4)
            keep = np.concatenate([ctx.candidates[:1, 0], rest])
        else:
            keep = ctx.candidates.reshape(-1, 4, 4)
        sub = ViewContext(
            ctx.grid, ctx.current_pose, keep[:, None], ctx.sphere, ctx.camera, ctx.lam, ctx.scene
        )
        s = score_views(
            ctx.grid,
            ctx.scene,
            ctx.camera.core(),
            self.trajectories(sub),
            ctx.lam,
            region=self.region(ctx),
        )
        if top and v > 1:
            out = np.empty((u, v), dtype=np.float32)
            out[:, 0] = s[0]
            out[:, 1:] = s[1:].reshape(u, v - 1)
            return out
        return s.reshape(u, v)


def fixed_waypoints(
    kind: str,
    sphere: ViewSphere,
    *,
    L: int = 3,
    circle_theta: float = math.pi / 5,
    phi0: float = 0.0,
    rng: np.random.Generator | None = None,
    hemisphere_radius: float = 0.5,
    hemisphere_theta: float = math.pi / 6,
    hemisphere_views: int = 6,
) -> F64:
    """Waypoints of the fixed-view baselines: ``"circle"`` (L evenly spaced at polar
    angle ``circle_theta`` from azimuth ``phi0``, then back to the first: once around the
    scene, as Table II's 1.87 m needs) or ``"hemisphere6"`` (GraspNeRF; random
    azimuths from ``rng``, visited in increasing azimuth)."""
    if kind == "circle":
        return circle_waypoints(sphere, L=L, theta=circle_theta, phi0=phi0, closed=True)
    if kind == "hemisphere6":
        return hemisphere_waypoints(
            rng if rng is not None else np.random.default_rng(0),
            sphere.target,
            n=hemisphere_views,
            radius=hemisphere_radius,
            theta=hemisphere_theta,
        )
    raise ValueError(f"fixed waypoints: kind must be 'circle' or 'hemisphere6', got {kind!r}")


def sweep_waypoints(
    sphere: ViewSphere,
    current: npt.ArrayLike,
    seen: npt.ArrayLike,
    *,
    degrees: float,
    step: float = 45.0,
    theta: float = math.pi / 5,
) -> F64:
    """Waypoints of a sweep along the circle at polar angle ``theta`` from the azimuth of
    ``current`` (4 x 4 camera pose, or its eye), ``degrees`` of azimuth in steps of at
    most ``step`` (``RunConfig.sweep_degrees``).

    It turns whichever way reaches more azimuths that the camera positions ``seen``
    (``(N, 3)``) lack: each waypoint counts its angular distance to the nearest azimuth
    seen, up to 45°, and the larger sum wins (ties turn counter-clockwise). Positions
    within 10° of the sphere's axis have no azimuth to speak of and are ignored.
    """
    if not (math.isfinite(degrees) and 0.0 < degrees <= 360.0):
        raise ValueError(f"degrees must be in (0, 360], got {degrees!r}")
    if not (math.isfinite(step) and step > 0.0):
        raise ValueError(f"step must be > 0, got {step!r}")
    pts = np.asarray(seen, dtype=np.float64).reshape(-1, 3)
    phi0, _, _ = sphere.spherical(current)
    n = max(1, math.ceil(degrees / step - 1e-9))
    offsets = np.radians(degrees) * np.arange(1, n + 1) / n
    azimuths = []
    for p in pts:
        phi, th, _ = sphere.spherical(p)
        if th > math.radians(10.0):
            azimuths.append(phi)
    seen_phi = np.asarray(azimuths, dtype=np.float64)

    def novelty(phis: F64) -> float:
        if seen_phi.size == 0:
            return 0.0
        d = np.abs((phis[:, None] - seen_phi[None, :] + math.pi) % (2 * math.pi) - math.pi)
        return float(np.minimum(d.min(axis=1), math.radians(45.0)).sum())

    ccw, cw = phi0 + offsets, phi0 - offsets
    phis = ccw if novelty(ccw) >= novelty(cw) else cw
    return np.stack([sphere.pose(float(phi), theta) for phi in phis])
