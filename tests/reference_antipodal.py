"""NumPy reference of the antipodal planner's per-orientation search.

This is the planner's original NumPy implementation (heapgrasp.planning.antipodal before
the search moved to the Rust core, ``heapgrasp._core.antipodal_grasps``), kept as the
test oracle. The only changes: matrix products are written as explicit sums of products
(in the order the core evaluates them) and the 3 x 3 solve is plain Gaussian elimination
with partial pivoting, so that ties (cells exactly half-way between two voxels, which
the 30° tilts make common) are decided by the same floating-point operations on both
sides and the two agree bit for bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import numpy as np
import numpy.typing as npt
from heapgrasp.planning.antipodal import _EPS

F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]
Bool = npt.NDArray[np.bool_]
AnyArr = npt.NDArray[Any]

#: A lattice cell closer than this (in voxels, per axis) to a voxel centre overlaps
#: that voxel only.
_ALIGN_TOL = 0.05
#: Ridge (cells²) on the slopes of the contact-plane fit: a patch one voxel high is
#: taken as parallel to the approach.
_RIDGE = 1.0
#: The plane is fitted over the columns whose extreme lies within this many cells.
_FIT_ROWS = 3
#: Levels below the fingertips searched for a ledge.
_LEDGE_LEVELS = 2
#: Contact levels (cells along the approach at the extreme) of a flat contact.
_FLAT_LEVELS = 2


def _ramp(x: npt.ArrayLike, x0: float, x1: float, y0: float, y1: float) -> F64:
    """``y0`` up to ``x0``, ``y1`` from ``x1``, linear in between."""
    t = np.clip((np.asarray(x, dtype=np.float64) - x0) / max(x1 - x0, 1e-12), 0.0, 1.0)
    return np.asarray(y0 + (y1 - y0) * t)


def _tcp(p: F64, rot: F64) -> F64:
    """``p @ rot`` as ``(p0 r0j + p1 r1j) + p2 r2j``."""
    p = np.asarray(p, dtype=np.float64)
    return p[..., 0:1] * rot[0] + p[..., 1:2] * rot[1] + p[..., 2:3] * rot[2]


def _grid(u: F64, rot: F64) -> F64:
    """``u @ rot.T`` as ``(u0 rw0 + u1 rw1) + u2 rw2``."""
    u = np.asarray(u, dtype=np.float64)
    return u[..., 0:1] * rot[:, 0] + u[..., 1:2] * rot[:, 1] + u[..., 2:3] * rot[:, 2]


def _dot(g: F64, w: F64) -> F64:
    return g[:, 0] * w[0] + g[:, 1] * w[1] + g[:, 2] * w[2]


def _solve3(mat: F64, rhs: F64) -> F64:
    """Batched 3 x 3 solve: Gaussian elimination with partial pivoting (first maximum)."""
    m = mat.copy()
    b = rhs.copy()
    n = len(m)
    rows = np.arange(n)
    for col in range(3):
        piv = col + np.argmax(np.abs(m[:, col:, col]), axis=1)
        for arr in (m, b):
            top = arr[rows, col].copy()
            arr[rows, col] = arr[rows, piv]
            arr[rows, piv] = top
        inv = 1.0 / m[:, col, col]
        for row in range(col + 1, 3):
            lam = m[:, row, col] * inv
            for k in range(col, 3):
                m[:, row, k] -= lam * m[:, col, k]
            b[:, row] -= lam * b[:, col]
    x = np.zeros((n, 3))
    for row in (2, 1, 0):
        s = b[:, row].copy()
        for k in range(row + 1, 3):
            s -= m[:, row, k] * x[:, k]
        x[:, row] = s / m[:, row, row]
    return x


#: The contact plane is fitted on the pad widened by this many cells.
_FIT_MARGIN = 1


def _cells(lo: float, hi: float, v: float) -> tuple[int, int]:
    """Lattice offsets (inclusive range) whose cell centre lies in ``[lo, hi]``."""
    return math.ceil(lo / v - _EPS), math.floor(hi / v + _EPS)


@dataclass(frozen=True)
class Cells:
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


def cells(pl: Any, v: float) -> Cells:
    """The gripper's boxes in lattice cells (the core's ``GripperCells::from_params``)."""
    g = pl.gripper
    clr = pl.clearance
    pre = pl.pregrasp_distance
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
    return Cells(
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


def search(pl: Any, scene: Any) -> tuple[F64, I64, F64]:
    """Every orientation of ``pl`` at every candidate of ``scene`` (the planner's
    ``_scene``): each candidate's best quality, orientation and width."""
    cells_ = cells(pl, scene.v)
    occ = scene.occ
    side = occ.copy()
    side[1:-1, 1:-1, :] = False
    scene = SimpleNamespace(
        **vars(scene),
        overlap=_overlap_grids(occ),
        padded=np.pad(occ, 2),
        side=np.pad(side, 2) if side.any() else None,
        occ_centres=np.asarray((np.argwhere(occ) + 0.5) * scene.v, dtype=np.float64),
        cand_centres=np.asarray((scene.cand + 0.5) * scene.v, dtype=np.float64),
    )
    best_q = np.zeros(len(scene.cand))
    best_k = np.zeros(len(scene.cand), dtype=np.int64)
    best_w = np.zeros(len(scene.cand))
    for k, rot in enumerate(pl.rotations):
        idx, q, w = evaluate(pl, scene, cells_, rot, float(pl._tilt[k]))
        better = q > best_q[idx]
        idx, q, w = idx[better], q[better], w[better]
        best_q[idx] = q
        best_k[idx] = k
        best_w[idx] = w
    return best_q, best_k, best_w


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
class Lattice:
    """The grid resampled on a lattice along one TCP orientation."""

    lo: F64
    q: Bool
    q_nn: Bool
    side: Bool | None


def lattice(pl: Any, scene: Any, rot: F64) -> Lattice:
    """Resamples the grid on a lattice along the TCP axes covering every occupied
    voxel and candidate."""
    v = scene.v
    r = scene.occ.shape[0]
    u_occ = _tcp(scene.occ_centres, rot)
    u_cand = _tcp(scene.cand_centres, rot)
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
    return Lattice(
        lo=lo,
        q=scene.overlap.ravel()[flat],
        q_nn=q_nn,
        side=None if scene.side is None else scene.side.ravel()[flat_nn],
    )


def evaluate(pl: Any, scene: Any, cells: Any, rot: F64, tilt: float) -> tuple[I64, F64, F64]:
    """Valid grasps of one orientation: candidate indices, quality, width."""
    g = pl.gripper
    v = scene.v
    clr = pl.clearance
    none = (np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0))
    lat = lattice(pl, scene, rot)
    a, b, c = lat.q.shape
    ucell = (_tcp(scene.cand_centres, rot) - lat.lo) / v
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
    ok &= width <= pl.max_opening + _EPS
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
    h_act = 0.5 * np.minimum(pl.max_opening, width + pl.opening_margin)
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
    pre = pl.pregrasp_distance
    half_w = 0.5 * g.finger_width
    low_x = -abs(rz[0]) * half_w
    for t, z0, z1 in (
        (g.tip_thickness, g.finger_split - pre, g.finger_tip),
        (g.base_thickness, g.finger_base - pre, g.finger_split),
    ):
        low_z = min(rz[2] * z0, rz[2] * z1)
        for y0, y1 in ((h_act, h_act + t), (-h_act - t, -h_act)):
            low_y = np.minimum(rz[1] * y0, rz[1] * y1)
            ok &= pz + low_x + low_y + low_z >= pl.table_z + pl.table_clearance
    for (hx, hy), z0, z1 in (
        (g.palm_front_half, g.palm_split, g.palm_front),
        (g.palm_back_half, g.palm_back - pre, g.palm_split),
    ):
        low = -abs(rz[0]) * hx - abs(rz[1]) * hy + min(rz[2] * z0, rz[2] * z1)
        ok &= pz + low >= pl.table_z + pl.table_clearance
    keep = np.flatnonzero(ok)
    if len(keep) == 0:
        return none
    sel = sel[keep]
    ic, jc, kc = ic[keep], jc[keep], kc[keep]
    hi_row, lo_row = hi_row[keep], lo_row[keep]
    e_plus, e_minus, width, h_act = e_plus[keep], e_minus[keep], width[keep], h_act[keep]
    q, ok = contacts(pl, scene, cells, lat, rot, tilt, ic, jc, kc, hi_row, lo_row, h_act)
    q *= _ramp(0.5 * np.abs(e_plus - e_minus), 0.5 * v, 0.02, 1.0, 0.85)  # centring
    return sel[ok], q[ok], width[ok]


def contacts(
    pl: Any,
    scene: Any,
    cells: Any,
    lat: Lattice,
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
    g = pl.gripper
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
    ok &= depth >= pl.min_depth - _EPS

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
        coef = _solve3(mat, rhs)
        # Tilt across the finger: summed occupancy gradients on the patch (the fit
        # cannot see it on a patch one column wide, e.g. at a corner).
        h = np.nonzero(patch)
        u = lat.lo + v * np.stack([i3[h], row[h], k3[h]], axis=1).astype(np.float64)
        vox = np.clip(np.floor(_grid(u, rot) / v).astype(np.int64), 0, r - 1)
        grads = scene.grad[:, vox[:, 0], vox[:, 1], vox[:, 2]].T
        gsum = np.zeros((m, 3))
        np.add.at(gsum, h[0], grads)
        tan_x = np.abs(_dot(gsum, xw)) / np.maximum(np.abs(_dot(gsum, yw)), 1e-12)
        tan_x = np.maximum(tan_x, np.abs(coef[:, 1]))
        cos_side.append(1.0 / np.sqrt(1.0 + tan_x**2 + coef[:, 2] ** 2))
    ok &= np.minimum(n_patch[0], n_patch[1]) >= pl.min_patch
    min_levels = max(1, round(pl.min_contact_height / v))
    ok &= np.minimum(levels_side[0], levels_side[1]) >= min_levels
    cos_min = np.minimum(cos_side[0], cos_side[1])
    ok &= cos_min >= math.cos(pl.friction_angle) - 1e-12

    # Quality: 1 for a clean grasp; minor weaknesses cost a few percent, risky ones
    # (shallow, above a ledge, contacts one voxel high) more.
    cone = pl.friction_angle
    # math.acos (the C library's, as the core's f64::acos), not NumPy's SIMD arccos,
    # which may differ in the last bit.
    ang = np.array([math.acos(c) for c in np.clip(cos_min, -1.0, 1.0)], dtype=np.float64)
    q = _ramp(ang, 0.3 * cone, cone, 1.0, 0.85)
    q *= _ramp(depth, pl.min_depth, pl.target_depth, 0.7, 1.0)
    q *= _ramp(np.minimum(n_patch[0], n_patch[1]), pl.min_patch, pl.min_patch + 2, 0.9, 1)
    q *= np.where(np.minimum(levels_side[0], levels_side[1]) >= _FLAT_LEVELS, 1.0, 0.85)
    q *= np.where(ledge, pl.ledge_factor, 1.0)
    q *= 1.0 - 0.1 * min(tilt / (math.pi / 4), 1.0)
    # Closing line near the centroid of the grasped blob (seed 001: line of gravity).
    mid = np.stack([ic, (y_hi + y_lo) // 2, kc], axis=1).astype(np.float64)
    vox = np.clip(np.floor(_grid(lat.lo + v * mid, rot) / v).astype(np.int64), 0, r - 1)
    lab = scene.labels[vox[:, 0], vox[:, 1], vox[:, 2]]
    to_c = scene.centroids[lab] - _grid(lat.lo + v * np.stack([ic, jc, kc], 1), rot)
    off = to_c - _dot(to_c, yw)[:, None] * yw[None, :]
    dist = np.sqrt(off[:, 0] * off[:, 0] + off[:, 1] * off[:, 1] + off[:, 2] * off[:, 2])
    q *= np.where(lab > 0, _ramp(dist, 0.03, 0.08, 1.0, 0.9), 0.9)
    return np.clip(q, 0.0, 1.0), ok
