"""Plain NumPy references for the heapgrasp kernels.

Written from the documented semantics only (module docs of heapgrasp-core), never from
the package itself: every function here works in float64 and loops or broadcasts in the
most obvious way. Projections also report *tie* voxels: those whose f64 pixel coordinate
lies so close to a pixel border (or whose depth is so close to 0) that the kernel's f32
evaluation may legitimately pick the neighbouring pixel.
"""

from __future__ import annotations

import numpy as np

TIE_PX = 1e-3  # documented allowed error is ~1e-4 px; keep a 10x margin


# ----------------------------------------------------------------------------- poses
def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """cam2world with OpenCV axes: z toward target, x = z x up, y = z x x."""
    eye = np.asarray(eye, dtype=np.float64)
    target = np.asarray(target, dtype=np.float64)
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, np.asarray(up, dtype=np.float64))
    if np.linalg.norm(x) < 1e-9:
        x = np.cross(z, np.array([0.0, 1.0, 0.0]))
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = x, y, z, eye
    return pose


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """Uniform random rotation (QR of a Gaussian matrix, det +1)."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def pose_from(rot: np.ndarray, trans) -> np.ndarray:
    p = np.eye(4)
    p[:3, :3] = rot
    p[:3, 3] = trans
    return p


def world2cam(cam2world: np.ndarray) -> np.ndarray:
    r = cam2world[:3, :3]
    t = cam2world[:3, 3]
    out = np.eye(4)
    out[:3, :3] = r.T
    out[:3, 3] = -r.T @ t
    return out


# ----------------------------------------------------------------------------- grid
def voxel_centres(origin, size: float, res: int) -> np.ndarray:
    """(R, R, R, 3) world coordinates of voxel centres, indexed [a, b, c]."""
    h = size / res
    idx = (np.arange(res, dtype=np.float64) + 0.5) * h
    o = np.asarray(origin, dtype=np.float64)
    a, b, c = np.meshgrid(idx + o[0], idx + o[1], idx + o[2], indexing="ij")
    return np.stack([a, b, c], axis=-1)


def _near_int(f: np.ndarray, tol: np.ndarray) -> np.ndarray:
    return np.abs(f - np.round(f)) <= tol


def project(points: np.ndarray, cam, cam2world: np.ndarray):
    """Projects world points (..., 3) into ``cam``.

    Returns ``(u, v, inside, tie, z)``: integer pixel indices (valid where inside), the
    inside-image flag, the border-tie flag and the camera-frame depth.
    """
    w2c = world2cam(cam2world)
    p = points @ w2c[:3, :3].T + w2c[:3, 3]
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        uf = cam.fx * x / z + cam.cx + 0.5
        vf = cam.fy * y / z + cam.cy + 0.5
    front = z > 0
    uf = np.where(front, uf, -1.0)
    vf = np.where(front, vf, -1.0)
    # Error budget of the f32 kernel: affine camera coordinates in f32 (absolute error
    # ~eps32 * magnitude), then the division and the f32 sum with cx.
    mag = np.abs(points - cam2world[:3, 3]).sum(axis=-1) + 1e-12
    dz = 8 * np.finfo(np.float32).eps * mag
    with np.errstate(divide="ignore", invalid="ignore"):
        zs = np.where(front, z, np.inf)
        eu = cam.fx * (dz + np.abs(x / zs) * dz) / zs + 8e-7 * np.abs(uf)
        ev = cam.fy * (dz + np.abs(y / zs) * dz) / zs + 8e-7 * np.abs(vf)
    tol_u = np.maximum(TIE_PX, 10 * eu)
    tol_v = np.maximum(TIE_PX, 10 * ev)
    u = np.floor(uf)
    v = np.floor(vf)
    inside = front & (u >= 0) & (u < cam.width) & (v >= 0) & (v < cam.height)
    tie = np.abs(z) <= 10 * dz
    tie |= front & _near_int(uf, tol_u) & (vf > -1 - tol_v) & (vf < cam.height + 1 + tol_v)
    tie |= front & _near_int(vf, tol_v) & (uf > -1 - tol_u) & (uf < cam.width + 1 + tol_u)
    u = np.where(inside, u, 0).astype(np.int64)
    v = np.where(inside, v, 0).astype(np.int64)
    return u, v, inside, tie, z


# ----------------------------------------------------------------------------- carving
def sfs_counts(origin, size, res, masks, cam, poses):
    """Reference (segmented, visible, tie) counts of Shape from Silhouette."""
    centres = voxel_centres(origin, size, res)
    seg = np.zeros((res,) * 3, dtype=np.int64)
    vis = np.zeros((res,) * 3, dtype=np.int64)
    tie = np.zeros((res,) * 3, dtype=bool)
    for mask, pose in zip(masks, poses, strict=True):
        u, v, inside, t, _ = project(centres, cam, pose)
        vis += inside
        seg += inside & (np.asarray(mask)[v, u] != 0)
        tie |= t
    return seg, vis, tie


def occupancy(seg, vis) -> np.ndarray:
    seg = np.asarray(seg)
    vis = np.asarray(vis)
    out = np.zeros(seg.shape, dtype=np.float32)
    nz = vis > 0
    out[nz] = seg[nz].astype(np.float32) / vis[nz].astype(np.float32)
    return out


def high_confidence(seg, vis, lam) -> np.ndarray:
    occ = occupancy(seg, vis)
    keep = (occ > 0) & (occ >= np.float32(lam))
    return np.where(keep, occ, np.float32(0))


# ----------------------------------------------------------------------------- TSDF
class TsdfRef:
    def __init__(self, origin, size, res, truncation):
        self.origin, self.size, self.res, self.trunc = origin, size, res, truncation
        self.values = np.zeros((res,) * 3)
        self.weights = np.zeros((res,) * 3)
        self.tie = np.zeros((res,) * 3, dtype=bool)

    def integrate(self, depth, cam, pose):
        centres = voxel_centres(self.origin, self.size, self.res)
        u, v, inside, tie, z = project(centres, cam, pose)
        d = np.asarray(depth, dtype=np.float64)[v, u]
        with np.errstate(invalid="ignore"):
            ok = inside & np.isfinite(d) & (d > 0)
            sdf = d - z
            ok &= sdf >= -self.trunc
        obs = np.minimum(1.0, sdf / self.trunc)
        new_w = self.weights + 1
        self.values = np.where(ok, (self.values * self.weights + obs) / new_w, self.values)
        self.weights = np.where(ok, new_w, self.weights)
        self.tie |= tie


# ----------------------------------------------------------------------------- meshes
def box_mesh(half_extents) -> tuple[np.ndarray, np.ndarray]:
    """Closed, outward-oriented box centred on the origin (8 vertices, 12 triangles)."""
    hx, hy, hz = half_extents
    v = np.array(
        [[sx * hx, sy * hy, sz * hz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)],
        dtype=np.float64,
    )
    # vertex index = 4*ix + 2*iy + iz
    quads = [
        (0, 1, 3, 2),  # -x
        (4, 6, 7, 5),  # +x
        (0, 4, 5, 1),  # -y
        (2, 3, 7, 6),  # +y
        (0, 2, 6, 4),  # -z
        (1, 5, 7, 3),  # +z
    ]
    f = []
    for a, b, c, d in quads:
        f += [(a, b, c), (a, c, d)]
    return v, np.array(f, dtype=np.int64)


def render_bruteforce(meshes, cam, cam2world, eps=1e-9):
    """Moller-Trumbore over every triangle for every pixel-centre ray.

    ``meshes``: list of ``(id, vertices, faces, obj2world)``. Returns
    ``(mask, depth (f64, 0 = none), labels, tie)``, where ``tie`` flags pixels whose ray
    passes within ``eps`` (barycentric) of a triangle edge or whose two nearest hits of
    different meshes are within ``eps`` in depth.
    """
    w2c = world2cam(cam2world)
    h, w = cam.height, cam.width
    vv, uu = np.meshgrid(
        np.arange(h, dtype=np.float64), np.arange(w, dtype=np.float64), indexing="ij"
    )
    d = np.stack([(uu - cam.cx) / cam.fx, (vv - cam.cy) / cam.fy, np.ones_like(uu)], -1)
    d = d.reshape(-1, 1, 3)
    best = np.full(h * w, np.inf)
    labels = np.zeros(h * w, dtype=np.uint32)
    tie = np.zeros(h * w, dtype=bool)
    for mid, verts, faces, o2w in meshes:
        m = w2c @ o2w
        vc = verts @ m[:3, :3].T + m[:3, 3]
        tri = vc[faces]  # (F, 3, 3)
        v0, e1, e2 = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
        pvec = np.cross(d, e2[None])  # (P, F, 3)
        det = np.einsum("fk,pfk->pf", e1, pvec)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            tvec = -v0[None]  # ray origin is the camera centre (0, 0, 0)
            a = np.einsum("pfk,pfk->pf", np.broadcast_to(tvec, pvec.shape), pvec) * inv
            qvec = np.cross(np.broadcast_to(tvec, pvec.shape), e1[None])
            b = np.einsum("pfk,pfk->pf", np.broadcast_to(d, qvec.shape), qvec) * inv
            t = np.einsum("fk,pfk->pf", e2, qvec) * inv
        valid = det != 0
        hit = valid & (a >= 0) & (b >= 0) & (a + b <= 1) & (t > 0)
        near_edge = (
            valid
            & (t > 0)
            & ((np.abs(a) <= eps) | (np.abs(b) <= eps) | (np.abs(a + b - 1) <= eps))
            & (a >= -eps)
            & (b >= -eps)
            & (a + b <= 1 + eps)
        )
        tie |= near_edge.any(axis=1)
        tz = np.where(hit, t, np.inf).min(axis=1)  # d_z = 1 so t is the camera z
        closer = tz < best
        with np.errstate(invalid="ignore"):
            tie |= np.isfinite(tz) & (np.abs(tz - best) <= eps)
        labels = np.where(closer, np.uint32(mid), labels)
        best = np.minimum(best, tz)
    mask = np.isfinite(best)
    depth = np.where(mask, best, 0.0)
    return (mask.reshape(h, w), depth.reshape(h, w), labels.reshape(h, w), tie.reshape(h, w))


# ----------------------------------------------------------------------------- filters
def gaussian_kernel(sigma: float) -> np.ndarray:
    r = int(4.0 * sigma + 0.5)
    k = np.arange(-r, r + 1, dtype=np.float64)
    w = np.exp(-0.5 / sigma**2 * k**2)
    return w / w.sum()


def gaussian_filter3d(volume: np.ndarray, sigma: float) -> np.ndarray:
    """Separable Gaussian, mode nearest, f64 sums rounded to f32 after each pass."""
    out = np.asarray(volume, dtype=np.float32).copy()
    if sigma <= 1e-15:
        return out
    w = gaussian_kernel(sigma)
    r = (len(w) - 1) // 2
    n = out.shape[0]
    for axis in range(3):
        pad = [(0, 0)] * 3
        pad[axis] = (r, r)
        p = np.pad(out.astype(np.float64), pad, mode="edge")
        acc = np.zeros(out.shape, dtype=np.float64)
        for j, wj in enumerate(w):
            sl = [slice(None)] * 3
            sl[axis] = slice(j, j + n)
            acc += wj * p[tuple(sl)]
        out = acc.astype(np.float32)
    return out


def maximum_filter3d(volume: np.ndarray, window: int) -> np.ndarray:
    """Max over offsets [-(w//2), w-1-w//2] per axis, clipped to the grid (NaN ignored)."""
    vol = np.asarray(volume, dtype=np.float32)
    n = vol.shape[0]
    lo, hi = window // 2, window - 1 - window // 2
    out = np.full(vol.shape, np.nan, dtype=np.float32)
    for a in range(n):
        for b in range(n):
            for c in range(n):
                blk = vol[
                    max(0, a - lo) : a + hi + 1,
                    max(0, b - lo) : b + hi + 1,
                    max(0, c - lo) : c + hi + 1,
                ]
                blk = blk[~np.isnan(blk)]
                if blk.size:
                    out[a, b, c] = blk.max()
    return out


def nms3d(volume: np.ndarray, threshold: float, window: int) -> np.ndarray:
    vol = np.asarray(volume, dtype=np.float32)
    mx = maximum_filter3d(vol, window)
    with np.errstate(invalid="ignore"):
        keep = (vol >= np.float32(threshold)) & (vol == mx) & ~np.isnan(vol)
    flat = np.flatnonzero(keep.ravel())
    vals = vol.ravel()[flat].astype(np.float64)
    order = sorted(range(len(flat)), key=lambda i: (-vals[i], flat[i]))
    flat = flat[order] if len(flat) else flat
    return np.stack(np.unravel_index(flat, vol.shape), axis=-1).astype(np.int64).reshape(-1, 3)
