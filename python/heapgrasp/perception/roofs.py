"""Trimming the roofs that Shape from Silhouette leaves on objects seen from above.

Every HEAPGrasp view lies within θ_max = π/5 of the vertical (Table I), so the visual
hull of eq. 10 over-estimates heights: above an object of width ``w`` seen from one side
at tilt θ the hull rises up to ``w / tan θ`` (1.4 ``w`` at 36°), a wedge; seen from all
around, a tent or cone of up to ``w / (2 tan θ)`` (0.7 ``w``). A grasp planned on that
roof closes above the object, and the hand's palm, kept clear of the roof, cannot lower
the 4.6 cm fingers onto it. Silhouettes alone cannot tell a roof from a real top; the
paper's grasp network learns it from training on such hulls (§V). The analytic planner
gets this prior instead: real tops are flat where the hull's roofs are peaked.

:func:`trim_roofs` opens the hull's height map (the top of each occupied column) with a
disc of radius ρ, counting only occupied columns: a column is lowered to the highest
level that a disc of occupied columns containing it reaches everywhere. A roof's ridge
is lowered toward its eaves, which lie at the real top; a flat top at least as wide as
the disc stays; an object narrower than the disc keeps its height, because the empty
columns beside it do not count (a plain grey opening would erase it). What it can cut
is real and higher than its surroundings and narrower than the disc: a bottle's neck,
a bowl's rim, the raised edge of a tilted object, a tall object standing against a lower
one in a merged hull, an object's edge beside the low skirt that carving leaves around
it. A planner would see free space there, and a grasp near it would touch it on the way
in.

:func:`keep_silhouettes` puts such parts back. The silhouettes cannot say which hull
voxels are real, but they do say what must be: every pixel of a mask is a ray that hits
an object. A roof is explained away, because the rays through it go on to hit the
object under it; a real part that was cut leaves pixels of some silhouette that nothing
left in the grid covers. Cut voxels are restored level by level from the bottom, those
whose projection holds such a pixel, so that a real part low down, once back, explains
the pixels a roof above it would otherwise claim.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy import ndimage

from heapgrasp import PinholeCamera
from heapgrasp._core import keep_silhouettes as _core_keep_silhouettes

__all__ = ["SilhouetteView", "column_heights", "keep_silhouettes", "trim_roofs"]

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]


def column_heights(occupied: npt.NDArray[np.bool_]) -> I64:
    """``(R, R)`` number of layers up to the top occupied voxel of each column of an
    ``[x, y, z]`` volume (0 for an empty column)."""
    occ = np.asarray(occupied, dtype=bool)
    if occ.ndim != 3:
        raise ValueError(f"occupied must be a 3-D [x, y, z] volume, got shape {occ.shape}")
    levels = np.arange(1, occ.shape[2] + 1, dtype=np.int64)
    return np.asarray(np.max(np.where(occ, levels, 0), axis=2, initial=0))


def trim_roofs(grid: npt.ArrayLike, voxel_size: float, radius: float) -> F32:
    """The high-confidence grid with its roofs trimmed (see the module docstring).

    Parameters
    ----------
    grid
        ``(R, R, R)`` occupancy indexed ``[x, y, z]`` (z up; a voxel is occupied when > 0),
        e.g. ``Ŝ≥λ``.
    voxel_size
        Edge of a voxel (m).
    radius
        Radius ρ of the disc (m); a disc under one voxel leaves the grid as it is.

    Returns
    -------
    numpy.ndarray
        float32 copy of ``grid`` with the voxels above each column's trimmed height set
        to 0.
    """
    g = np.asarray(grid, dtype=np.float32)
    if g.ndim != 3 or len(set(g.shape)) != 1:
        raise ValueError(f"grid must be a cubic (R, R, R) volume, got shape {g.shape}")
    if not np.isfinite(g).all():
        raise ValueError("grid holds NaN or infinity")
    if not (math.isfinite(voxel_size) and voxel_size > 0):
        raise ValueError(f"voxel_size must be > 0, got {voxel_size!r}")
    if not (math.isfinite(radius) and radius >= 0):
        raise ValueError(f"radius must be >= 0, got {radius!r}")
    k = round(radius / voxel_size)
    if k < 1:
        return g.copy()
    heights = column_heights(g > 0)
    occupied = heights > 0
    yy, xx = np.mgrid[-k : k + 1, -k : k + 1]
    disc = xx * xx + yy * yy <= k * k
    # Empty columns do not bound the erosion: a narrow object keeps its height.
    above_all = g.shape[2] + 1
    eroded = ndimage.grey_erosion(
        np.where(occupied, heights, above_all), footprint=disc, mode="nearest"
    )
    eroded = np.where(occupied, eroded, 0)
    opened = ndimage.grey_dilation(eroded, footprint=disc, mode="nearest")
    cap = np.minimum(heights, opened)
    keep = np.arange(g.shape[2])[None, None, :] < cap[:, :, None]
    return np.where(keep, g, np.float32(0.0)).astype(np.float32)


@dataclass(frozen=True)
class SilhouetteView:
    """One captured silhouette: the camera, its pose and the binary mask."""

    camera: PinholeCamera
    cam2world: F64
    mask: npt.NDArray[np.bool_]

    def __post_init__(self) -> None:
        pose = np.asarray(self.cam2world, dtype=np.float64)
        if pose.shape != (4, 4) or not np.isfinite(pose).all():
            raise ValueError(f"cam2world must be a finite (4, 4) matrix, got shape {pose.shape}")
        mask = np.asarray(self.mask, dtype=bool)
        if mask.shape != (self.camera.height, self.camera.width):
            raise ValueError(
                f"mask must have shape {(self.camera.height, self.camera.width)} "
                f"(camera height, width), got {mask.shape}"
            )
        object.__setattr__(self, "cam2world", pose)
        object.__setattr__(self, "mask", mask)


def keep_silhouettes(
    full: npt.ArrayLike,
    trimmed: npt.ArrayLike,
    origin: npt.ArrayLike,
    voxel_size: float,
    views: Sequence[SilhouetteView],
) -> F32:
    """Puts back what :func:`trim_roofs` cut that a silhouette shows to be real.

    A roof is explained away: every ray through it goes on to hit the object under it.
    A real part that was cut (a bowl's rim standing up, a bottle's neck) leaves pixels
    of some silhouette that no remaining voxel covers. For every view, the pixels of
    the mask that the projections of the kept voxels do not cover (each voxel drawn as
    the box around its circumscribed sphere; slivers one or two pixels wide, which
    discretisation leaves at the silhouette's rim, are ignored) are *unexplained*. Level
    by level from the bottom, the cut voxels whose projection holds an unexplained pixel
    are needed, and the pixels they cover explained. Each column is raised back to its
    highest needed voxel.

    The check runs in the Rust core (``heapgrasp._core.keep_silhouettes``, module
    ``roofs`` of ``heapgrasp-core``) with the GIL released.

    Parameters
    ----------
    full
        ``(R, R, R)`` grid before trimming (a voxel is occupied when > 0).
    trimmed
        The same grid after :func:`trim_roofs` (a subset of ``full``).
    origin
        World position (m) of the grid's minimum corner.
    voxel_size
        Edge of a voxel (m).
    views
        The silhouettes the grid was carved from (any subset, in any order).

    Raises
    ------
    ValueError
        For volumes that are not cubic or differ in shape, a bad ``origin`` or
        ``voxel_size``; ``heapgrasp.NotRigidError`` (a ``ValueError``) for a view whose
        pose is not a rigid transform.

    Returns
    -------
    numpy.ndarray
        float32 copy of ``trimmed`` with the restored voxels of ``full``.
    """
    f = np.asarray(full, dtype=np.float32)
    t = np.asarray(trimmed, dtype=np.float32)
    if f.ndim != 3 or len(set(f.shape)) != 1 or t.shape != f.shape:
        raise ValueError(
            f"full and trimmed must be cubic (R, R, R) volumes of one shape, got {f.shape} "
            f"and {t.shape}"
        )
    o = np.asarray(origin, dtype=np.float64)
    if o.shape != (3,) or not np.isfinite(o).all():
        raise ValueError(f"origin must be 3 finite numbers, got {origin!r}")
    if not (math.isfinite(voxel_size) and voxel_size > 0):
        raise ValueError(f"voxel_size must be > 0, got {voxel_size!r}")
    out = t.copy()
    if not views:
        return out
    restored = _core_keep_silhouettes(
        f > 0,
        t > 0,
        tuple(float(x) for x in o),
        float(voxel_size),
        [v.camera for v in views],
        np.stack([v.cam2world for v in views]),
        [np.ascontiguousarray(v.mask) for v in views],
    )
    out[restored] = f[restored]
    return out
