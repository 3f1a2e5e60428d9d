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
or a tall object standing against a lower one in a merged hull. A planner then sees free
space there, so a grasp near it may touch it on the way in.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from scipy import ndimage

__all__ = ["column_heights", "trim_roofs"]

F32 = npt.NDArray[np.float32]
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
