"""heapgrasp: active-perception robotic grasping with a hand-eye camera.

The geometric core (Rust, ``heapgrasp._core``) provides the pieces every experiment
shares: pinhole cameras, the Shape-from-Silhouette occupancy grid of HEAPGrasp
(eq. 9-10), TSDF fusion for the VGN baseline, ground-truth mesh silhouettes, exact
view scoring (eq. 14), 3-D smoothing / non-maximum suppression, and exact-geometry
grasp labels.

Conventions (shared by every function):

* Poses are ``(4, 4)`` float64 ``a2b`` matrices, e.g. ``cam2world``; camera axes are
  OpenCV's (x right, y down, z forward).
* A camera point ``(x, y, z)``, ``z > 0``, lands on pixel
  ``(floor(fx*x/z + cx + 0.5), floor(fy*y/z + cy + 0.5))``; masks are ``(H, W)`` arrays
  indexed ``[v, u]``.
* A grid is a cube with minimum corner ``origin``, side ``size`` and ``resolution`` R;
  voxel ``[a, b, c]`` has its centre at ``origin + (index + 0.5) * size / R``; volumes are
  ``(R, R, R)`` C-order arrays indexed ``[x, y, z]``.

Kernels: ``kernel_level()`` names the carving kernel in use, the best the CPU has
(``avx512``, ``avx2`` or ``baseline``); ``HEAPGRASP_KERNEL`` forces a level the CPU has
(a value it cannot honour is named in a warning at import), ``HEAPGRASP_NO_SIMD`` the
portable one.
"""

import warnings as _warnings

from heapgrasp._core import (
    GraspLabeller,
    HeapgraspError,
    InvalidValueError,
    MeshError,
    MeshScene,
    NonFiniteError,
    NotRigidError,
    OccupancyGrid,
    PinholeCamera,
    ShapeError,
    TSDFVolume,
    UnknownMeshError,
    __version__,
    antipodal_pairs,
    contact_patches,
    depth_voxels,
    first_free_pose,
    gaussian_filter3d,
    grasp_region,
    hand_point_counts,
    kernel_level,
    kernel_request_problem,
    maximum_filter3d,
    nms3d,
    num_threads,
    point_normals,
    score_views,
    seen_empty,
    surfel_visibility,
    voxel_downsample,
)

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
    "antipodal_pairs",
    "contact_patches",
    "depth_voxels",
    "first_free_pose",
    "gaussian_filter3d",
    "grasp_region",
    "hand_point_counts",
    "kernel_level",
    "maximum_filter3d",
    "nms3d",
    "num_threads",
    "point_normals",
    "score_views",
    "seen_empty",
    "surfel_visibility",
    "voxel_downsample",
]

if (_problem := kernel_request_problem()) is not None:
    _warnings.warn(f"{_problem}; using the {kernel_level()} kernel", stacklevel=2)
