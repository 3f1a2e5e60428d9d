"""Analytic antipodal grasp planner on a voxel occupancy grid (no training).

The force-closure grasp synthesis of seed 001 §3.3 — pairs of contacts whose surface
normals oppose each other, a contact patch large enough on both fingers, a
collision-free approach checked against the measured volume, a preference for grasps
near the line of gravity — adapted to the high-confidence occupancy grid ``Ŝ≥λ`` of
HEAPGrasp and written as per-voxel grasp volumes (HEAPGrasp eq. 11), so that the
post-processing of §IV-B (Gaussian smoothing, threshold ε, non-maximum suppression;
:func:`~heapgrasp.grasping.volumes.select_candidates`) applies unchanged.

Method
------
For every TCP orientation of a fixed set (top-down plus tilted approaches, each with
``n_yaw`` closing directions, see :func:`grasp_orientations`) the grid is resampled on a
lattice aligned with the TCP axes (x across the fingers, y the closing axis, z the
approach), so that every part of the gripper is an axis-aligned box and every test is a
box sum or a scan along a lattice row. Two lattices are used: a conservative one, where
a cell is occupied when its cube overlaps an occupied voxel (collisions, opening), and a
nearest-voxel one (contact geometry). For every candidate TCP (the voxel centres on or
next to occupied voxels) and orientation:

1. *Closing region.* In the band swept by the finger pads, the nearest places on each
   side of the TCP where a finger fits (a free run as thick as the finger over its whole
   approach sweep) bound the object segment between the fingers; its extreme voxels are
   the contacts. The opening is symmetric about the TCP (the Panda's fingers are
   coupled): twice the farther contact plus a clearance, at most the maximum opening.
   The segment must not touch a side face of the grid (the object may go on outside).
2. *Collision-free approach.* The fingers at the executed opening and the palm, swept
   from the pre-grasp pose (``pregrasp_distance`` back along z) to the grasp, must not
   overlap occupied voxels, nor come closer than ``table_clearance`` to the table (the
   grid's bottom face; everything below is occupied).
3. *Antipodal contacts* (seed 001's contact-patch and normal constraints). On each
   finger the patch is the pad cells whose object extreme lies within a voxel of the
   contact; it must span ``min_patch`` cells. The contact normal comes from a plane
   fitted to the extremes around the patch (tilt along the approach) and from the
   summed gradients of the smoothed occupancy on the patch (tilt across the finger);
   both normals must lie in the friction cone about the closing axis.
4. *Quality* in [0, 1]: 1 for a clean grasp, times bounded factors for its weaknesses —
   normals near the edge of the cone, shallow finger engagement (below
   ``target_depth``), a small patch, a contact only one voxel high, the object off the
   TCP, the closing line far from the centroid of the grasped blob (seed 001 prefers
   grasps near the line of gravity), a tilted approach, and a *ledge*: the object
   widening just below the fingertips (``ledge_factor``). Carving from views above the
   scene leaves a roof on every object, narrower than the object and as high as half its
   width or more (:mod:`heapgrasp.roofs` trims most of it); contacts above a ledge may be
   on what is left of it, with the object below the fingertips.

Blobs of occupied voxels that do not reach down to the table (``support_height``) are
carving artefacts (e.g. voxels near the top of the cube seen from a few views only) and
are ignored. Every voxel keeps its best orientation. A valid grasp stays valid for TCPs
in a small region around it, so the quality volume is a set of blobs; smoothing keeps
their interiors, i.e. the grasps most robust to a TCP error.

Smoothing and threshold
-----------------------
A grasp region is only 2–4 voxels deep along the approach (the fingers reach 4.6 cm
below the palm, a voxel is 7.5 mm) and often as thin across, so a Gaussian of
HEAPGrasp's σ = 1 voxel keeps about half of its peak (a 3-voxel slab keeps 0.88 along
one axis, a 2 × 3 × 3 block ≈ 0.5): with ε = 0.8 almost no scene would have a
candidate. :attr:`AntipodalPlanner.sigma` = 0.5 keeps ≥ 0.89 of a block at least 2
voxels thick and 0.49 of an isolated voxel, and :attr:`AntipodalPlanner.epsilon` = 0.4
is the threshold calibrated on held-out simulated scenes (see the class docstring).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy import ndimage
from scipy.spatial.transform import Rotation

from heapgrasp import gaussian_filter3d
from heapgrasp.grasping.volumes import GraspVolumes, GridFrame

__all__ = ["AntipodalPlanner", "GripperGeometry", "grasp_orientations"]

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]
Bool = npt.NDArray[np.bool_]
AnyArr = npt.NDArray[Any]

_EPS = 1e-9
#: A lattice cell closer than this (in voxels, per axis) to a voxel centre overlaps
#: that voxel only.
_ALIGN_TOL = 0.05
#: Ridge (cells²) on the slopes of the contact-plane fit: a patch one voxel high is
#: taken as parallel to the approach.
_RIDGE = 1.0
#: The contact plane is fitted on the pad widened by this many cells, over the columns
#: whose extreme lies within ``_FIT_ROWS`` cells of the contact.
_FIT_MARGIN = 1
_FIT_ROWS = 3
#: Levels below the fingertips searched for a ledge.
_LEDGE_LEVELS = 2
#: Contact levels (cells along the approach at the extreme) of a flat contact.
_FLAT_LEVELS = 2


def _finite(name: str, value: float) -> float:
    v = float(value)
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return v


def _positive(name: str, value: float) -> float:
    v = _finite(name, value)
    if not v > 0:
        raise ValueError(f"{name} must be > 0, got {value!r}")
    return v


def _non_negative(name: str, value: float) -> float:
    v = _finite(name, value)
    if not v >= 0:
        raise ValueError(f"{name} must be >= 0, got {value!r}")
    return v


def _count(name: str, value: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
    return int(value)


def _ramp(x: npt.ArrayLike, x0: float, x1: float, y0: float, y1: float) -> F64:
    """``y0`` up to ``x0``, ``y1`` from ``x1``, linear in between."""
    t = np.clip((np.asarray(x, dtype=np.float64) - x0) / max(x1 - x0, 1e-12), 0.0, 1.0)
    return np.asarray(y0 + (y1 - y0) * t)


def _cells(lo: float, hi: float, v: float) -> tuple[int, int]:
    """Lattice offsets (inclusive range) whose cell centre lies in ``[lo, hi]``."""
    return math.ceil(lo / v - _EPS), math.floor(hi / v + _EPS)


@dataclass(frozen=True)
class GripperGeometry:
    """Collision model of a parallel-jaw gripper in its TCP frame (metres).

    The TCP frame is ``panda_grasptarget``: z is the approach direction (fingertips at
    positive z), the fingers close along y, x runs across the finger width. The
    defaults are the collision meshes of the Franka Panda hand
    (``pybullet_data/franka_panda/meshes/collision``).

    Parameters
    ----------
    finger_width
        Finger extent along x.
    finger_tip
        z of the fingertips (0.7 cm beyond the TCP).
    finger_base
        z where the fingers leave the hand.
    finger_split
        z where the finger changes from its thin tip to its thicker base.
    tip_thickness, base_thickness
        Finger extent along y (from the inner pad outwards) of the tip and base parts.
    palm_front
        z of the hand's face toward the fingertips.
    palm_split
        z where the hand's narrow front part meets its wider back part.
    palm_back
        z of the back of the hand.
    palm_front_half, palm_back_half
        ``(x, y)`` half extents of the hand's front and back parts.
    """

    finger_width: float = 0.021
    finger_tip: float = 0.0072
    finger_base: float = -0.0466
    finger_split: float = -0.02
    tip_thickness: float = 0.016
    base_thickness: float = 0.026
    palm_front: float = -0.039
    palm_split: float = -0.075
    palm_back: float = -0.131
    palm_front_half: tuple[float, float] = (0.022, 0.101)
    palm_back_half: tuple[float, float] = (0.032, 0.104)

    def __post_init__(self) -> None:
        for name in ("finger_width", "tip_thickness", "base_thickness"):
            _positive(f"GripperGeometry.{name}", getattr(self, name))
        for name in (
            "finger_tip",
            "finger_base",
            "finger_split",
            "palm_front",
            "palm_split",
            "palm_back",
        ):
            _finite(f"GripperGeometry.{name}", getattr(self, name))
        for name in ("palm_front_half", "palm_back_half"):
            half = tuple(getattr(self, name))
            if len(half) != 2:
                raise ValueError(f"GripperGeometry.{name} must be 2 numbers, got {half}")
            for h in half:
                _positive(f"GripperGeometry.{name}", h)
            object.__setattr__(self, name, (float(half[0]), float(half[1])))
        if not self.finger_base < self.finger_split < self.finger_tip:
            raise ValueError(
                "GripperGeometry.finger_base < finger_split < finger_tip is required, got "
                f"{self.finger_base}, {self.finger_split}, {self.finger_tip}"
            )
        if not self.palm_back < self.palm_split < self.palm_front < self.finger_tip:
            raise ValueError(
                "GripperGeometry.palm_back < palm_split < palm_front < finger_tip is "
                f"required, got {self.palm_back}, {self.palm_split}, {self.palm_front}"
            )


def grasp_orientations(tilts: tuple[float, ...], n_azimuth: int, n_yaw: int) -> tuple[F64, F64]:
    """TCP rotations searched by the planner.

    The approach direction (TCP z) is ``(sin t cos φ, sin t sin φ, -cos t)``: straight
    down for tilt ``t = 0``, else tilted by ``t`` toward azimuth ``φ`` (``n_azimuth``
    values over 360°). The closing axis (TCP y) turns about the approach in ``n_yaw``
    steps over 180° (the fingers are alike: yaw ψ and ψ + 180° are the same grasp).

    Parameters
    ----------
    tilts
        Tilts from the vertical (rad).
    n_azimuth
        Azimuths per non-zero tilt.
    n_yaw
        Closing directions per approach.

    Returns
    -------
    rotations : numpy.ndarray, shape (K, 3, 3)
        TCP-to-world rotations (columns: TCP x, y, z in world axes).
    tilt : numpy.ndarray, shape (K,)
        Tilt of each approach (rad).
    """
    rots: list[F64] = []
    tilt_of: list[float] = []
    for t in tilts:
        azimuths = [0.0] if t == 0 else [2 * math.pi * a / n_azimuth for a in range(n_azimuth)]
        for phi in azimuths:
            z = np.array([math.sin(t) * math.cos(phi), math.sin(t) * math.sin(phi), -math.cos(t)])
            e1 = np.array([-math.sin(phi), math.cos(phi), 0.0])
            e2 = np.cross(z, e1)
            for m in range(n_yaw):
                psi = math.pi * m / n_yaw
                y = math.cos(psi) * e1 + math.sin(psi) * e2
                rots.append(np.stack([np.cross(y, z), y, z], axis=1))
                tilt_of.append(float(t))
    return np.asarray(rots, dtype=np.float64), np.asarray(tilt_of, dtype=np.float64)


# --------------------------------------------------------------------------- lattice ops


def _overlap_grids(occ: Bool) -> Bool:
    """The 8 dilations of ``occ`` by ``{0, 1}`` voxel along each subset of axes, padded
    with 2 empty layers: ``out[4 sx + 2 sy + sz, t + 2]`` is whether any voxel in
    ``t .. t + s`` is occupied. A cell looked up with its overlapping voxels' lowest
    index ``t`` and per-axis spans ``s`` tells whether its cube overlaps an occupied
    voxel, in one gather."""
    r = occ.shape[0]
    base = np.zeros((r + 4,) * 3, dtype=bool)
    base[2:-2, 2:-2, 2:-2] = occ
    out = np.empty((8, *base.shape), dtype=bool)
    for code in range(8):
        d = base.copy()
        for axis, bit in enumerate((4, 2, 1)):
            if code & bit:
                shifted = np.zeros_like(d)
                sl = [slice(None)] * 3
                sl[axis] = slice(0, -1)
                src = [slice(None)] * 3
                src[axis] = slice(1, None)
                shifted[tuple(sl)] = d[tuple(src)]
                d |= shifted
        out[code] = d
    return out


def _integral_xz(q: Bool) -> npt.NDArray[np.int32]:
    """2-D integral over axes 0 and 2 with a leading zero plane: ``(A + 1, B, C + 1)``."""
    a, b, c = q.shape
    s = np.zeros((a + 1, b, c + 1), dtype=np.int32)
    np.cumsum(q, axis=0, dtype=np.int32, out=s[1:, :, 1:])
    np.cumsum(s[1:, :, 1:], axis=2, out=s[1:, :, 1:])
    return s


def _band_any(s2: npt.NDArray[np.int32], di: tuple[int, int], dk: tuple[int, int]) -> Bool:
    """Whether the window ``[di0, di1] x [dk0, dk1]`` (axes 0 and 2) around each cell
    holds an occupied cell; ``s2`` is :func:`_integral_xz`."""
    a, c = s2.shape[0] - 1, s2.shape[2] - 1
    i, k = np.arange(a), np.arange(c)
    ih, il = np.clip(i + di[1] + 1, 0, a), np.clip(i + di[0], 0, a)
    kh, kl = np.clip(k + dk[1] + 1, 0, c), np.clip(k + dk[0], 0, c)
    sh, sl = s2[ih], s2[il]
    return np.asarray((sh[:, :, kh] - sl[:, :, kh] - sh[:, :, kl] + sl[:, :, kl]) > 0)


def _cumsum_j(q: Bool) -> npt.NDArray[np.int32]:
    """Cumulative count along axis 1 with a leading zero plane: ``(A, B + 1, C)``."""
    out = np.zeros((q.shape[0], q.shape[1] + 1, q.shape[2]), dtype=np.int32)
    np.cumsum(q, axis=1, dtype=np.int32, out=out[:, 1:, :])
    return out


def _free_from(cum: npt.NDArray[np.int32], n: int) -> Bool:
    """Rows ``j`` such that rows ``j .. j + n - 1`` are free (beyond the lattice is)."""
    b = cum.shape[1] - 1
    j = np.arange(b)
    return np.asarray(np.take(cum, np.minimum(j + n, b), axis=1) == cum[:, :b, :])


def _free_to(cum: npt.NDArray[np.int32], n: int) -> Bool:
    """Rows ``j`` such that rows ``j - n + 1 .. j`` are free."""
    b = cum.shape[1] - 1
    j = np.arange(b)
    return np.asarray(cum[:, 1:, :] == np.take(cum, np.maximum(j - n + 1, 0), axis=1))


def _next_true(mask: Bool) -> npt.NDArray[np.int16]:
    """Per cell, the first row ``>= j`` where ``mask`` holds (``B`` if none)."""
    b = mask.shape[1]
    rows = np.arange(b, dtype=np.int16)[None, :, None]
    idx = np.where(mask, rows, np.int16(b))[:, ::-1, :]
    return np.ascontiguousarray(np.minimum.accumulate(idx, axis=1)[:, ::-1, :])


def _prev_true(mask: Bool) -> npt.NDArray[np.int16]:
    """Per cell, the last row ``<= j`` where ``mask`` holds (-1 if none)."""
    rows = np.arange(mask.shape[1], dtype=np.int16)[None, :, None]
    return np.asarray(np.maximum.accumulate(np.where(mask, rows, np.int16(-1)), axis=1))


def _take(arr: AnyArr, i: AnyArr, j: AnyArr, k: AnyArr) -> AnyArr:
    """``arr[i, j, k]`` for a C-contiguous 3-D array (indices in range)."""
    _, nb, nc = arr.shape
    return np.asarray(arr.ravel()[(i * nb + j) * nc + k])


@dataclass
class _Scene:
    """What every orientation shares."""

    v: float
    origin: F64
    occ: Bool
    overlap: Bool  # _overlap_grids(occ)
    padded: Bool  # occ with two empty layers around
    side: Bool | None  # padded occupied voxels on the grid's side faces (None: none)
    grad: F64  # (3, R, R, R) gradient of the smoothed occupancy
    occ_centres: F64  # (M, 3) relative to the grid origin
    cand: I64  # (N, 3) voxel indices of candidate TCPs
    cand_centres: F64  # (N, 3) relative to the grid origin
    labels: npt.NDArray[np.int32]
    centroids: F64  # (n_labels + 1, 3) relative to the grid origin


@dataclass
class _Lattice:
    """The grid resampled on a lattice along one TCP orientation."""

    lo: F64
    """Centre of cell (0, 0, 0) in TCP-aligned coordinates relative to the origin."""
    q: Bool
    """Occupied when the cell's cube overlaps an occupied voxel (conservative)."""
    q_nn: Bool
    """Occupied when the cell's centre lies in an occupied voxel."""
    side: Bool | None
    """Like ``q_nn`` for the occupied voxels on the grid's side faces."""


@dataclass(frozen=True)
class _Cells:
    """The gripper's boxes as lattice offsets (inclusive ranges) for a voxel size."""

    x_pad: tuple[int, int]  # finger width
    x_clear: tuple[int, int]  # finger width plus clearance
    x_fit: tuple[int, int]  # finger width plus the fit margin
    z_contact: tuple[int, int]  # pad length: palm front to fingertip
    z_thin: tuple[int, int]  # tip part of the finger
    z_thick: tuple[int, int]  # base part, swept from the pre-grasp pose
    n_thin: int  # rows a finger tip needs at least
    n_thick: int
    palm: tuple[tuple[tuple[int, int], tuple[int, int], tuple[int, int]], ...]


class AntipodalPlanner:
    """Antipodal grasp planner on an occupancy grid (seed 001 §3.3 on voxels).

    Satisfies :class:`~heapgrasp.grasping.volumes.GraspPlanner`: :meth:`predict` maps
    the high-confidence occupancy grid (a voxel is occupied when > 0) to per-voxel grasp
    quality, TCP orientation and width; see the module docstring for the method.

    Parameters
    ----------
    max_opening
        Maximum opening of the gripper (m); every width is at most this.
    gripper
        Collision model of the hand (default: the Franka Panda hand).
    tilts
        Tilts of the approach from straight down (rad), each in ``[0, π/2)``.
    n_azimuth
        Azimuths of each non-zero tilt.
    n_yaw
        Closing directions per approach (over 180°).
    friction_angle
        Half-angle of the friction cone (rad) about the closing axis in which both
        contact normals must lie. Seed 001 asks for ≥ 150° between the normals (15°
        each); voxel normals are only good to ~10°, and the simulated friction
        coefficient of 1 allows 45°.
    table_z
        Height of the table (m, world z); everything below is occupied.
    table_clearance
        How close (m) any part of the gripper may come to the table.
    pregrasp_distance
        Distance (m) of the pre-grasp pose back along the approach; the gripper is
        swept from there to the grasp.
    opening_margin
        How much wider (m) than the planned width the executor opens the fingers
        (:func:`heapgrasp.sim.gripper.execute_grasp`: 1 cm); the fingers are checked
        where they will be.
    clearance
        Margin (m) added between the contacts and the fingers and around the gripper.
    min_depth
        Minimum engagement (m) of the object between the fingers along the approach.
    target_depth
        Engagement (m) from which the depth factor of the quality is 1.
    min_patch
        Minimum contact patch per finger (lattice cells).
    min_contact_height
        Minimum height (m, along the approach) of each contact at its extreme.
    ledge_factor
        Quality factor in [0, 1] of a grasp whose object widens just below the
        fingertips (see the module docstring).
    support_height
        Blobs whose lowest voxel is higher than this above the table (or the grid's
        bottom) are ignored as carving artefacts; None keeps everything.
    epsilon, sigma
        Post-processing these volumes are designed for (:func:`select_candidates`'s
        threshold ε and Gaussian σ in voxels): σ = 0.5 and ε = 0.4. HEAPGrasp's
        σ = 1 halves the peak of a typical grasp region (2–4 voxels thick), so no scene
        reaches ε = 0.8. ε = 0.4 was chosen on scenes the benchmark does not use
        (``heapgrasp bench grasp --seed 100 --scenes 20 --epsilon 0.05``: on no-vp
        circle grids every top candidate scoring ≥ 0.45 but one succeeded and every
        one below 0.36 failed). On the benchmark's 20 procedural 5-object piles
        (seeds 0–19) the top candidate at ε = 0.4 succeeds in 13 of 16 scenes on
        circle grids (9 of 12 at the earlier ε = 0.5) and 18 of 18 on densely carved
        grids (docs/bench_grasp.md).
    """

    name = "antipodal"

    def __init__(
        self,
        *,
        max_opening: float = 0.08,
        gripper: GripperGeometry | None = None,
        tilts: tuple[float, ...] = (0.0, math.radians(30.0)),
        n_azimuth: int = 8,
        n_yaw: int = 8,
        friction_angle: float = math.radians(35.0),
        table_z: float = 0.0,
        table_clearance: float = 0.005,
        pregrasp_distance: float = 0.05,
        opening_margin: float = 0.01,
        clearance: float = 0.003,
        min_depth: float = 0.012,
        target_depth: float = 0.022,
        min_patch: int = 2,
        min_contact_height: float = 0.0075,
        ledge_factor: float = 0.4,
        support_height: float | None = 0.015,
        epsilon: float = 0.4,
        sigma: float = 0.5,
    ) -> None:
        self.max_opening = _positive("max_opening", max_opening)
        if gripper is not None and not isinstance(gripper, GripperGeometry):
            raise ValueError(f"gripper must be a GripperGeometry, got {type(gripper).__name__}")
        self.gripper = GripperGeometry() if gripper is None else gripper
        try:
            tilt_list = tuple(float(t) for t in tilts)
        except (TypeError, ValueError):
            raise ValueError(f"tilts must be a sequence of angles, got {tilts!r}") from None
        if not tilt_list or not all(math.isfinite(t) and 0 <= t < math.pi / 2 for t in tilt_list):
            raise ValueError(f"tilts must be non-empty, each in [0, pi/2) rad, got {tilts!r}")
        self.tilts = tilt_list
        self.n_azimuth = _count("n_azimuth", n_azimuth)
        self.n_yaw = _count("n_yaw", n_yaw)
        self.min_patch = _count("min_patch", min_patch)
        fa = _finite("friction_angle", friction_angle)
        if not 0.0 < fa < math.pi / 2:
            raise ValueError(f"friction_angle must be in (0, pi/2) rad, got {friction_angle!r}")
        self.friction_angle = fa
        self.table_z = _finite("table_z", table_z)
        self.table_clearance = _non_negative("table_clearance", table_clearance)
        self.pregrasp_distance = _non_negative("pregrasp_distance", pregrasp_distance)
        self.opening_margin = _non_negative("opening_margin", opening_margin)
        self.clearance = _non_negative("clearance", clearance)
        self.min_depth = _non_negative("min_depth", min_depth)
        self.target_depth = _positive("target_depth", target_depth)
        if self.target_depth < self.min_depth:
            raise ValueError(
                f"target_depth must be >= min_depth, got {target_depth!r} < {min_depth!r}"
            )
        self.min_contact_height = _non_negative("min_contact_height", min_contact_height)
        lf = _finite("ledge_factor", ledge_factor)
        if not 0.0 <= lf <= 1.0:
            raise ValueError(f"ledge_factor must be in [0, 1], got {ledge_factor!r}")
        self.ledge_factor = lf
        self.support_height = (
            None if support_height is None else _non_negative("support_height", support_height)
        )
        eps = _finite("epsilon", epsilon)
        if not 0.0 <= eps <= 1.0:
            raise ValueError(f"epsilon must be in [0, 1], got {epsilon!r}")
        self.epsilon = eps
        self.sigma = _non_negative("sigma", sigma)
        self._rotations, self._tilt = grasp_orientations(self.tilts, self.n_azimuth, self.n_yaw)
        quats = Rotation.from_matrix(self._rotations).as_quat()
        quats[quats[:, 3] < 0] *= -1.0
        self._quats = quats.astype(np.float32)

    @property
    def rotations(self) -> F64:
        """``(K, 3, 3)`` TCP rotations searched (:func:`grasp_orientations`)."""
        return self._rotations.copy()

    def __repr__(self) -> str:
        return (
            f"AntipodalPlanner(max_opening={self.max_opening}, tilts={self.tilts}, "
            f"n_azimuth={self.n_azimuth}, n_yaw={self.n_yaw}, "
            f"friction_angle={self.friction_angle:.3f}, epsilon={self.epsilon}, "
            f"sigma={self.sigma})"
        )

    # ------------------------------------------------------------------ predict
    def predict(self, grid: F32, frame: GridFrame) -> GraspVolumes:
        """Grasp volumes of an occupancy grid.

        Parameters
        ----------
        grid
            ``(R, R, R)`` occupancy in [0, 1], indexed ``[x, y, z]``; a voxel is occupied
            when > 0 (HEAPGrasp's ``Ŝ≥λ``; unobserved voxels are 0).
        frame
            Where the grid lies; its bottom face should be at or above the table.

        Returns
        -------
        GraspVolumes
            Quality in [0, 1] (0: no grasp centred at the voxel), TCP quaternion
            ``x, y, z, w`` (TCP z = approach, fingers close along TCP y) and width (m).
        """
        r = frame.resolution
        arr = np.asarray(grid)
        if arr.shape != (r, r, r):
            raise ValueError(f"grid must have shape {(r, r, r)}, got {arr.shape}")
        if not np.isfinite(arr).all():
            raise ValueError("grid holds NaN or infinity")
        quality = np.zeros((r, r, r), dtype=np.float32)
        quats = np.zeros((r, r, r, 4), dtype=np.float32)
        quats[..., 3] = 1.0
        widths = np.zeros((r, r, r), dtype=np.float32)
        scene = self._scene(arr > 0, frame)
        if scene is not None:
            cells = self._cells(scene.v)
            best_q = np.zeros(len(scene.cand))
            best_k = np.zeros(len(scene.cand), dtype=np.int64)
            best_w = np.zeros(len(scene.cand))
            for k, rot in enumerate(self._rotations):
                idx, q, w = self._evaluate(scene, cells, rot, float(self._tilt[k]))
                better = q > best_q[idx]
                idx, q, w = idx[better], q[better], w[better]
                best_q[idx] = q
                best_k[idx] = k
                best_w[idx] = w
            keep = best_q > 0
            a, b, c = scene.cand[keep].T
            quality[a, b, c] = best_q[keep]
            quats[a, b, c] = self._quats[best_k[keep]]
            widths[a, b, c] = best_w[keep]
        return GraspVolumes(frame=frame, quality=quality, quaternions=quats, widths=widths)

    # ------------------------------------------------------------------ set-up
    def _cells(self, v: float) -> _Cells:
        g = self.gripper
        clr = self.clearance
        pre = self.pregrasp_distance
        half_w = 0.5 * g.finger_width
        x_pad = _cells(-half_w, half_w, v)
        palm = tuple(
            (
                _cells(-hx - clr, hx + clr, v),
                _cells(-hy - clr, hy + clr, v),
                _cells(z0 - clr, z1 + clr, v),
            )
            for (hx, hy), z0, z1 in (
                (g.palm_front_half, g.palm_split, g.palm_front),
                (g.palm_back_half, g.palm_back - pre, g.palm_split),
            )
        )
        return _Cells(
            x_pad=x_pad,
            x_clear=_cells(-half_w - clr, half_w + clr, v),
            x_fit=(x_pad[0] - _FIT_MARGIN, x_pad[1] + _FIT_MARGIN),
            z_contact=_cells(g.palm_front, g.finger_tip, v),
            z_thin=_cells(g.finger_split, g.finger_tip + clr, v),
            z_thick=_cells(g.finger_base - pre - clr, g.finger_split, v),
            n_thin=max(1, math.floor(g.tip_thickness / v + _EPS)),
            n_thick=max(1, math.floor(g.base_thickness / v + _EPS)),
            palm=palm,
        )

    def _scene(self, occ: Bool, frame: GridFrame) -> _Scene | None:
        v = frame.voxel_size
        r = frame.resolution
        origin = np.asarray(frame.origin, dtype=np.float64)
        full = np.ones((3, 3, 3), dtype=bool)
        labels, n = ndimage.label(occ, structure=full)
        if n == 0:
            return None
        if self.support_height is not None:
            # Objects rest on the table or on each other: a blob that does not reach
            # down to the table is a carving artefact.
            k = np.broadcast_to(np.arange(r), occ.shape)
            low = np.asarray(ndimage.minimum(k, labels, np.arange(1, n + 1)), dtype=np.float64)
            floor = max(self.table_z, float(origin[2])) + self.support_height
            keep = np.concatenate([[False], origin[2] + low * v <= floor + _EPS])
            occ = keep[labels]
            if not occ.any():
                return None
            labels, n = ndimage.label(occ, structure=full)
        # Candidate TCPs: occupied voxels and their neighbours above the table.
        near = ndimage.binary_dilation(occ, structure=full)
        z_centres = origin[2] + (np.arange(r) + 0.5) * v
        near &= (z_centres > self.table_z + self.table_clearance)[None, None, :]
        cand = np.argwhere(near)
        if len(cand) == 0:
            return None
        counts = np.bincount(labels.ravel(), minlength=n + 1).astype(np.float64)
        centroids = np.zeros((n + 1, 3))
        coord = (np.arange(r) + 0.5) * v
        for ax in range(3):
            shape = [1, 1, 1]
            shape[ax] = r
            w = np.broadcast_to(coord.reshape(shape), occ.shape)
            centroids[:, ax] = np.bincount(labels.ravel(), weights=w.ravel(), minlength=n + 1)
        centroids /= np.maximum(counts, 1.0)[:, None]
        side = occ.copy()
        side[1:-1, 1:-1, :] = False
        smooth = gaussian_filter3d(np.ascontiguousarray(occ, dtype=np.float32), 1.0)
        return _Scene(
            v=v,
            origin=origin,
            occ=occ,
            overlap=_overlap_grids(occ),
            padded=np.pad(occ, 2),
            side=np.pad(side, 2) if side.any() else None,
            grad=np.stack(list(np.gradient(smooth.astype(np.float64))), axis=0),
            occ_centres=np.asarray((np.argwhere(occ) + 0.5) * v, dtype=np.float64),
            cand=cand,
            cand_centres=np.asarray((cand + 0.5) * v, dtype=np.float64),
            labels=labels.astype(np.int32),
            centroids=centroids,
        )

    def _lattice(self, scene: _Scene, rot: F64) -> _Lattice:
        """Resamples the grid on a lattice along the TCP axes covering every occupied
        voxel and candidate."""
        v = scene.v
        r = scene.occ.shape[0]
        u_occ = scene.occ_centres @ rot
        u_cand = scene.cand_centres @ rot
        lo = np.minimum(u_occ.min(axis=0), u_cand.min(axis=0)) - v
        hi = np.maximum(u_occ.max(axis=0), u_cand.max(axis=0)) + v
        a, b, c = (int(s) for s in np.floor((hi - lo) / v + _EPS).astype(np.int64) + 1)
        axes = (lo[0] + v * np.arange(a), lo[1] + v * np.arange(b), lo[2] + v * np.arange(c))
        n = r + 4
        flat = np.zeros((a, b, c), dtype=np.int64)
        flat_nn = np.zeros((a, b, c), dtype=np.int64)
        code = np.zeros((a, b, c), dtype=np.int64)
        for w in range(3):
            # Voxel coordinate of each cell centre (voxel centres at integers).
            x = (
                (axes[0] * (rot[w, 0] / v))[:, None, None]
                + (axes[1] * (rot[w, 1] / v))[None, :, None]
                + (axes[2] * (rot[w, 2] / v) - 0.5)[None, None, :]
            )
            # The cell's cube overlaps voxels lower .. upper along this axis (one voxel
            # when it is within _ALIGN_TOL of being aligned with it).
            lower = np.floor(x + _ALIGN_TOL).astype(np.int64)
            upper = np.floor(x + (1.0 - _ALIGN_TOL)).astype(np.int64)
            flat = flat * n + np.clip(lower + 2, 0, n - 1)
            code = 2 * code + (upper - lower)
            flat_nn = flat_nn * n + np.clip(np.floor(x + 0.5).astype(np.int64) + 2, 0, n - 1)
        flat += code * n**3
        q_nn = scene.padded.ravel()[flat_nn]
        return _Lattice(
            lo=lo,
            q=scene.overlap.ravel()[flat],
            q_nn=q_nn,
            side=None if scene.side is None else scene.side.ravel()[flat_nn],
        )

    # ------------------------------------------------------------------ one orientation
    def _evaluate(
        self, scene: _Scene, cells: _Cells, rot: F64, tilt: float
    ) -> tuple[I64, F64, F64]:
        """Valid grasps of one orientation: candidate indices, quality, width."""
        g = self.gripper
        v = scene.v
        clr = self.clearance
        none = (np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0))
        lat = self._lattice(scene, rot)
        a, b, c = lat.q.shape
        ucell = (scene.cand_centres @ rot - lat.lo) / v
        cell = np.clip(np.rint(ucell).astype(np.int64), 0, np.array([a, b, c]) - 1)
        ic, jc, kc = cell.T
        dy = (ucell[:, 1] - cell[:, 1]) * v  # true TCP minus lattice cell centre, along y

        # 1. Closing region: the nearest rows on each side where a finger fits (free in
        # both finger bands over the whole sweep) bound the segment between the fingers.
        s2 = _integral_xz(lat.q)
        band_c = _band_any(s2, cells.x_pad, cells.z_contact)
        c_thin = _cumsum_j(_band_any(s2, cells.x_clear, cells.z_thin))
        c_thick = _cumsum_j(_band_any(s2, cells.x_clear, cells.z_thick))
        fit_plus = _free_from(c_thin, cells.n_thin) & _free_from(c_thick, cells.n_thick)
        fit_minus = _free_to(c_thin, cells.n_thin) & _free_to(c_thick, cells.n_thick)
        hi_row = _take(_next_true(fit_plus), ic, jc, kc).astype(np.int64) - 1
        lo_row = _take(_prev_true(fit_minus), ic, jc, kc).astype(np.int64) + 1
        hi_cl, lo_cl = np.clip(hi_row, 0, b - 1), np.clip(lo_row, 0, b - 1)
        y_hi = _take(_prev_true(band_c), ic, hi_cl, kc).astype(np.int64)
        y_lo = _take(_next_true(band_c), ic, lo_cl, kc).astype(np.int64)
        ok = (hi_row >= lo_row) & (y_hi >= lo_row) & (y_lo <= hi_row)
        # Contacts relative to the true TCP (m), at the far faces of the extreme cells;
        # the opening is symmetric about the TCP.
        e_plus = (y_hi - jc + 0.5) * v - dy
        e_minus = (jc - y_lo + 0.5) * v + dy
        width = 2.0 * (np.maximum(e_plus, e_minus) + clr)
        ok &= width <= self.max_opening + _EPS
        if lat.side is not None and lat.side.any():
            # The segment must not touch a side face of the grid: the object may be
            # wider than it looks.
            c_side = _cumsum_j(_band_any(_integral_xz(lat.side), cells.x_pad, cells.z_contact))
            lo_s, hi_s = np.clip(y_lo, 0, b), np.clip(y_hi + 1, 0, b)
            ok &= _take(c_side, ic, np.maximum(hi_s, lo_s), kc) == _take(c_side, ic, lo_s, kc)
        sel = np.flatnonzero(ok)
        if len(sel) == 0:
            return none
        ic, jc, kc, dy = ic[sel], jc[sel], kc[sel], dy[sel]
        y_hi, y_lo, hi_row, lo_row = y_hi[sel], y_lo[sel], hi_row[sel], lo_row[sel]
        e_plus, e_minus, width = e_plus[sel], e_minus[sel], width[sel]

        # 2. Collision-free approach. Fingers where the executor opens them.
        h_act = 0.5 * np.minimum(self.max_opening, width + self.opening_margin)
        ok = np.ones(len(sel), dtype=bool)
        for cum, t in ((c_thin, g.tip_thickness), (c_thick, g.base_thickness)):
            for y0, y1 in ((h_act - clr, h_act + t + clr), (-h_act - t - clr, -h_act + clr)):
                r0 = np.clip(jc + np.ceil((dy + y0) / v - _EPS).astype(np.int64), 0, b)
                r1 = np.clip(jc + np.floor((dy + y1) / v + _EPS).astype(np.int64) + 1, 0, b)
                ok &= _take(cum, ic, np.maximum(r0, r1), kc) == _take(cum, ic, r0, kc)
        # Palm, swept from the pre-grasp pose: box sums of the 3-D integral.
        s3 = np.zeros((a + 1, b + 1, c + 1), dtype=np.int32)
        np.cumsum(s2[:, :, :], axis=1, out=s3[:, 1:, :])
        for (i0, i1), (j0, j1), (k0, k1) in cells.palm:
            ia, ib = np.clip(ic + i0, 0, a), np.clip(ic + i1 + 1, 0, a)
            ja, jb = np.clip(jc + j0, 0, b), np.clip(jc + j1 + 1, 0, b)
            ka, kb = np.clip(kc + k0, 0, c), np.clip(kc + k1 + 1, 0, c)
            total = (
                _take(s3, ib, jb, kb)
                - _take(s3, ia, jb, kb)
                - _take(s3, ib, ja, kb)
                - _take(s3, ib, jb, ka)
                + _take(s3, ia, ja, kb)
                + _take(s3, ia, jb, ka)
                + _take(s3, ib, ja, ka)
                - _take(s3, ia, ja, ka)
            )
            ok &= total == 0
        # Table: the lowest point of every swept box.
        pz = scene.origin[2] + scene.cand_centres[sel, 2]
        rz = rot[2]
        pre = self.pregrasp_distance
        half_w = 0.5 * g.finger_width
        low_x = -abs(rz[0]) * half_w
        for t, z0, z1 in (
            (g.tip_thickness, g.finger_split - pre, g.finger_tip),
            (g.base_thickness, g.finger_base - pre, g.finger_split),
        ):
            low_z = min(rz[2] * z0, rz[2] * z1)
            for y0, y1 in ((h_act, h_act + t), (-h_act - t, -h_act)):
                low_y = np.minimum(rz[1] * y0, rz[1] * y1)
                ok &= pz + low_x + low_y + low_z >= self.table_z + self.table_clearance
        for (hx, hy), z0, z1 in (
            (g.palm_front_half, g.palm_split, g.palm_front),
            (g.palm_back_half, g.palm_back - pre, g.palm_split),
        ):
            low = -abs(rz[0]) * hx - abs(rz[1]) * hy + min(rz[2] * z0, rz[2] * z1)
            ok &= pz + low >= self.table_z + self.table_clearance
        keep = np.flatnonzero(ok)
        if len(keep) == 0:
            return none
        sel = sel[keep]
        ic, jc, kc = ic[keep], jc[keep], kc[keep]
        hi_row, lo_row = hi_row[keep], lo_row[keep]
        e_plus, e_minus, width, h_act = e_plus[keep], e_minus[keep], width[keep], h_act[keep]
        q, ok = self._contacts(scene, cells, lat, rot, tilt, ic, jc, kc, hi_row, lo_row, h_act)
        q *= _ramp(0.5 * np.abs(e_plus - e_minus), 0.5 * v, 0.02, 1.0, 0.85)  # centring
        return sel[ok], q[ok], width[ok]

    def _contacts(
        self,
        scene: _Scene,
        cells: _Cells,
        lat: _Lattice,
        rot: F64,
        tilt: float,
        ic: I64,
        jc: I64,
        kc: I64,
        hi_row: I64,
        lo_row: I64,
        h_act: F64,
    ) -> tuple[F64, Bool]:
        """Contact geometry on the nearest-voxel lattice (the conservative one blurs flat
        tops and faces by half a voxel): validity and quality without centring."""
        v = scene.v
        g = self.gripper
        a, b, c = lat.q_nn.shape
        m = len(ic)
        q_nn = lat.q_nn
        band_c = _band_any(_integral_xz(q_nn), cells.x_pad, cells.z_contact)
        y_hi = _take(_prev_true(band_c), ic, np.clip(hi_row, 0, b - 1), kc).astype(np.int64)
        y_lo = _take(_next_true(band_c), ic, np.clip(lo_row, 0, b - 1), kc).astype(np.int64)
        ok = (y_hi >= lo_row) & (y_lo <= hi_row)
        y_hi = np.where(ok, y_hi, jc)
        y_lo = np.where(ok, y_lo, jc)

        # Engagement: levels of the pad holding object between the contacts.
        s1 = np.zeros((a + 1, b, c), dtype=np.int32)
        np.cumsum(q_nn, axis=0, dtype=np.int32, out=s1[1:])
        ia = np.arange(a)
        band_x = (
            s1[np.clip(ia + cells.x_pad[1] + 1, 0, a)] - s1[np.clip(ia + cells.x_pad[0], 0, a)]
        ) > 0
        c_x = _cumsum_j(band_x)
        dks = np.arange(cells.z_contact[0], cells.z_contact[1] + 1)
        kk = kc[:, None] + dks[None, :]
        inside_k = (kk >= 0) & (kk < c)
        kk = np.clip(kk, 0, c - 1)
        ii, hi1, lo0 = ic[:, None], np.clip(y_hi + 1, 0, b)[:, None], y_lo[:, None]
        present = _take(c_x, ii, hi1, kk) > _take(c_x, ii, lo0, kk)
        depth = (inside_k & present).sum(axis=1) * v
        ok &= depth >= self.min_depth - _EPS

        # Ledge below the fingertips, under the fingers or between them and the contacts.
        ledge = np.zeros(m, dtype=bool)
        out_rows = np.ceil((h_act + g.base_thickness) / v).astype(np.int64)
        hi_a, hi_b = np.clip(y_hi + 1, 0, b), np.clip(jc + out_rows + 1, 0, b)
        lo_a, lo_b = np.clip(jc - out_rows, 0, b), np.clip(y_lo, 0, b)
        for dk in range(cells.z_contact[1] + 1, cells.z_contact[1] + 1 + _LEDGE_LEVELS):
            k = kc + dk
            inside = (k >= 0) & (k < c)
            k = np.clip(k, 0, c - 1)
            above = _take(c_x, ic, np.maximum(hi_a, hi_b), k) > _take(c_x, ic, hi_a, k)
            below = _take(c_x, ic, np.maximum(lo_a, lo_b), k) > _take(c_x, ic, lo_a, k)
            ledge |= inside & (above | below)

        # Contact patches and normals, for both fingers at once: (m, x offsets, levels).
        dis = np.arange(cells.x_fit[0], cells.x_fit[1] + 1)
        on_pad = ((dis >= cells.x_pad[0]) & (dis <= cells.x_pad[1]))[None, :, None]
        i3 = ic[:, None, None] + dis[None, :, None]
        k3 = kc[:, None, None] + dks[None, None, :]
        shape3 = (m, len(dis), len(dks))
        inside3 = (i3 >= 0) & (i3 < a) & (k3 >= 0) & (k3 < c)
        i3 = np.broadcast_to(np.clip(i3, 0, a - 1), shape3)
        k3 = np.broadcast_to(np.clip(k3, 0, c - 1), shape3)
        di3 = np.broadcast_to(dis[None, :, None], shape3).astype(np.float64)
        dk3 = np.broadcast_to(dks[None, None, :], shape3).astype(np.float64)
        last = _prev_true(q_nn)
        first = _next_true(q_nn)
        yw, xw = rot[:, 1], rot[:, 0]
        r = scene.occ.shape[0]
        cos_side: list[F64] = []
        n_patch: list[F64] = []
        levels_side: list[F64] = []
        for sgn, ext, table in ((1, y_hi, last), (-1, y_lo, first)):
            row = _take(table, i3, ext[:, None, None], k3).astype(np.int64)
            depth_in = sgn * (row - ext[:, None, None])  # <= 0: rows inside the contact
            patch = inside3 & on_pad & (depth_in >= -1)
            n_patch.append(patch.sum(axis=(1, 2)).astype(np.float64))
            levels_side.append(
                (inside3 & on_pad & (depth_in == 0)).any(axis=1).sum(axis=1).astype(np.float64)
            )
            # Tilt along the approach (and across): plane fitted to the extremes.
            wgt = (inside3 & (depth_in >= -_FIT_ROWS)).astype(np.float64)
            rr = depth_in * wgt
            sw, sx, sz = wgt.sum((1, 2)), (di3 * wgt).sum((1, 2)), (dk3 * wgt).sum((1, 2))
            sxx, szz = (di3 * di3 * wgt).sum((1, 2)), (dk3 * dk3 * wgt).sum((1, 2))
            sxz = (di3 * dk3 * wgt).sum((1, 2))
            mat = np.empty((m, 3, 3))
            mat[:, 0] = np.stack([sw + 1e-9, sx, sz], axis=1)
            mat[:, 1] = np.stack([sx, sxx + _RIDGE, sxz], axis=1)
            mat[:, 2] = np.stack([sz, sxz, szz + _RIDGE], axis=1)
            rhs = np.stack([rr.sum((1, 2)), (di3 * rr).sum((1, 2)), (dk3 * rr).sum((1, 2))], 1)
            coef = np.linalg.solve(mat, rhs[:, :, None])[:, :, 0]
            # Tilt across the finger: summed occupancy gradients on the patch (the fit
            # cannot see it on a patch one column wide, e.g. at a corner).
            h = np.nonzero(patch)
            u = lat.lo + v * np.stack([i3[h], row[h], k3[h]], axis=1).astype(np.float64)
            vox = np.clip(np.floor((u @ rot.T) / v).astype(np.int64), 0, r - 1)
            grads = scene.grad[:, vox[:, 0], vox[:, 1], vox[:, 2]].T
            gsum = np.zeros((m, 3))
            np.add.at(gsum, h[0], grads)
            tan_x = np.abs(gsum @ xw) / np.maximum(np.abs(gsum @ yw), 1e-12)
            tan_x = np.maximum(tan_x, np.abs(coef[:, 1]))
            cos_side.append(1.0 / np.sqrt(1.0 + tan_x**2 + coef[:, 2] ** 2))
        ok &= np.minimum(n_patch[0], n_patch[1]) >= self.min_patch
        min_levels = max(1, round(self.min_contact_height / v))
        ok &= np.minimum(levels_side[0], levels_side[1]) >= min_levels
        cos_min = np.minimum(cos_side[0], cos_side[1])
        ok &= cos_min >= math.cos(self.friction_angle) - 1e-12

        # Quality: 1 for a clean grasp; minor weaknesses cost a few percent, risky ones
        # (shallow, above a ledge, contacts one voxel high) more.
        cone = self.friction_angle
        ang = np.arccos(np.clip(cos_min, -1.0, 1.0))
        q = _ramp(ang, 0.3 * cone, cone, 1.0, 0.85)
        q *= _ramp(depth, self.min_depth, self.target_depth, 0.7, 1.0)
        q *= _ramp(np.minimum(n_patch[0], n_patch[1]), self.min_patch, self.min_patch + 2, 0.9, 1)
        q *= np.where(np.minimum(levels_side[0], levels_side[1]) >= _FLAT_LEVELS, 1.0, 0.85)
        q *= np.where(ledge, self.ledge_factor, 1.0)
        q *= 1.0 - 0.1 * min(tilt / (math.pi / 4), 1.0)
        # Closing line near the centroid of the grasped blob (seed 001: line of gravity).
        mid = np.stack([ic, (y_hi + y_lo) // 2, kc], axis=1).astype(np.float64)
        vox = np.clip(np.floor(((lat.lo + v * mid) @ rot.T) / v).astype(np.int64), 0, r - 1)
        lab = scene.labels[vox[:, 0], vox[:, 1], vox[:, 2]]
        to_c = scene.centroids[lab] - (lat.lo + v * np.stack([ic, jc, kc], 1)) @ rot.T
        dist = np.linalg.norm(to_c - (to_c @ yw)[:, None] * yw[None, :], axis=1)
        q *= np.where(lab > 0, _ramp(dist, 0.03, 0.08, 1.0, 0.9), 0.9)
        return np.clip(q, 0.0, 1.0), ok
