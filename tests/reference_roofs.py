"""NumPy reference of the silhouette check (``heapgrasp.perception.roofs.keep_silhouettes``).

This is the check's original NumPy implementation, from before it moved to the Rust
core (``heapgrasp._core.keep_silhouettes``), kept as the test oracle. The core does the
same floating-point operations per voxel, except for the camera transform (here a
LAPACK inverse and a BLAS product, there ``Rᵀ`` and ``-Rᵀt`` with plain sums), which may
differ in the last bit; the two agree voxel for voxel unless a box edge lies within an
ulp of a pixel boundary.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
from heapgrasp.perception.roofs import SilhouetteView
from scipy import ndimage

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]


def _footprints(
    centres: F64, view: SilhouetteView, voxel_size: float
) -> tuple[I64, I64, I64, I64, npt.NDArray[np.bool_]]:
    """Pixel boxes ``[u0, u1] x [v0, v1]`` (inclusive, clipped to the image) holding the
    projection of each voxel's circumscribed sphere, and whether any pixel is in it."""
    cam = view.camera
    world2cam = np.linalg.inv(view.cam2world)
    p = centres @ world2cam[:3, :3].T + world2cam[:3, 3]
    z = p[:, 2]
    front = z > 1e-3
    zs = np.where(front, z, 1.0)
    u, v = cam.fx * p[:, 0] / zs + cam.cx, cam.fy * p[:, 1] / zs + cam.cy
    half = 0.5 * math.sqrt(3.0) * voxel_size / zs
    ru, rv = cam.fx * half, cam.fy * half
    u0 = np.clip(np.ceil(u - ru - 0.5), 0, cam.width).astype(np.int64)
    u1 = np.clip(np.floor(u + ru + 0.5), -1, cam.width - 1).astype(np.int64)
    v0 = np.clip(np.ceil(v - rv - 0.5), 0, cam.height).astype(np.int64)
    v1 = np.clip(np.floor(v + rv + 0.5), -1, cam.height - 1).astype(np.int64)
    return u0, u1, v0, v1, front & (u1 >= u0) & (v1 >= v0)


def keep_silhouettes(
    full: npt.ArrayLike,
    trimmed: npt.ArrayLike,
    origin: npt.ArrayLike,
    voxel_size: float,
    views: Sequence[SilhouetteView],
) -> F32:
    """``heapgrasp.perception.roofs.keep_silhouettes`` as NumPy computed it (valid input only)."""
    f = np.asarray(full, dtype=np.float32)
    t = np.asarray(trimmed, dtype=np.float32)
    o = np.asarray(origin, dtype=np.float64)
    kept = t > 0
    cut = (f > 0) & ~kept
    out = t.copy()
    if not cut.any() or not views:
        return out
    kept_c = o + (np.argwhere(kept) + 0.5) * voxel_size
    cut_idx = np.argwhere(cut)
    cut_c = o + (cut_idx + 0.5) * voxel_size
    sliver = np.ones((3, 3), dtype=bool)
    unexplained: list[npt.NDArray[np.bool_]] = []
    cut_boxes = []
    for view in views:
        h, w = view.mask.shape
        covered = _paint(np.zeros((h, w), dtype=bool), _footprints(kept_c, view, voxel_size))
        unexplained.append(ndimage.binary_opening(view.mask & ~covered, structure=sliver))
        cut_boxes.append(_footprints(cut_c, view, voxel_size))
    # Level by level from the bottom, so that a real part low down, once back, explains
    # the pixels that a roof above it would otherwise claim.
    needed = np.zeros(len(cut_idx), dtype=bool)
    for level in np.unique(cut_idx[:, 2]):
        at = np.flatnonzero(cut_idx[:, 2] == level)
        now = np.zeros(len(at), dtype=bool)
        for un, boxes in zip(unexplained, cut_boxes, strict=True):
            if un.any():
                now |= _any_in_boxes(un, boxes, at)
        if not now.any():
            continue
        needed[at[now]] = True
        back = at[now]
        for un, (u0, u1, v0, v1, ok) in zip(unexplained, cut_boxes, strict=True):
            sel = back[ok[back]]
            _paint(un, (u0[sel], u1[sel], v0[sel], v1[sel], None), value=False)
    if not needed.any():
        return out
    # Raise each column back to its highest needed voxel.
    r = f.shape[0]
    top = np.full((r, r), -1, dtype=np.int64)
    ci = cut_idx[needed]
    np.maximum.at(top, (ci[:, 0], ci[:, 1]), ci[:, 2])
    levels = np.arange(r)[None, None, :]
    back_mask = cut & (levels <= top[:, :, None])
    out[back_mask] = f[back_mask]
    return out


def _any_in_boxes(
    image: npt.NDArray[np.bool_],
    boxes: tuple[I64, I64, I64, I64, npt.NDArray[np.bool_]],
    idx: I64,
) -> npt.NDArray[np.bool_]:
    """Whether the pixel box of each voxel ``idx`` (of :func:`_footprints`) holds a set
    pixel of ``image``."""
    u0, u1, v0, v1, ok = (b[idx] for b in boxes)
    u1, v1 = np.maximum(u1, u0 - 1), np.maximum(v1, v0 - 1)  # empty boxes sum to 0
    s = np.zeros((image.shape[0] + 1, image.shape[1] + 1), dtype=np.int32)
    np.cumsum(np.cumsum(image, axis=0, dtype=np.int32), axis=1, out=s[1:, 1:])
    n = s[v1 + 1, u1 + 1] - s[v0, u1 + 1] - s[v1 + 1, u0] + s[v0, u0]
    return np.asarray(ok & (n > 0))


def _paint(
    image: npt.NDArray[np.bool_],
    boxes: tuple[I64, I64, I64, I64, npt.NDArray[np.bool_] | None],
    value: bool = True,
) -> npt.NDArray[np.bool_]:
    """Sets the pixel boxes ``[u0, u1] x [v0, v1]`` (where ``ok``) of ``image`` to
    ``value`` in place and returns it."""
    u0, u1, v0, v1, ok = boxes
    if ok is not None:
        u0, u1, v0, v1 = u0[ok], u1[ok], v0[ok], v1[ok]
    good = (u1 >= u0) & (v1 >= v0)
    u0, u1, v0, v1 = u0[good], u1[good], v0[good], v1[good]
    if len(u0) == 0:
        return image
    h, w = image.shape
    # The boxes' corners as +1/-1 in a difference image (summed with bincount, exact on
    # these small integers and much faster than np.add.at), then integrated.
    stride = w + 1
    corners = np.concatenate(
        [v0 * stride + u0, v0 * stride + u1 + 1, (v1 + 1) * stride + u0, (v1 + 1) * stride + u1 + 1]
    )
    signs = np.repeat(np.array([1.0, -1.0, -1.0, 1.0]), len(u0))
    diff = np.bincount(corners, weights=signs, minlength=(h + 1) * stride)
    diff = diff.astype(np.int64).reshape(h + 1, stride)
    hit = np.cumsum(np.cumsum(diff, axis=0), axis=1)[:h, :w] > 0
    image[hit] = value
    return image
