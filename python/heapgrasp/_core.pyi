"""Type stubs of the native module ``heapgrasp._core`` (Rust, pyo3).

Conventions: poses are ``(4, 4)`` float64 rigid ``a2b`` matrices (``cam2world``,
``obj2world``) with OpenCV camera axes (x right, y down, z forward). A camera point
``(x, y, z)``, ``z > 0``, lands on pixel ``(floor(fx*x/z + cx + 0.5), floor(fy*y/z + cy + 0.5))``;
images and masks are ``(H, W)`` indexed ``[v, u]``. A grid is a cube (``origin`` = min
corner, ``size``, ``resolution`` R); voxel ``[a, b, c]`` has its centre at
``origin + (index + 0.5) * size / R``; volumes are ``(R, R, R)`` C-order ``[x, y, z]``.
Arrays must be C-contiguous and aligned, with the stated dtype in native byte order;
anything else raises ``ShapeError``. A bool array may hold any byte (a view of other
data): nonzero reads as True, as in NumPy. Numbers are ints, floats or NumPy scalars: a
bool (Python's or NumPy's) is never taken for a number, and an object that is not a
number raises ``InvalidValueError`` naming the argument (not ``TypeError``); so does an
object of the wrong class where a ``PinholeCamera``, ``OccupancyGrid`` or ``MeshScene``
is expected. Sequences (3-vectors, camera and mask lists, trajectories) are read item by
item up to the length the call needs: an endless iterable is refused, not drained.
"""

from collections.abc import Mapping, Sequence
from typing import Any, final

import numpy as np
import numpy.typing as npt

__all__ = [
    "GraspLabeller",
    "HeapgraspError",
    "InvalidValueError",
    "MeshError",
    "MeshScene",
    "NonFiniteError",
    "NotRigidError",
    "OccupancyGrid",
    "PinholeCamera",
    "ShapeError",
    "TSDFVolume",
    "UnknownMeshError",
    "__version__",
    "antipodal_grasps",
    "antipodal_pairs",
    "contact_patches",
    "depth_voxels",
    "first_free_pose",
    "gaussian_filter3d",
    "grasp_region",
    "hand_point_counts",
    "keep_silhouettes",
    "kernel_level",
    "kernel_request_problem",
    "maximum_filter3d",
    "nms3d",
    "num_threads",
    "point_normals",
    "score_views",
    "seen_empty",
    "surfel_visibility",
    "voxel_downsample",
]

__version__: str

class HeapgraspError(ValueError):
    """Base class of every heapgrasp error."""

class ShapeError(HeapgraspError):
    """An array has the wrong shape, dtype or memory layout."""

class InvalidValueError(HeapgraspError):
    """A parameter is outside its valid range."""

class NonFiniteError(HeapgraspError):
    """An array holds NaN or infinity where finite values are required."""

class NotRigidError(HeapgraspError):
    """A 4x4 matrix that must be a rigid transform is not one."""

class MeshError(HeapgraspError):
    """A mesh cannot be used."""

class UnknownMeshError(HeapgraspError):
    """A mesh id that the scene does not hold."""

_Mask2 = npt.NDArray[np.bool_] | npt.NDArray[np.uint8]
_Mask3 = npt.NDArray[np.bool_] | npt.NDArray[np.uint8]
_F64 = npt.NDArray[np.float64]
_F32 = npt.NDArray[np.float32]
_U32 = npt.NDArray[np.uint32]
_Vec3 = Sequence[float] | npt.NDArray[np.floating]

@final
class PinholeCamera:
    """Ideal pinhole camera (no distortion); pixel centres at integer coordinates."""

    def __new__(
        cls, width: int, height: int, fx: float, fy: float, cx: float, cy: float
    ) -> PinholeCamera: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def fx(self) -> float: ...
    @property
    def fy(self) -> float: ...
    @property
    def cx(self) -> float: ...
    @property
    def cy(self) -> float: ...
    def __eq__(self, other: object, /) -> bool: ...
    def __getnewargs__(self) -> tuple[int, int, float, float, float, float]: ...

@final
class OccupancyGrid:
    """Shape-from-Silhouette counts on a cube (HEAPGrasp eq. 9-10)."""

    def __new__(
        cls, origin: _Vec3, size: float = 0.30, resolution: int | None = None
    ) -> OccupancyGrid:
        """``resolution=None`` means 40 voxels per axis (HEAPGrasp Table I)."""
    @property
    def origin(self) -> tuple[float, float, float]: ...
    @property
    def size(self) -> float: ...
    @property
    def resolution(self) -> int: ...
    @property
    def voxel_size(self) -> float: ...
    def integrate(self, mask: _Mask2, camera: PinholeCamera, cam2world: _F64) -> None:
        """Add one silhouette: ``mask`` bool/uint8 ``(H, W)``, nonzero = object."""
    def integrate_many(
        self,
        masks: _Mask2,
        camera: PinholeCamera,
        cam2worlds: _F64,
        *,
        threads: int | None = None,
    ) -> None:
        """Add N silhouettes ``(N, H, W)`` seen from ``(N, 4, 4)`` poses; all-or-nothing.

        ``threads``: carve on exactly that many threads (1 to 256) rather than as many as
        the work is worth; the counts do not depend on it. Counts saturate at 2**32 - 1.
        """
    def counts(self) -> tuple[_U32, _U32]:
        """``(segmented, visible)`` uint32 ``(R, R, R)`` copies."""
    def occupancy(self) -> _F32:
        """``segmented / visible`` where ``visible > 0`` else 0 (eq. 10), float32."""
    def high_confidence(self, lam: float = 0.9) -> _F32:
        """Occupancy with values below ``lam`` set to 0."""
    def count_high_confidence(self, lam: float = 0.9) -> int:
        """Number of non-zero voxels of :meth:`high_confidence`."""
    def reset(self) -> None: ...
    def copy(self) -> OccupancyGrid: ...
    def __copy__(self) -> OccupancyGrid: ...
    def __deepcopy__(self, memo: object) -> OccupancyGrid: ...
    @staticmethod
    def from_counts(origin: _Vec3, size: float, segmented: _U32, visible: _U32) -> OccupancyGrid:
        """A grid with given uint32 ``(R, R, R)`` counts (``segmented <= visible``)."""

@final
class TSDFVolume:
    """Truncated signed distance fusion of depth images (the VGN baseline's input).

    Per voxel centre visible in a frame with valid depth ``d`` (finite, > 0):
    ``sdf = d - z``; skipped if ``sdf < -truncation``; observation
    ``min(1, sdf / truncation)`` averaged with weight 1. Unobserved voxels are 0 with
    weight 0.
    """

    def __new__(
        cls,
        origin: _Vec3,
        size: float = 0.30,
        resolution: int | None = None,
        truncation: float = 0.03,
    ) -> TSDFVolume:
        """``resolution=None`` means 40 voxels per axis."""
    @property
    def origin(self) -> tuple[float, float, float]: ...
    @property
    def size(self) -> float: ...
    @property
    def resolution(self) -> int: ...
    @property
    def truncation(self) -> float: ...
    def integrate(self, depth_m: _F32, camera: PinholeCamera, cam2world: _F64) -> None:
        """Fuse a float32 ``(H, W)`` depth image in metres (0 or NaN = missing)."""
    def values(self) -> _F32: ...
    def weights(self) -> _F32: ...
    def reset(self) -> None: ...
    def copy(self) -> TSDFVolume: ...

@final
class MeshScene:
    """Rigid triangle meshes: exact silhouettes, depth and labels (ray through pixel centre)."""

    def __new__(cls) -> MeshScene: ...
    def add_mesh(
        self,
        vertices: _F64,
        faces: npt.NDArray[np.int64] | npt.NDArray[np.int32] | npt.NDArray[np.uint32],
        obj2world: _F64,
    ) -> int:
        """Add ``(V, 3)`` object-frame vertices and ``(F, 3)`` faces; returns the id (>= 1)."""
    def set_pose(self, id: int, obj2world: _F64) -> None: ...
    def pose(self, id: int) -> _F64: ...
    def remove(self, id: int) -> None: ...
    def ids(self) -> list[int]: ...
    def is_closed(self, id: int) -> bool: ...
    @property
    def triangle_count(self) -> int: ...
    def __len__(self) -> int: ...
    def render_mask(self, camera: PinholeCamera, cam2world: _F64) -> npt.NDArray[np.bool_]:
        """bool ``(H, W)``: True where the pixel-centre ray hits a mesh."""
    def render_depth(self, camera: PinholeCamera, cam2world: _F64) -> _F32:
        """float32 ``(H, W)``: camera z of the nearest hit in metres, 0 where none."""
    def render_labels(self, camera: PinholeCamera, cam2world: _F64) -> _U32:
        """uint32 ``(H, W)``: id of the nearest mesh, 0 where none."""
    def cast_ray(self, origin: _Vec3, direction: _Vec3) -> tuple[float, int] | None:
        """First hit of a world-frame ray: ``(distance, id)`` or None."""

@final
class GraspLabeller:
    """Exact-geometry grasp labels: would a parallel-jaw grasp, executed as VGN executes
    it in physics with the fingers fully open, hold an object?

    The scene: rigid objects, each a set of convex pieces (every ``(V, 3)`` vertex array
    is collided as its convex hull) at an ``obj2world`` pose, on the table's half-space
    below ``z = table_z`` (world frame, metres). The hand, in its TCP frame (z the
    approach, fingers closing along y) with the fingers fully open: ``hand`` is a
    mapping either with the fields of :class:`heapgrasp.geometry.gripper.GripperGeometry`
    (its boxes; pads at ``y = ±max_opening / 2``; the two ``*_half`` entries are pairs),
    or with ``palm``, ``left`` (the +y finger), ``right``: sequences of (V, 3) float64
    vertex arrays each collided as its convex hull, ``max_opening``, and optionally the
    contact thresholds ``palm_threshold`` and ``finger_threshold`` (m, default 0).

    Per grasp: (1) the open hand's parts, swept from the pre-grasp pose
    (``pregrasp_distance`` back along z) to ``approach_lag`` short of the grasp pose,
    stay farther than ``hand_margin + object_margin`` plus the smaller contact threshold
    of the pair from every piece, and ``hand_margin`` plus the part's threshold from the
    table, else ``collision``; (2) each finger, cast inward across the whole opening,
    meets an object (``empty`` if not), both the same one (``two-objects``), the closed
    width (opening minus both travels: a finger that meets a free object first pushes it
    to the other) is at least ``min_width`` (``narrow``), both contact normals (from the
    closest points where the fingers stop) lie within ``atan(friction)`` of the closing
    direction (``not-antipodal``).
    ``reasons()`` names the codes. Raises ``InvalidValueError`` naming a bad parameter.
    """

    def __new__(
        cls,
        hand: Mapping[str, Any],
        *,
        table_z: float,
        friction: float,
        pregrasp_distance: float,
        hand_margin: float,
        object_margin: float,
        min_width: float,
        approach_lag: float | None = None,
    ) -> GraspLabeller: ...
    def add_object(
        self, id: int, obj2world: _F64, pieces: Sequence[_F64], threshold: float | None = None
    ) -> None:
        """Adds object ``id`` (an int in [0, 2**31 - 1], not in the scene yet) at
        ``obj2world`` (4, 4) float64, made of ``pieces``: (V, 3) float64 vertex arrays in
        the object frame (m), V >= 4 spanning a volume (else ``MeshError``), at most 4096
        pieces; ``threshold`` its contact threshold (m, default 0)."""
    def label(
        self, tcp2world: _F64, *, threads: int | None = None
    ) -> tuple[npt.NDArray[np.bool_], _F32, npt.NDArray[np.int32], npt.NDArray[np.uint8]]:
        """Labels ``tcp2world`` (N, 4, 4) float64 rigid TCP poses (world) on ``threads``
        threads (None or 0: ``num_threads()``; results do not depend on it), releasing
        the GIL. Returns ``(success bool (N,), width float32 (N,), object int32 (N,),
        reason uint8 (N,))``: ``width`` the distance between the pads once closed (m;
        ``max_opening`` for a failure), ``object`` the id held (-1 for none), ``reason``
        an index into ``reasons()``."""
    @staticmethod
    def reasons() -> list[str]:
        """The reason codes' names, by code: success, collision, empty, two-objects,
        not-antipodal, narrow."""
    @property
    def table_z(self) -> float: ...
    @property
    def object_count(self) -> int: ...
    @property
    def piece_count(self) -> int: ...

def score_views(
    grid: OccupancyGrid,
    scene: MeshScene,
    camera: PinholeCamera,
    trajectories: Sequence[_F64],
    lam: float = 0.9,
    region: _Mask3 | None = None,
) -> _F32:
    """Exact eq. 14 score of each candidate trajectory (``(M_k, 4, 4)`` poses, 1 to 4096
    each; at most 65536 trajectories), float32 (K,).

    ``1 - #high-confidence after / #high-confidence before`` (float32 arithmetic),
    rendering the hypothetical masks from ``scene``. All zeros when the grid has no
    high-confidence voxel. Scores can be negative: voxels never seen before can become
    high-confidence when a new view segments them. With ``region`` (an ``(R, R, R)``
    bool or uint8 mask) both counts are restricted to its voxels; all zeros when it holds
    no high-confidence voxel.
    """

def antipodal_grasps(
    occupied: npt.NDArray[np.bool_],
    gradient: _F64,
    labels: npt.NDArray[np.int32],
    centroids: _F64,
    candidates: npt.NDArray[np.int64],
    rotations: _F64,
    tilts: _F64,
    params: Mapping[str, Any],
) -> tuple[_F64, npt.NDArray[np.int64], _F64]:
    """Each candidate's best antipodal grasp over every TCP orientation.

    ``occupied`` (R, R, R) bool; ``gradient`` (3, R, R, R) of the smoothed occupancy;
    ``labels`` (R, R, R) int32 blob labels indexing ``centroids`` (L, 3) (metres from the
    grid origin); ``candidates`` (N, 3) voxel indices of the TCPs; ``rotations``
    (K, 3, 3) TCP-to-world with their ``tilts`` (K,). ``params``: the voxel size, the
    grid's ``origin_z``, the gripper geometry and the thresholds of ``AntipodalPlanner``
    by name (the core puts the gripper on the lattice), in any mapping; the two
    ``*_half`` entries are pairs. Every gripper length must be finite and at most 65536
    voxels; ``min_patch`` an int in [0, 2**32 - 1]. ``rotations`` must be rotations
    (orthonormal, det +1, within 1e-4: else ``NotRigidError``) and ``tilts`` finite.
    Returns per candidate the best quality in [0, 1] (0: none), the index of its
    orientation and its width (m).
    """

def hand_point_counts(
    hand: Mapping[str, Any],
    tcp2world: _F64,
    openings: _F64,
    points: _F64,
    *,
    cell: float | None = None,
    threads: int | None = None,
) -> npt.NDArray[np.uint32]:
    """How many of ``points`` lie inside the hand at each pose (seed 001's gripper
    collision check against the object's and the unexplored region's points).

    ``hand``: a mapping of ``GripperGeometry``'s fields (its boxes); ``tcp2world``
    (N, 4, 4) float64 TCP poses (z the approach, fingers closing along y); ``openings``
    (N,) float64 distance between the finger pads (m), in (0, ``hand["max_opening"]``];
    ``points`` (P, 3) float64 world points, indexed in cells of ``cell`` metres
    (default 0.01). Returns (N,) counts (a point inside two of the hand's boxes counts
    twice). Runs on ``threads`` threads (0 or None: all) with the GIL released.
    """

def point_normals(
    points: _F64, *, k: int | None = None, threads: int | None = None
) -> tuple[_F64, _F64]:
    """Unit normals and curvatures of a point cloud from each point's ``k`` nearest
    points, itself included (seed 001's normals; PCL's ``NormalEstimation``).

    ``points`` (N, 3) float64, N >= ``k``; ``k`` an int >= 3 (default 10). Returns the
    (N, 3) normals (the covariance's eigenvector of the smallest eigenvalue, turned away
    from the cloud's centroid) and the (N,) curvatures ``λ0 / (λ0 + λ1 + λ2)``.
    """

def contact_patches(
    points: _F64,
    normals: _F64,
    candidates: npt.NDArray[np.bool_],
    *,
    threads: int | None = None,
) -> npt.NDArray[np.bool_]:
    """Whether a finger pad fits on the surface at each candidate point (seed 001's
    contact patch: the points within ±5 mm along the normal and ±30 mm across it, at
    1 px/mm; their convex hull in a disc of 18 px must hold a pixel 26 / 1.9 px from its
    edge).

    ``points``, ``normals`` (N, 3) float64 (unit normals); ``candidates`` (N,) bool.
    Returns (N,) bool, False where not a candidate.
    """

def antipodal_pairs(
    points: _F64,
    normals: _F64,
    usable: npt.NDArray[np.bool_],
    *,
    voxel: float,
    max_width: float,
    min_quality: float,
    threads: int | None = None,
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], _F64, _F64]:
    """Every pair ``i < j`` of usable points whose distance plus ``voxel`` is at most
    ``max_width`` with quality ``180° − (A + B)`` at least ``min_quality`` (degrees, in
    [0, 180]); ``A``, ``B`` the angles between the contact line and each normal.

    Returns (first, second, quality, width), ordered by (i, j).
    """

def depth_voxels(
    depth: _F32,
    camera: PinholeCamera,
    cam2world: _F64,
    *,
    min_range: float,
    max_range: float,
    voxel: float,
) -> _F64:
    """The world points of a depth view whose depth (m along the optical axis) lies in
    ``[min_range, max_range]``, down-sampled as :func:`voxel_downsample` does (pixels in
    row-major order; pixel ``(u, v)`` on the ray ``((u − cx) / fx, (v − cy) / fy, 1)``).

    ``depth`` (H, W) float32, the camera's size; ``cam2world`` a rigid (4, 4) pose.
    Returns (M, 3) float64.
    """

def voxel_downsample(points: _F64, voxel: float) -> _F64:
    """One point per occupied ``voxel``-sized cell of a lattice anchored at the origin:
    the centroid of the cell's points (summed in the points' order), cells in
    lexicographic order of their index ``⌊p / voxel⌋``.

    ``points`` (N, 3) float64, finite; ``voxel`` > 0 (m). Returns (M, 3) float64.
    """

def grasp_region(
    points: _F64,
    normals: _F64,
    targets: _F64,
    *,
    half_length: float,
    radius: float,
    threads: int | None = None,
) -> npt.NDArray[np.bool_]:
    """Whether each target lies within ``half_length`` along and ``radius`` across the
    normal line of some object point (seed 001's 3D heuristic: the unexplored points
    that could hold a grasp).

    ``points``, ``normals`` (N, 3) float64 (non-zero normals, normalised here);
    ``targets`` (M, 3) float64; ``half_length``, ``radius`` > 0 (m) with
    ``half_length / radius <= 10,000`` (the region is sampled every ``radius`` along each
    normal). Returns (M,) bool.
    """

def surfel_visibility(
    points: _F64,
    normals: _F64,
    eyes: _F64,
    targets: _F64,
    *,
    radius: float,
    threads: int | None = None,
) -> npt.NDArray[np.bool_]:
    """Whether each target is visible from each eye past a surfel reconstruction of the
    object points: squares of half width ``radius`` across their normals, ray cast with
    parry3d's BVH (the unseen parts of the object occlude nothing).

    ``points``, ``normals`` (N, 3) float64; ``eyes`` (V, 3), ``targets`` (M, 3) float64;
    ``radius`` > 0 (m). Returns (V, M) bool. The field of view and the sensor's range
    are the caller's.
    """

def first_free_pose(
    hand: Mapping[str, Any],
    tcp2world: _F64,
    openings: _F64,
    points: _F64,
    *,
    cell: float | None = None,
    threads: int | None = None,
) -> int | None:
    """The index of the first pose at which the hand holds none of ``points``, or None.

    The arguments are :func:`hand_point_counts`'; the answer is the first ``i`` with
    ``hand_point_counts(...)[i] == 0``, found with each pose's search stopped at its
    first point and the poses after the answer left unchecked.
    """

def seen_empty(
    points: _F64,
    depth: _F32,
    camera: PinholeCamera,
    cam2world: _F64,
    *,
    min_range: float,
    max_range: float,
    occlusion: float,
    floor_z: float,
    threads: int | None = None,
) -> npt.NDArray[np.bool_]:
    """Whether a depth view shows each world point to be empty (seed 001's unexplored
    region).

    ``points`` (N, 3) float64; ``depth`` (H, W) float32, the camera's size (m along the
    optical axis). A point is seen empty when it projects into the image in front of the
    camera, ``z >= floor_z``, and the depth at its pixel is missing (NaN or outside
    ``[min_range, max_range]``) or beyond ``occlusion`` times its own depth. Points off
    the image are not seen. Returns (N,) bool.
    """

def keep_silhouettes(
    full: npt.NDArray[np.bool_],
    trimmed: npt.NDArray[np.bool_],
    origin: _Vec3,
    voxel_size: float,
    cameras: Sequence[PinholeCamera],
    poses: _F64,
    masks: Sequence[npt.NDArray[np.bool_]],
) -> npt.NDArray[np.bool_]:
    """The voxels of ``full`` (R, R, R) that roof trimming cut from ``trimmed`` and that
    the silhouettes show to be real (``heapgrasp.roofs.keep_silhouettes``' rule).

    One view per entry of ``cameras``, ``poses`` (N, 4, 4) cam2world and ``masks``
    ((height, width) bool each; ``cameras`` and ``masks`` any iterables of N entries).
    Returns a bool (R, R, R) volume. Raises ``ShapeError``,
    ``InvalidValueError``, ``NonFiniteError`` or ``NotRigidError`` naming the bad
    argument.
    """

def gaussian_filter3d(volume: _F32, sigma: float) -> _F32:
    """Equal to ``scipy.ndimage.gaussian_filter(volume, sigma, mode="nearest", truncate=4)``."""

def maximum_filter3d(volume: _F32, window: int | None = None) -> _F32:
    """Max over offsets ``[-(w//2), w-1-w//2]`` per axis, clipped (``window=None``: 4)."""

def nms3d(volume: _F32, threshold: float, window: int | None = None) -> npt.NDArray[np.int64]:
    """Voxels ``>= threshold`` equal to their window max, ``(K, 3)``, best first."""

def kernel_level() -> str:
    """``"avx512"``, ``"avx2"`` or ``"baseline"``: the carving kernel build in use."""

def kernel_request_problem() -> str | None:
    """Why ``HEAPGRASP_KERNEL`` was not honoured (an unknown value, or a level this CPU
    lacks), or None."""

def num_threads() -> int:
    """Threads used by the kernels (``HEAPGRASP_NUM_THREADS`` or the CPU count)."""
