"""Natarajan et al.'s heuristic policies: the 2D and 3D heuristics and the information gain
comparison (§4.2, Algorithms 1 and 2).

Each scores candidate next views by how much of the unexplored region they would show,
from the fused state (:meth:`~heapgrasp.viewsphere.policies.ViewState.fused`:
the object's points and the unexplored region's points), assuming optimistically that
the next view finds no new object points:

- :class:`Heuristic2D` (Algorithm 1): projects the object and the unexplored points into
  each next view's image, closes both masks (a ``closing_px`` square, 19 in the public
  code: the points are a voxel apart, about 10 px at 0.4 m), and counts the unexplored
  pixels the object does not cover.
- :class:`Heuristic3D` (Algorithm 2): keeps the unexplored points that could hold a
  grasp (:func:`heapgrasp.grasp_region`: within the gripper's opening along, and
  ``region_radius`` across, some visible surface normal; at most ``max_points`` of them,
  drawn at random), and counts those each next view would see: in its field of view and
  sensor range, and not hidden by the object's surfels (:func:`heapgrasp.surfel_visibility`,
  squares of a voxel's half width, ray cast in the Rust core). When the best view sees at
  most ``lookahead_share`` of them, the views two steps away decide instead.
- :class:`InformationGain` (§4.2.3, after Arruda et al. 2016): the same visibility count
  over *all* the unexplored points, over the fixed set of 34 viewpoints
  (:func:`information_gain_viewpoints`); the camera flies to the best one. It picks
  viewpoints, not directions: :func:`~heapgrasp.viewsphere.policies.run_viewpoint_episode`
  runs it.

Directions whose step falls back onto another direction's
(:meth:`~heapgrasp.viewsphere.sphere.DiscreteViewsphere.move`) are not candidates; ties
go to the first direction in :data:`~heapgrasp.viewsphere.sphere.DIRECTIONS`' order.
Without object points (nothing seen yet) every view scores 0 and the first valid
direction is taken; without points in the grasp region the 3D heuristic counts all the
unexplored points (the paper leaves that case open).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from scipy import ndimage

from heapgrasp._core import grasp_region, surfel_visibility
from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.perception.clouds import project
from heapgrasp.planning.synthesis import estimate_normals
from heapgrasp.viewsphere.policies import ViewState, pose_key
from heapgrasp.viewsphere.sphere import DIRECTIONS, DiscreteViewsphere, SpherePose

__all__ = [
    "Heuristic2D",
    "Heuristic3D",
    "InformationGain",
    "ViewsphereScorer",
    "information_gain_viewpoints",
]

F64 = npt.NDArray[np.float64]


@dataclass(frozen=True)
class ViewsphereScorer:
    """What the heuristics share: the viewsphere, the camera, the sensor's range, the
    voxel (the fused points' spacing: the surfels' half width), the points per normal
    estimate, and the box where the object can be (± ``half_xy`` about the sphere's
    centre in x and y, up to ``max_height`` above it: the centre lies on the table)."""

    sphere: DiscreteViewsphere
    camera: CameraSpec
    min_range: float = 0.10
    max_range: float = 3.0
    voxel: float = 0.0075
    neighbours: int = 10
    half_xy: float = 0.15
    max_height: float = 0.30

    def targets(self, unexplored: F64) -> F64:
        """The unexplored points in the object's box: the lattice beyond it is grown
        for the grasp's collision check (and starts below the table), and no view can
        find an object point there."""
        c = np.asarray(self.sphere.centre)
        keep = (
            (np.abs(unexplored[:, 0] - c[0]) <= self.half_xy)
            & (np.abs(unexplored[:, 1] - c[1]) <= self.half_xy)
            & (unexplored[:, 2] >= c[2])
            & (unexplored[:, 2] <= c[2] + self.max_height)
        )
        out: F64 = unexplored[keep]
        return out

    def next_views(self, pose: SpherePose, steps: int = 1) -> list[tuple[int, SpherePose]]:
        """The directions a step (``steps`` steps' arc in one move) can take from
        ``pose`` without falling back, with where each leads."""
        sphere = self.sphere
        if steps != 1:
            sphere = dataclasses.replace(sphere, step=min(steps * sphere.step, 0.999 * math.pi))
        out = []
        for d in range(len(DIRECTIONS)):
            taken, nxt = sphere.move(pose, d)
            if taken == d:
                out.append((d, nxt))
        return out

    def in_view(self, points: F64, pose: SpherePose) -> npt.NDArray[np.bool_]:
        """Which points the camera at ``pose`` has in its field of view and range."""
        return project(
            points,
            self.camera,
            self.sphere.camera_pose(pose),
            min_range=self.min_range,
            max_range=self.max_range,
        )[2]

    def normals(self, obj: F64) -> F64 | None:
        """The object points' normals, or None with too few points to estimate them."""
        if len(obj) < self.neighbours:
            return None
        return estimate_normals(obj, self.neighbours)[0]

    def visible_counts(
        self, obj: F64, normals: F64 | None, targets: F64, poses: Sequence[SpherePose]
    ) -> list[int]:
        """How many ``targets`` each pose sees past the surfels of ``obj`` (module doc;
        without ``normals`` nothing hides them)."""
        if len(targets) == 0 or not poses:
            return [0] * len(poses)
        eyes = np.array([self.sphere.position(p) for p in poses])
        if normals is None:
            clear = np.ones((len(poses), len(targets)), dtype=bool)
        else:
            clear = surfel_visibility(obj, normals, eyes, targets, radius=self.voxel)
        return [
            int(np.count_nonzero(clear[i] & self.in_view(targets, p))) for i, p in enumerate(poses)
        ]


def _best(scored: Sequence[tuple[int, float]]) -> int:
    """The direction of the highest score (ties: the first in direction order)."""
    best_d, best_s = scored[0]
    for d, s in scored[1:]:
        if s > best_s:
            best_d, best_s = d, s
    return best_d


@dataclass
class Heuristic2D:
    """Natarajan et al.'s Algorithm 1 (module doc)."""

    scorer: ViewsphereScorer
    closing_px: int = 19
    name: str = "heuristic-2d"

    def __post_init__(self) -> None:
        if not (isinstance(self.closing_px, int) and self.closing_px >= 1):
            raise ValueError(f"closing_px must be an int >= 1, got {self.closing_px!r}")

    def reset(self, seed: int) -> None:
        pass

    def _mask(self, points: F64, pose: SpherePose) -> npt.NDArray[np.bool_]:
        cam = self.scorer.camera
        u, v, inside = project(
            points,
            cam,
            self.scorer.sphere.camera_pose(pose),
            min_range=self.scorer.min_range,
            max_range=self.scorer.max_range,
        )
        img = np.zeros((cam.height, cam.width), dtype=np.uint8)
        img[v[inside], u[inside]] = 1
        k = self.closing_px
        # A closing: dilation, then erosion with the border counted as set (OpenCV's
        # default), each separable for a square.
        img = ndimage.maximum_filter(img, size=k, mode="constant", cval=0)
        img = ndimage.minimum_filter(img, size=k, mode="constant", cval=1)
        mask: npt.NDArray[np.bool_] = img.astype(bool)
        return mask

    def score(self, obj: F64, unexplored: F64, pose: SpherePose) -> int:
        """Unexplored pixels not covered by the object's pixels, seen from ``pose``."""
        if len(unexplored) == 0:
            return 0
        return int(np.count_nonzero(self._mask(unexplored, pose) & ~self._mask(obj, pose)))

    def choose(self, state: ViewState) -> int:
        obj, unexplored = state.fused()
        unexplored = self.scorer.targets(unexplored)
        views = self.scorer.next_views(state.pose)
        return _best([(d, self.score(obj, unexplored, p)) for d, p in views])


@dataclass
class Heuristic3D:
    """Natarajan et al.'s Algorithm 2 (module doc): ``half_length`` is the gripper's opening."""

    scorer: ViewsphereScorer
    half_length: float = 0.08
    region_radius: float = 0.015
    max_points: int = 1000
    lookahead_share: float = 0.15
    name: str = "heuristic-3d"
    _rng: np.random.Generator = field(default_factory=lambda: np.random.default_rng(0))

    def __post_init__(self) -> None:
        for key in ("half_length", "region_radius"):
            value = getattr(self, key)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{key} must be finite and > 0, got {value}")
        if not (isinstance(self.max_points, int) and self.max_points >= 1):
            raise ValueError(f"max_points must be an int >= 1, got {self.max_points!r}")
        if not 0.0 <= self.lookahead_share <= 1.0:
            raise ValueError(f"lookahead_share must be in [0, 1], got {self.lookahead_share}")

    def reset(self, seed: int) -> None:
        self._rng = np.random.default_rng(seed)

    def useful(self, obj: F64, normals: F64 | None, unexplored: F64) -> F64:
        """The unexplored points that could hold a grasp (at most ``max_points``, drawn
        at random), or all of them when none could."""
        if normals is None or len(unexplored) == 0:
            return unexplored
        keep = grasp_region(
            obj, normals, unexplored, half_length=self.half_length, radius=self.region_radius
        )
        useful = unexplored[keep] if keep.any() else unexplored
        if len(useful) > self.max_points:
            pick = self._rng.choice(len(useful), self.max_points, replace=False)
            useful = useful[np.sort(pick)]
        return useful

    def choose(self, state: ViewState) -> int:
        obj, unexplored = state.fused()
        unexplored = self.scorer.targets(unexplored)
        normals = self.scorer.normals(obj)
        useful = self.useful(obj, normals, unexplored)
        views = self.scorer.next_views(state.pose)
        counts = self.scorer.visible_counts(obj, normals, useful, [p for _, p in views])
        if max(counts) <= self.lookahead_share * len(useful):
            ahead = self.scorer.next_views(state.pose, steps=2)
            if ahead:
                far = self.scorer.visible_counts(obj, normals, useful, [p for _, p in ahead])
                return _best([(d, c) for (d, _), c in zip(ahead, far, strict=True)])
        return _best([(d, c) for (d, _), c in zip(views, counts, strict=True)])


def information_gain_viewpoints() -> tuple[SpherePose, ...]:
    """The 34 viewpoints of Natarajan et al.'s information gain comparison (§4.2.3): home at
    polar π/6.5 (azimuth π); 9 at polar 22.5° (azimuth 0–320° every 40°); 12 each at
    polar 45° and 67.5° (azimuth 60–300° every 20°, leaving out 161–199°)."""
    views = [SpherePose(math.pi, math.pi / 6.5)]
    views += [SpherePose(math.radians(a), math.radians(22.5)) for a in range(0, 321, 40)]
    for polar in (45.0, 67.5):
        views += [
            SpherePose(math.radians(a), math.radians(polar))
            for a in range(60, 301, 20)
            if not 161 <= a <= 199
        ]
    return tuple(views)


@dataclass
class InformationGain:
    """The information gain comparison (module doc): picks the unvisited viewpoint of
    ``viewpoints`` that sees the most unexplored points."""

    scorer: ViewsphereScorer
    viewpoints: tuple[SpherePose, ...] = field(default_factory=information_gain_viewpoints)
    name: str = "information-gain"

    def reset(self, seed: int) -> None:
        pass

    def choose_view(self, state: ViewState) -> SpherePose:
        """The next viewpoint (ties: the first in ``viewpoints``' order)."""
        visited = {pose_key(p) for p in state.visited}
        left = [p for p in self.viewpoints if pose_key(p) not in visited]
        if not left:
            raise ValueError("every viewpoint was visited")
        obj, unexplored = state.fused()
        unexplored = self.scorer.targets(unexplored)
        counts = self.scorer.visible_counts(obj, self.scorer.normals(obj), unexplored, left)
        return left[_best(list(enumerate(counts)))]
