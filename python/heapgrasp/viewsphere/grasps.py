"""Natarajan et al.'s perception and grasp synthesis over the views a camera on the viewsphere
has taken: what a simulated or a real depth camera feeds the benchmark's policies.

The benchmark of seed ``001_95c7dd5c6a7c3646.txt`` (§3.2–3.3) asks after every move
whether the views taken so far yield a grasp. :class:`ViewsphereGrasps` answers it from
depth images (any source: :class:`heapgrasp.viewsphere.world.ViewsphereWorld`
renders them; a real camera would capture them):

1. each view's points (the sensor's range) down-sampled at the voxel (the core's
   :func:`heapgrasp.depth_voxels`: :func:`~heapgrasp.perception.clouds.backproject` and
   :func:`~heapgrasp.perception.clouds.voxel_downsample` in one pass); a set of views
   fuses them (order-free);
2. the table (RANSAC, within 10° of level), fitted once to what the first view shows
   (the table does not move; refitting it to every set of views changed nothing but the
   time), and the object's points above it, in a box around the viewsphere's centre;
3. the unexplored region: the lattice grown from what the *first* view shows
   (:meth:`~heapgrasp.perception.clouds.UnexploredRegion.around`), less what any view of
   the set shows to be empty (each view's "seen" mask is computed once);
4. grasp synthesis (:mod:`heapgrasp.planning.synthesis`): normals, candidate contacts,
   antipodal pairs, their contact patches, the ranking and the first collision-free grasp
   (the hand grown by half a voxel: see :attr:`ViewsphereConfig.hand_margin_voxels`).

Every view's depth, points and mask, and every set's answer, are cached: a search over
sets of views (:func:`~heapgrasp.viewsphere.policies.breadth_first`) and several
policies on the same object pose pay for each once. Every parameter is a field of
:class:`ViewsphereConfig`, with the paper's values as defaults.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from heapgrasp import depth_voxels
from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.geometry.gripper import PANDA_HAND, GripperGeometry
from heapgrasp.perception.clouds import (
    TablePlane,
    UnexploredRegion,
    fit_table,
    voxel_downsample,
)
from heapgrasp.planning.synthesis import (
    candidate_contacts,
    estimate_normals,
    first_free_grasp,
    patched_pairs,
    rank_grasps,
)
from heapgrasp.viewsphere.heuristics import ViewsphereScorer
from heapgrasp.viewsphere.policies import PoseKey, pose_key
from heapgrasp.viewsphere.sphere import DiscreteViewsphere, SpherePose

__all__ = ["VIEWSPHERE_CAMERA", "FoundGrasp", "ViewsphereConfig", "ViewsphereGrasps"]

F64 = npt.NDArray[np.float64]
Depth = npt.NDArray[np.float32]

#: Natarajan et al.'s depth camera: 640 × 480, fx = fy = 554.2547 (a horizontal field of view of
#: 1.047 rad), principal point (320.5, 240.5).
VIEWSPHERE_CAMERA = CameraSpec(width=640, height=480, fx=554.2547, fy=554.2547, cx=320.5, cy=240.5)


@dataclass(frozen=True)
class ViewsphereConfig:
    """Every setting of Natarajan et al.'s benchmark (lengths in metres, angles in degrees)."""

    radius: float = 0.40
    """The viewsphere's radius."""
    step_deg: float = 20.0
    """The arc of one move."""
    max_polar_deg: float = 85.0
    """The largest polar angle of a valid pose (0: straight above)."""
    start_azimuth_deg: float = 180.0
    start_polar_deg: float = 180.0 / 7.0
    """The start pose (azimuth π, polar π/7)."""
    max_steps: int = 6
    """Moves per episode; a pose without a grasp after them counts this many steps."""
    min_range: float = 0.10
    max_range: float = 3.0
    """The depth sensor's range."""
    voxel: float = 0.0075
    """The fusion's voxel (also the unexplored lattice's spacing and a grasp's margin)."""
    table_threshold: float = 0.005
    table_max_tilt_deg: float = 10.0
    """The table's RANSAC: inlier distance and largest tilt from level."""
    object_half_xy: float = 0.15
    object_min_height: float = 0.01
    object_max_height: float = 0.30
    """Where the object's points are looked for: ± half width around the centre in x and
    y, between these heights above the table."""
    grow_xy: float = 0.30
    grow_z: float = 0.25
    """The unexplored region's growth (at least these, else the object's extent)."""
    neighbours: int = 10
    """Points per normal estimate."""
    curvature_factor: float = 2.0
    """A contact's curvature is at most this times the object's mean."""
    min_contact_height: float = 0.01
    """No contact this close to the object's lowest point."""
    min_quality_deg: float = 150.0
    """A pair's least quality ``180° − (A + B)``."""
    hand_margin_voxels: float = 0.5
    """The collision check grows the hand outward by this many voxels: the points sample
    surfaces a voxel apart, and a hand overlapping a surface by less passes between
    them (the opening is unchanged). The paper's check has no margin (0)."""
    bfs_max_sets: int = 600
    """Breadth-first search's budget: distinct sets of views synthesised per episode
    (about three levels of the search); past it the pose counts as not found."""

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.name in ("max_steps", "neighbours", "bfs_max_sets"):
                low = {"max_steps": 0, "neighbours": 3, "bfs_max_sets": 1}[f.name]
                if not (isinstance(value, int) and not isinstance(value, bool) and value >= low):
                    raise ValueError(f"ViewsphereConfig.{f.name} must be an int >= {low}")
                continue
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ValueError(f"ViewsphereConfig.{f.name} must be a number, got {value!r}")
            if not math.isfinite(value):
                raise ValueError(f"ViewsphereConfig.{f.name} must be finite, got {value}")
        positive = ("radius", "step_deg", "max_polar_deg", "voxel", "table_threshold")
        if self.hand_margin_voxels < 0:
            raise ValueError(
                f"ViewsphereConfig.hand_margin_voxels must be >= 0, got {self.hand_margin_voxels}"
            )
        for name in (*positive, "object_half_xy", "curvature_factor", "max_range"):
            if getattr(self, name) <= 0:
                raise ValueError(f"ViewsphereConfig.{name} must be > 0, got {getattr(self, name)}")
        if not 0 <= self.min_range < self.max_range:
            raise ValueError(
                f"ViewsphereConfig: need 0 <= min_range < max_range, got {self.min_range}, "
                f"{self.max_range}"
            )
        if not 0 <= self.object_min_height < self.object_max_height:
            raise ValueError(
                "ViewsphereConfig: need 0 <= object_min_height < object_max_height, got "
                f"{self.object_min_height}, {self.object_max_height}"
            )
        if not 0 <= self.min_quality_deg <= 180:
            raise ValueError(
                f"ViewsphereConfig.min_quality_deg must be in [0, 180], got {self.min_quality_deg}"
            )
        if not self.max_polar_deg <= 180:
            raise ValueError(
                f"ViewsphereConfig.max_polar_deg must be in (0, 180], got {self.max_polar_deg}"
            )
        if not 0 <= self.start_polar_deg <= self.max_polar_deg:
            raise ValueError(
                f"ViewsphereConfig.start_polar_deg must be in [0, max_polar_deg], got "
                f"{self.start_polar_deg}"
            )

    def sphere(self, centre: Sequence[float] = (0.0, 0.0, 0.0)) -> DiscreteViewsphere:
        """The viewsphere around ``centre``."""
        return DiscreteViewsphere(
            radius=self.radius,
            step=math.radians(self.step_deg),
            max_polar=math.radians(self.max_polar_deg),
            centre=(float(centre[0]), float(centre[1]), float(centre[2])),
        )

    def view_scorer(self, sphere: DiscreteViewsphere, camera: CameraSpec) -> ViewsphereScorer:
        """What the heuristic and learned policies score views with, on ``sphere``."""
        return ViewsphereScorer(
            sphere,
            camera,
            min_range=self.min_range,
            max_range=self.max_range,
            voxel=self.voxel,
            neighbours=self.neighbours,
            half_xy=self.object_half_xy,
            max_height=self.object_max_height,
        )

    @property
    def start(self) -> SpherePose:
        """The episodes' first pose."""
        return SpherePose(math.radians(self.start_azimuth_deg), math.radians(self.start_polar_deg))

    def to_dict(self) -> dict[str, Any]:
        """The settings by name (JSON-ready)."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]) -> ViewsphereConfig:
        """A config from :meth:`to_dict`'s mapping (missing keys: defaults); an unknown
        key is a ValueError naming it."""
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise ValueError(
                f"unknown viewsphere setting(s) {', '.join(unknown)}; known: "
                + ", ".join(sorted(known))
            )
        return cls(**dict(values))


@dataclass(frozen=True)
class FoundGrasp:
    """A grasp the synthesis found: the TCP pose, the contacts, the quality (degrees) and
    the opening it needs (m)."""

    pose: F64
    contacts: tuple[F64, F64]
    quality: float
    width: float

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return {
            "pose": np.round(self.pose, 6).tolist(),
            "contacts": [np.round(c, 6).tolist() for c in self.contacts],
            "quality_deg": round(self.quality, 4),
            "width_m": round(self.width, 6),
        }


class ViewsphereGrasps:
    """Whether, and where, the views of a set yield a grasp (module doc).

    ``render(pose)`` gives the depth image (camera z, metres; 0 or NaN where nothing is
    measured) seen from a pose of ``sphere`` with ``camera``.
    """

    def __init__(
        self,
        render: Callable[[SpherePose], npt.ArrayLike],
        *,
        sphere: DiscreteViewsphere,
        camera: CameraSpec = VIEWSPHERE_CAMERA,
        config: ViewsphereConfig | None = None,
        gripper: GripperGeometry = PANDA_HAND,
    ) -> None:
        self.config = ViewsphereConfig() if config is None else config
        self.sphere = sphere
        self.camera = camera
        self._core_camera = camera.core()
        self.gripper = gripper
        self._render = render
        self._depth: dict[PoseKey, Depth] = {}
        self._points: dict[PoseKey, F64] = {}
        self._table: dict[PoseKey, TablePlane | None] = {}
        self._region: dict[PoseKey, UnexploredRegion | None] = {}
        self._seen: dict[tuple[PoseKey, PoseKey], npt.NDArray[np.bool_]] = {}
        self._answers: dict[tuple[PoseKey, frozenset[PoseKey]], FoundGrasp | None] = {}
        self.sets_evaluated = 0
        """How many distinct sets of views were synthesised (cache misses)."""

    # ------------------------------------------------------------------ views
    def depth(self, pose: SpherePose) -> Depth:
        """The view's depth image (rendered once)."""
        key = pose_key(pose)
        if key not in self._depth:
            d = np.asarray(self._render(pose), dtype=np.float32)
            if d.shape != (self.camera.height, self.camera.width):
                raise ValueError(
                    f"a depth image must be ({self.camera.height}, {self.camera.width}), "
                    f"got {d.shape}"
                )
            self._depth[key] = d
        return self._depth[key]

    def points(self, pose: SpherePose) -> F64:
        """The view's world points (the sensor's range), down-sampled to the voxel."""
        key = pose_key(pose)
        if key not in self._points:
            c = self.config
            self._points[key] = depth_voxels(
                self.depth(pose),
                self._core_camera,
                self.sphere.camera_pose(pose),
                min_range=c.min_range,
                max_range=c.max_range,
                voxel=c.voxel,
            )
        return self._points[key]

    def table(self, pose: SpherePose) -> TablePlane | None:
        """The table seen from ``pose`` (RANSAC on the view's points), or None when the
        view shows none; fitted once per view."""
        key = pose_key(pose)
        if key not in self._table:
            c = self.config
            points = self.points(pose)
            try:
                self._table[key] = fit_table(
                    points,
                    threshold=c.table_threshold,
                    max_tilt=math.radians(c.table_max_tilt_deg),
                )
            except ValueError:
                self._table[key] = None
        return self._table[key]

    def object_points(self, poses: Sequence[SpherePose]) -> tuple[F64, float]:
        """The fused object points of ``poses`` above the table the first pose shows,
        and the table's height at the centre (no points and 0 without a table)."""
        c = self.config
        table = self.table(poses[0])
        if table is None:
            return np.zeros((0, 3)), 0.0
        fused = voxel_downsample(np.vstack([self.points(p) for p in poses]), c.voxel)
        centre = np.asarray(self.sphere.centre)
        table_z = float((table.offset - table.normal[:2] @ centre[:2]) / table.normal[2])
        height = table.height(fused)
        keep = (
            (np.abs(fused[:, 0] - centre[0]) <= c.object_half_xy)
            & (np.abs(fused[:, 1] - centre[1]) <= c.object_half_xy)
            & (height >= c.object_min_height)
            & (height <= c.object_max_height)
        )
        return fused[keep], table_z

    def unexplored(self, poses: Sequence[SpherePose]) -> F64:
        """The unexplored region's points after ``poses`` (grown from the first)."""
        first = pose_key(poses[0])
        region = self._first_region(poses[0])
        if region is None:
            return np.zeros((0, 3))
        left = np.ones(len(region), dtype=bool)
        for p in poses:
            key = (first, pose_key(p))
            if key not in self._seen:
                self._seen[key] = region.seen(
                    self.depth(p),
                    self.camera,
                    self.sphere.camera_pose(p),
                    min_range=self.config.min_range,
                    max_range=self.config.max_range,
                )
            left &= ~self._seen[key]
        out: F64 = region.points[left]
        return out

    def _first_region(self, pose: SpherePose) -> UnexploredRegion | None:
        key = pose_key(pose)
        if key not in self._region:
            obj, table_z = self.object_points([pose])
            c = self.config
            self._region[key] = (
                None
                if len(obj) == 0
                else UnexploredRegion.around(
                    obj, table_z, spacing=c.voxel, grow_xy=c.grow_xy, grow_z=c.grow_z
                )
            )
        return self._region[key]

    # ------------------------------------------------------------------ grasps
    def grasp(self, poses: Sequence[SpherePose]) -> FoundGrasp | None:
        """The first collision-free grasp on what ``poses`` show (the unexplored region
        grows from the first pose), or None; cached per (first pose, set of poses)."""
        if not poses:
            raise ValueError("grasp needs at least one view")
        key = (pose_key(poses[0]), frozenset(pose_key(p) for p in poses))
        if key not in self._answers:
            self._answers[key] = self._synthesise(poses)
            self.sets_evaluated += 1
        return self._answers[key]

    def _synthesise(self, poses: Sequence[SpherePose]) -> FoundGrasp | None:
        c = self.config
        obj, _ = self.object_points(poses)
        if len(obj) < max(10, c.neighbours):
            return None
        region = self.unexplored(poses)
        normals, curvature = estimate_normals(obj, c.neighbours)
        candidates = candidate_contacts(
            obj, curvature, factor=c.curvature_factor, min_height=c.min_contact_height
        )
        pairs = patched_pairs(
            obj,
            normals,
            candidates,
            voxel=c.voxel,
            max_width=self.gripper.max_opening,
            min_quality=c.min_quality_deg,
        )
        if len(pairs) == 0:
            return None
        centre = np.vstack([obj, region[_inside(region, obj)]]).mean(axis=0)
        order = rank_grasps(obj, pairs, centre)
        hand = self.gripper.inflated(c.hand_margin_voxels * c.voxel)
        found = first_free_grasp(obj, region, pairs, order, gripper=hand)
        if found is None:
            return None
        k, pose = found
        return FoundGrasp(
            pose=pose,
            contacts=(obj[pairs.first[k]], obj[pairs.second[k]]),
            quality=float(pairs.quality[k]),
            width=float(pairs.width[k]),
        )

    def fused(self, poses: Sequence[SpherePose]) -> tuple[F64, F64]:
        """The fused state a policy sees (:meth:`ViewState.fused`): the object's points
        and the unexplored region's after ``poses``."""
        return self.object_points(poses)[0], self.unexplored(poses)

    def grasp_found(self, keys: frozenset[PoseKey]) -> bool:
        """:func:`~heapgrasp.viewsphere.policies.breadth_first`'s question for a
        set of pose keys: the configured start pose, which every set holds, first."""
        start = pose_key(self.config.start)
        ordered = [start, *sorted(k for k in keys if k != start)]
        return self.grasp([SpherePose(a, p) for a, p in ordered]) is not None


def _inside(points: F64, obj: F64) -> npt.NDArray[np.bool_]:
    """The points within the object's bounding box (the public code's centroid counts
    the unexplored points there, the object's hidden part)."""
    lo, hi = obj.min(axis=0), obj.max(axis=0)
    inside: npt.NDArray[np.bool_] = np.all((points >= lo) & (points <= hi), axis=1)
    return inside
