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

With silhouettes (``perception="silhouette"``, neither paper's: HEAPGrasp's measurement
on Natarajan et al.'s benchmark) the views' object masks are carved into a grid
(Shape from Silhouette, HEAPGrasp eq. 9–10: a 0.30 m cube of ``voxel`` cells standing
on the table at the viewsphere's centre, ``Ŝ ≥ λ``), and the synthesis runs on the
hull: the object's points are the hull's boundary (its cells' outer faces), the
unexplored region its cells (everything outside the hull has been seen empty). No depth
is read, so transparent and specular objects are measured as opaque ones. A hull's
surface is mostly phantom: one silhouette bounds nothing along its rays, and the true
surface touches the hull only along each view's rim. Where the rims of two views cross
(the frontier points of two-view geometry: both views' silhouette cones are tangent to
each other and to the object) the hull does touch the object; where two cones cross at
an angle it has a ridge of phantom volume. So a finger may only touch a surface point
on the silhouette boundary of two views whose cones are tangent there and whose rays
cross at a wide angle (``rim_views``, ``rim_agree_deg``, ``rim_apart_deg``; every point
is still an obstacle to the hand). ``perception="fused"`` keeps the depth points inside
the hull (grown by a cell), which may all be touched, beside its surface, and the
depth's unexplored region inside the hull: the hull removes see-through and stray
depth, the depth fills the hull's concavities.

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
from scipy import ndimage

from heapgrasp import OccupancyGrid, depth_voxels
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

__all__ = [
    "PERCEPTIONS",
    "VIEWSPHERE_CAMERA",
    "FoundGrasp",
    "Hull",
    "ViewsphereConfig",
    "ViewsphereGrasps",
]

#: What the synthesis reads: the paper's depth, the carved silhouettes' hull, or both
#: (module doc).
PERCEPTIONS = ("depth", "silhouette", "fused")

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
    hull_size: float = 0.30
    hull_lambda: float = 0.9
    """The silhouettes' grid (``perception`` silhouette or fused): a cube of this side
    standing on the table at the viewsphere's centre, cells of ``voxel``, a cell in the
    hull when ``Ŝ ≥ hull_lambda`` (HEAPGrasp's Table I: 0.30 m, λ = 0.9)."""
    rim_views: int = 2
    rim_agree_deg: float = 20.0
    rim_apart_deg: float = 40.0
    """A point of the hull's surface may be touched when it is a frontier point
    (:meth:`Hull.touchable`): on the silhouette boundary of ``rim_views`` views whose
    cones are tangent there (normals within ``rim_agree_deg``) and whose rays cross at
    ``rim_apart_deg`` or more."""
    bfs_max_sets: int = 600
    """Breadth-first search's budget: distinct sets of views synthesised per episode
    (about three levels of the search); past it the pose counts as not found."""

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.name in ("max_steps", "neighbours", "bfs_max_sets", "rim_views"):
                low = {"max_steps": 0, "neighbours": 3, "bfs_max_sets": 1, "rim_views": 1}[f.name]
                if not (isinstance(value, int) and not isinstance(value, bool) and value >= low):
                    raise ValueError(f"ViewsphereConfig.{f.name} must be an int >= {low}")
                continue
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ValueError(f"ViewsphereConfig.{f.name} must be a number, got {value!r}")
            if not math.isfinite(value):
                raise ValueError(f"ViewsphereConfig.{f.name} must be finite, got {value}")
        positive = (
            "radius",
            "step_deg",
            "max_polar_deg",
            "voxel",
            "table_threshold",
            "hull_size",
        )
        if not 0 < self.hull_lambda <= 1:
            raise ValueError(
                f"ViewsphereConfig.hull_lambda must be in (0, 1], got {self.hull_lambda}"
            )
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
class Hull:
    """The views' silhouettes carved: the centres of its boundary faces ``(N, 3)``
    (the hull's surface), its cells' centres, its cells (``(R, R, R)`` bool, x y z),
    which surface points lie on which view's rim (``(N, V)`` bool) and the views'
    camera centres ``(V, 3)``."""

    surface: F64
    interior: F64
    cells: npt.NDArray[np.bool_]
    rims: npt.NDArray[np.bool_]
    cone_normals: F64
    cameras: F64
    corner: F64
    voxel: float

    def holds(self, points: F64, grow: bool = False) -> npt.NDArray[np.bool_]:
        """Which ``points`` fall in a cell of the hull (``grow``: of the hull grown by
        one cell)."""
        cells = _grown(self.cells) if grow else self.cells
        res = np.array(cells.shape)
        idx = np.floor((points - self.corner) / self.voxel).astype(np.int64)
        ok = np.all((idx >= 0) & (idx < res), axis=1)
        out = np.zeros(len(points), dtype=bool)
        out[ok] = cells[tuple(idx[ok].T)]
        return out

    def touchable(self, *, views: int, agree_deg: float, apart_deg: float) -> npt.NDArray[np.bool_]:
        """The surface points a finger may touch: frontier points, where the hull
        touches the object. A point on the rims of two views is one when the two
        views' silhouette cones are tangent to each other there (their normals within
        ``agree_deg``: where they cross at an angle, the point is on a ridge of phantom
        volume) and the views' rays cross at ``apart_deg`` or more (nearly parallel
        views have rims that run together for centimetres). ``views`` 1: any rim."""
        if views < 2:
            out: npt.NDArray[np.bool_] = self.rims.sum(axis=1) >= views
            return out
        rays = self.surface[:, None, :] - self.cameras[None, :, :]
        rays /= np.linalg.norm(rays, axis=2, keepdims=True)
        apart = np.einsum("nvk,nwk->nvw", rays, rays) <= math.cos(math.radians(apart_deg))
        agree = np.abs(np.einsum("nvk,nwk->nvw", self.cone_normals, self.cone_normals)) >= (
            math.cos(math.radians(agree_deg))
        )
        pairs = self.rims[:, :, None] & self.rims[:, None, :] & apart & agree
        out = pairs.any(axis=(1, 2))
        return out


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
    measured) seen from a pose of ``sphere`` with ``camera``; ``silhouette(pose)`` the
    object's mask (``(H, W)`` bool), which ``perception`` silhouette and fused need.
    """

    def __init__(
        self,
        render: Callable[[SpherePose], npt.ArrayLike],
        *,
        sphere: DiscreteViewsphere,
        camera: CameraSpec = VIEWSPHERE_CAMERA,
        config: ViewsphereConfig | None = None,
        gripper: GripperGeometry = PANDA_HAND,
        silhouette: Callable[[SpherePose], npt.ArrayLike] | None = None,
        perception: str = "depth",
    ) -> None:
        if perception not in PERCEPTIONS:
            raise ValueError(
                f"perception must be one of {', '.join(PERCEPTIONS)}, got {perception!r}"
            )
        if perception != "depth" and silhouette is None:
            raise ValueError(f"perception {perception!r} needs the views' silhouettes")
        self.perception = perception
        self._silhouette = silhouette
        self._masks: dict[PoseKey, npt.NDArray[np.bool_]] = {}
        self._hulls: dict[frozenset[PoseKey], Hull] = {}
        self._inside_px: dict[PoseKey, npt.NDArray[np.float32]] = {}
        """Per view: the silhouette's signed distance and its gradient (pixels)."""
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
    def _image(self, image: npt.NDArray[Any], what: str) -> npt.NDArray[Any]:
        """``image`` when it has the camera's ``(height, width)``; else a ValueError
        naming ``what`` it is and both shapes."""
        want = (self.camera.height, self.camera.width)
        if image.shape != want:
            raise ValueError(f"{what} must be {want}, got {image.shape}")
        return image

    def depth(self, pose: SpherePose) -> Depth:
        """The view's depth image (rendered once)."""
        key = pose_key(pose)
        if key not in self._depth:
            d = np.asarray(self._render(pose), dtype=np.float32)
            self._depth[key] = self._image(d, "a depth image")
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

    # ------------------------------------------------------------------ silhouettes
    def mask(self, pose: SpherePose) -> npt.NDArray[np.bool_]:
        """The view's object silhouette (taken once)."""
        key = pose_key(pose)
        if key not in self._masks:
            assert self._silhouette is not None
            m = np.ascontiguousarray(self._silhouette(pose), dtype=bool)
            self._masks[key] = self._image(m, "a silhouette")
        return self._masks[key]

    def hull(self, poses: Sequence[SpherePose]) -> Hull:
        """The silhouettes of ``poses`` carved (module doc), cached per set of views."""
        key = frozenset(pose_key(p) for p in poses)
        if key not in self._hulls:
            c = self.config
            res = max(1, round(c.hull_size / c.voxel))
            size = res * c.voxel
            centre = np.asarray(self.sphere.centre, dtype=np.float64)
            origin = (centre[0] - size / 2, centre[1] - size / 2, centre[2])
            grid = OccupancyGrid(origin, size, res)
            ordered = [SpherePose(*k) for k in sorted(key)]
            grid.integrate_many(
                np.stack([self.mask(p) for p in ordered]),
                self._core_camera,
                np.stack([self.sphere.camera_pose(p) for p in ordered]),
            )
            inside = grid.occupancy() >= np.float32(c.hull_lambda)
            corner = np.asarray(origin)
            surface = np.ascontiguousarray(_boundary_faces(inside, corner, c.voxel))
            self._hulls[key] = Hull(
                surface=surface,
                interior=np.ascontiguousarray(corner + (np.argwhere(inside) + 0.5) * c.voxel),
                cells=inside,
                **_rims([self._rim(surface, p) for p in ordered]),
                cameras=np.stack([self.sphere.camera_pose(p)[:3, 3] for p in ordered]),
                corner=corner,
                voxel=c.voxel,
            )
        return self._hulls[key]

    def _rim(self, points: F64, pose: SpherePose) -> tuple[npt.NDArray[np.bool_], F64]:
        """Which points lie on the view's rim (their projection within a face's half
        diagonal, in pixels, of a pixel outside the silhouette) and, there, the normal
        of the view's silhouette cone (the plane through the camera centre that holds the
        ray and the silhouette boundary's tangent; zero elsewhere)."""
        key = pose_key(pose)
        if key not in self._inside_px:
            mask = self.mask(pose)
            # Signed distance to the silhouette's boundary (positive inside) and its
            # gradient, which points inward, across the boundary.
            signed = ndimage.distance_transform_edt(mask) - ndimage.distance_transform_edt(~mask)
            gv, gu = np.gradient(ndimage.gaussian_filter(signed, 1.0))
            self._inside_px[key] = np.stack([signed, gu, gv]).astype(np.float32)
        signed, gu, gv = self._inside_px[key]
        cam2world = self.sphere.camera_pose(pose)
        rot = cam2world[:3, :3]
        local = (points - cam2world[:3, 3]) @ rot
        z = np.where(local[:, 2] > 1e-6, local[:, 2], np.inf)
        cam = self.camera
        u = np.floor(cam.fx * local[:, 0] / z + cam.cx + 0.5)
        v = np.floor(cam.fy * local[:, 1] / z + cam.cy + 0.5)
        seen = np.isfinite(z) & (u >= 0) & (u < cam.width) & (v >= 0) & (v < cam.height)
        reach = math.sqrt(0.5) * self.config.voxel * cam.fx / z
        on = np.zeros(len(points), dtype=bool)
        normals = np.zeros((len(points), 3))
        ui, vi = u[seen].astype(np.int64), v[seen].astype(np.int64)
        on[seen] = signed[vi, ui] <= reach[seen]
        # The cone's plane: the pixel's ray and the ray of a pixel along the boundary's
        # tangent (perpendicular to the gradient), crossed, in the world.
        g = np.stack([gu[vi, ui], gv[vi, ui]], axis=1).astype(np.float64)
        uu, vv = u[seen], v[seen]
        r1 = np.stack([(uu - cam.cx) / cam.fx, (vv - cam.cy) / cam.fy, np.ones_like(uu)], 1)
        r2 = np.stack(
            [(uu - g[:, 1] - cam.cx) / cam.fx, (vv + g[:, 0] - cam.cy) / cam.fy, np.ones_like(uu)],
            1,
        )
        n = np.cross(r1, r2) @ rot.T
        length = np.linalg.norm(n, axis=1, keepdims=True)
        normals[seen] = np.where(length > 1e-12, n / np.maximum(length, 1e-12), 0.0)
        on &= np.linalg.norm(normals, axis=1) > 0.5
        return on, normals

    def object_points(self, poses: Sequence[SpherePose]) -> tuple[F64, float]:
        """The object's points after ``poses`` (what ``perception`` reads: the depth's
        above the table the first pose shows, the hull's surface, or both) and the
        table's height at the centre."""
        points, _, table_z = self._perceived(poses)
        return points, table_z

    def _perceived(self, poses: Sequence[SpherePose]) -> tuple[F64, Hull | None, float]:
        """The object's points (the hull's surface first, when there is one), the hull
        (None for depth) and the table's height (module doc)."""
        if self.perception == "depth":
            points, table_z = self._depth_object_points(poses)
            return points, None, table_z
        hull = self.hull(poses)
        table_z = float(self.sphere.centre[2])
        if self.perception == "silhouette":
            return hull.surface, hull, table_z
        depth, _ = self._depth_object_points(poses)
        near = depth[hull.holds(depth, grow=True)]
        return np.ascontiguousarray(np.vstack([hull.surface, near])), hull, table_z

    def _depth_object_points(self, poses: Sequence[SpherePose]) -> tuple[F64, float]:
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
        """The unexplored region's points after ``poses``: the depth's (grown from the
        first), the hull's interior, or the depth's inside the hull (``perception``)."""
        if self.perception == "silhouette":
            return self.hull(poses).interior
        region = self._depth_unexplored(poses)
        if self.perception == "fused":
            out: F64 = region[self.hull(poses).holds(region)]
            return out
        return region

    def _depth_unexplored(self, poses: Sequence[SpherePose]) -> F64:
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
            obj, table_z = self._depth_object_points([pose])
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
        obj, hull, _ = self._perceived(poses)
        if len(obj) < max(10, c.neighbours):
            return None
        region = self.unexplored(poses)
        normals, curvature = estimate_normals(obj, c.neighbours)
        candidates = candidate_contacts(
            obj, curvature, factor=c.curvature_factor, min_height=c.min_contact_height
        )
        if hull is not None:  # the hull's surface may be touched at frontier points only
            candidates[: len(hull.surface)] &= hull.touchable(
                views=c.rim_views, agree_deg=c.rim_agree_deg, apart_deg=c.rim_apart_deg
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


def _rims(per_view: Sequence[tuple[npt.NDArray[np.bool_], F64]]) -> dict[str, Any]:
    """:class:`Hull`'s ``rims`` ``(N, V)`` and ``cone_normals`` ``(N, V, 3)`` from
    each view's :meth:`ViewsphereGrasps._rim`."""
    return {
        "rims": np.stack([on for on, _ in per_view], axis=1),
        "cone_normals": np.stack([n for _, n in per_view], axis=1),
    }


def _boundary_faces(cells: npt.NDArray[np.bool_], corner: F64, voxel: float) -> F64:
    """The centres of the faces between a cell of ``cells`` and one that is not (or
    the grid's outside): points on the hull's boundary, which bounds the object (cell
    centres would lie up to half a cell inside it)."""
    padded = np.pad(cells, 1, constant_values=False)
    inner = (slice(1, -1),) * 3
    out = []
    for axis in range(3):
        for step in (-1, 1):
            neighbour = np.roll(padded, -step, axis=axis)[inner]
            idx = np.argwhere(cells & ~neighbour).astype(np.float64) + 0.5
            idx[:, axis] += 0.5 * step
            out.append(corner + idx * voxel)
    return np.vstack(out)


def _grown(cells: npt.NDArray[np.bool_]) -> npt.NDArray[np.bool_]:
    """``cells`` grown by one cell along each axis (6-neighbours)."""
    padded = np.pad(cells, 1, constant_values=False)
    out = cells.copy()
    inner = (slice(1, -1),) * 3
    for axis in range(3):
        for step in (-1, 1):
            out |= np.roll(padded, step, axis=axis)[inner]
    return out


def _inside(points: F64, obj: F64) -> npt.NDArray[np.bool_]:
    """The points within the object's bounding box (the public code's centroid counts
    the unexplored points there, the object's hidden part)."""
    lo, hi = obj.min(axis=0), obj.max(axis=0)
    inside: npt.NDArray[np.bool_] = np.all((points >= lo) & (points <= hi), axis=1)
    return inside
