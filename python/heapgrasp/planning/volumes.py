"""Per-voxel grasp predictions (HEAPGrasp eq. 11) and their post-processing (eq. 15).

A grasp planner maps a grid to :class:`GraspVolumes`: at every voxel centre a grasp
quality in [0, 1], a TCP orientation (quaternion ``x, y, z, w``, world axes) and an
opening width. :func:`select_candidates` then smooths the quality with a 3-D Gaussian,
keeps the voxels scoring at least ε that are maxima of their neighbourhood (NMS), and
returns them as :class:`GraspCandidate` objects, best first: the set
``P_grasp,ε`` of eq. 15.

The TCP frame is ``panda_grasptarget``: z is the approach direction, the fingers close
along y (as VGN).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from heapgrasp import gaussian_filter3d, nms3d
from heapgrasp.geometry.grid import GridFrame
from heapgrasp.geometry.gripper import PANDA_HAND

__all__ = [
    "GraspCandidate",
    "GraspPlanner",
    "GraspVolumes",
    "quaternion_to_matrix",
    "select_candidates",
]

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]


@dataclass(frozen=True)
class GraspVolumes:
    """Per-voxel grasp predictions on a grid (eq. 11)."""

    frame: GridFrame
    quality: F32
    """``(R, R, R)`` grasp score in [0, 1]."""
    quaternions: F32
    """``(R, R, R, 4)`` TCP orientation, unit quaternions ``x, y, z, w`` in world axes."""
    widths: F32
    """``(R, R, R)`` gripper opening (m)."""
    tcp_offset: float = 0.0
    """How far the TCP lies ahead of a voxel's centre along its grasp's approach (z), m:
    0 where the voxels hold the TCP itself (the analytic planner); a grasp network's
    voxels hold VGN's grasp origin, the centre of the palm's face, which lies
    ``-palm_front`` (3.9 cm for the Panda hand) behind the TCP."""

    def __post_init__(self) -> None:
        if not math.isfinite(self.tcp_offset):
            raise ValueError(f"GraspVolumes.tcp_offset must be finite, got {self.tcp_offset}")
        r = self.frame.resolution
        for name, arr, shape in (
            ("quality", self.quality, (r, r, r)),
            ("quaternions", self.quaternions, (r, r, r, 4)),
            ("widths", self.widths, (r, r, r)),
        ):
            if not isinstance(arr, np.ndarray) or arr.shape != shape:
                got = getattr(arr, "shape", type(arr).__name__)
                raise ValueError(f"GraspVolumes.{name} must have shape {shape}, got {got}")
            if not np.isfinite(arr).all():
                raise ValueError(f"GraspVolumes.{name} holds NaN or infinity")


@dataclass(frozen=True)
class GraspCandidate:
    """One grasp of ``P_grasp,ε`` (eq. 15)."""

    pose: F64
    """``(4, 4)`` TCP pose in the world (z = approach, fingers along y)."""
    width: float
    """Opening (m)."""
    score: float
    """Smoothed grasp score."""
    index: tuple[int, int, int]
    """Voxel the grasp was read from (its TCP's, or its grasp origin's:
    :attr:`GraspVolumes.tcp_offset`)."""

    @property
    def position(self) -> F64:
        """TCP position (world, m)."""
        return self.pose[:3, 3]

    @property
    def quaternion(self) -> F64:
        """TCP orientation ``x, y, z, w``."""
        return matrix_to_quaternion(self.pose[:3, :3])


@runtime_checkable
class GraspPlanner(Protocol):
    """Maps a measured grid to grasp volumes, and declares what the loop needs to know of
    it (the loop reads these, never the planner's name)."""

    name: str
    """For records and labels only."""
    input_kind: str
    """The grid it reads: ``"occupancy"`` (``Ŝ≥λ``) or ``"tsdf"`` (the VGN baseline's)."""
    sigma: float
    """Eq. 15's smoothing of its quality volume (σ, voxels) unless the run sets one."""
    epsilon: float
    """Eq. 15's threshold on its smoothed quality (ε) unless the run or a critic sets one."""
    opens_fully: bool
    """Its grasps are executed with the hand fully open (as they were labelled), else
    opened to the candidate's width + 1 cm."""
    needs_hull_check: bool
    """Its poses are not checked against the grid it read (a network's regressed ones):
    the loop checks them against the hull (:class:`~heapgrasp.planning.hull_check.HullCheck`;
    for a TSDF network, against the TSDF's observed shells)."""

    def predict(self, grid: F32, frame: GridFrame) -> GraspVolumes:
        """``grid``: ``(R, R, R)`` float32 input volume (the high-confidence occupancy
        grid for HEAPGrasp, a TSDF for the VGN baseline)."""
        ...


def quaternion_to_matrix(q: npt.ArrayLike) -> F64:
    """Rotation matrices of unit quaternions ``(..., 4)`` ``x, y, z, w``."""
    a = np.asarray(q, dtype=np.float64)
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    x, y, z, w = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    out = np.empty((*a.shape[:-1], 3, 3))
    out[..., 0, 0] = 1 - 2 * (y * y + z * z)
    out[..., 0, 1] = 2 * (x * y - z * w)
    out[..., 0, 2] = 2 * (x * z + y * w)
    out[..., 1, 0] = 2 * (x * y + z * w)
    out[..., 1, 1] = 1 - 2 * (x * x + z * z)
    out[..., 1, 2] = 2 * (y * z - x * w)
    out[..., 2, 0] = 2 * (x * z - y * w)
    out[..., 2, 1] = 2 * (y * z + x * w)
    out[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return out


def matrix_to_quaternion(rot: npt.ArrayLike) -> F64:
    """Unit quaternion ``x, y, z, w`` (``w >= 0``) of a rotation matrix ``(3, 3)``."""
    from scipy.spatial.transform import Rotation

    q = np.asarray(Rotation.from_matrix(np.asarray(rot, dtype=np.float64)).as_quat())
    return q if q[3] >= 0 else -q


def _peaks(smooth: F32, epsilon: float, window: int) -> npt.NDArray[np.int64]:
    """``nms3d(smooth, epsilon, window)``, run on the smallest cube of the grid that holds
    every voxel scoring ``>= epsilon``: the same peaks in the same order (a voxel outside
    scores below ε and cannot beat one inside; ties go by flat index, which a shift
    keeps), for a fraction of the voxels."""
    above = np.argwhere(smooth >= np.float32(epsilon))
    if len(above) == 0:
        return np.zeros((0, 3), dtype=np.int64)
    r = smooth.shape[0]
    lo = above.min(axis=0)
    side = int((above.max(axis=0) + 1 - lo).max())
    lo = np.minimum(lo, r - side)  # the cube stays inside the grid
    a, b, c = (int(x) for x in lo)
    crop = np.ascontiguousarray(smooth[a : a + side, b : b + side, c : c + side])
    peaks: npt.NDArray[np.int64] = np.asarray(nms3d(crop, float(epsilon), window), np.int64)
    peaks += lo
    return peaks


def _poses(volumes: GraspVolumes, idx: npt.NDArray[np.int64]) -> F64:
    """``(N, 4, 4)`` TCP poses of the grasps at voxels ``idx``."""
    a, b, c = idx[:, 0], idx[:, 1], idx[:, 2]
    rots = quaternion_to_matrix(volumes.quaternions[a, b, c])
    poses = np.tile(np.eye(4), (len(idx), 1, 1))
    poses[:, :3, :3] = rots
    poses[:, :3, 3] = volumes.frame.centers(idx) + volumes.tcp_offset * rots[:, :, 2]
    return poses


def select_candidates(
    volumes: GraspVolumes,
    *,
    epsilon: float = 0.8,
    sigma: float = 1.0,
    nms_window: int = 4,
    max_width: float = PANDA_HAND.max_opening,
    reject: Callable[[F64], npt.NDArray[np.bool_]] | None = None,
) -> list[GraspCandidate]:
    """``P_grasp,ε`` of eq. 15: smooth the quality (3-D Gaussian, ``sigma`` voxels; 0 =
    none), keep voxels with score ``>= epsilon`` that are the maximum of their
    ``nms_window``-wide neighbourhood, best first. Widths are clipped to
    ``[0, max_width]``.

    ``reject``: maps ``(N, 4, 4)`` TCP poses to ``(N,)`` bools, True for a grasp to drop
    (:class:`~heapgrasp.planning.hull_check.HullCheck`), applied to every voxel scoring
    ``>= epsilon`` before NMS: a dropped grasp suppresses none of its neighbours."""
    if not (math.isfinite(epsilon) and 0.0 <= epsilon <= 1.0):
        raise ValueError(f"epsilon must be in [0, 1], got {epsilon}")
    if not (math.isfinite(sigma) and sigma >= 0.0):
        raise ValueError(f"sigma must be finite and >= 0, got {sigma}")
    if nms_window < 1:
        raise ValueError(f"nms_window must be >= 1, got {nms_window}")
    quality = np.ascontiguousarray(volumes.quality, dtype=np.float32)
    smooth = gaussian_filter3d(quality, sigma) if sigma > 0 else quality
    # Smoothing must not create grasps where the planner found none.
    smooth = np.where(quality > 0, smooth, np.float32(0.0)).astype(np.float32)
    if reject is not None:
        above = np.argwhere(smooth >= np.float32(epsilon))
        dropped = np.asarray(reject(_poses(volumes, above)), dtype=bool)
        if dropped.shape != (len(above),):
            raise ValueError(f"reject returned shape {dropped.shape} for {len(above)} poses")
        smooth[tuple(above[dropped].T)] = 0.0
    idx = _peaks(smooth, epsilon, nms_window)
    if len(idx) == 0:
        return []
    a, b, c = idx[:, 0], idx[:, 1], idx[:, 2]
    poses = _poses(volumes, idx)
    out = []
    for k in range(len(idx)):
        pose = poses[k].copy()
        width = float(np.clip(volumes.widths[a[k], b[k], c[k]], 0.0, max_width))
        out.append(
            GraspCandidate(
                pose=pose,
                width=width,
                score=float(smooth[a[k], b[k], c[k]]),
                index=(int(a[k]), int(b[k]), int(c[k])),
            )
        )
    return out
