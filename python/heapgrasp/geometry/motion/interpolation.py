"""Eq. 8's interpolation ``f(p_A, p_B)``: a great-circle arc on the view sphere, every pose
looking at the scene centre, sampled by arc length; and the rotations it slerps."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from heapgrasp._core import InvalidValueError, ShapeError
from heapgrasp.geometry.motion.sphere import ViewSphere, look_at_many
from heapgrasp.geometry.motion.validation import (
    MIN_DISTANCE,
    PARALLEL,
    FloatArray,
    as_pose,
    as_poses,
    norm,
    positive,
)


def interpolate(
    pose_a: npt.ArrayLike,
    pose_b: npt.ArrayLike,
    sphere: ViewSphere,
    *,
    step: float = 0.005,
) -> FloatArray:
    """Interpolation function ``f(p_A, p_B)`` of eq. 8 on a view sphere.

    The eye moves along the sphere surface: its direction from ``sphere.center`` is
    slerped between the two eyes (great-circle arc, the shorter one), and its distance from
    the centre is interpolated linearly (constant when both eyes are on the same sphere).
    Every pose looks at ``sphere.target`` (:func:`look_at`, up = ``+z``), i.e. the paper's
    "oriented toward the centre"; the rotations of the inputs are ignored (they already
    look at the target when made by :meth:`ViewSphere.pose`).

    Deterministic special cases: identical eyes give a single pose; eyes on the same ray
    from the centre move radially; antipodal eyes take the arc through the top of the
    sphere (toward ``+z``), or through ``+y`` when the eyes are the two poles.

    Parameters
    ----------
    pose_a, pose_b : array_like, shape (4, 4)
        Start and end ``cam2world`` poses (only their translations are used).
    sphere : ViewSphere
        Sphere whose ``center`` is the origin of the arc and whose ``target`` is looked at.
    step : float, optional
        Maximum distance (m) between consecutive eye positions, default 5 mm.

    Returns
    -------
    numpy.ndarray, shape (N, 4, 4)
        Poses from ``p_A`` to ``p_B``, both included; the first and last eye positions are
        exactly those of the inputs. ``N = 1`` when the eyes coincide.
    """
    pa = as_pose("pose_a", pose_a)
    pb = as_pose("pose_b", pose_b)
    step = positive("step", step)
    eyes = _arc_eyes(pa[:3, 3], pb[:3, 3], sphere.center_array, step)
    return look_at_many(eyes, sphere.target_array, np.array([0.0, 0.0, 1.0]))


def interpolate_sampled(
    pose_a: npt.ArrayLike,
    poses_b: npt.ArrayLike,
    sphere: ViewSphere,
    *,
    step: float,
    frames: int,
) -> list[FloatArray]:
    """:func:`interpolate` from ``pose_a`` to each of ``poses_b`` ``(N, 4, 4)``, each path
    then reduced to at most ``frames`` poses evenly spaced in arc length, the first
    (already seen) excluded and the last included: exactly the poses
    ``subsample(interpolate(a, b))`` picks, but only those are oriented, which is what
    makes scoring hundreds of hypothetical paths (eq. 14) cheap.

    All paths are built at once: NumPy over every path's eyes, with the same
    floating-point operations per eye as :func:`interpolate` and
    :func:`arc_length_samples` do for one path, so the poses are bit-identical to theirs.
    The few scalar steps of each path (its angle and number of samples, by ``math``;
    the arc-length search) stay a loop over the paths."""
    pa = as_pose("pose_a", pose_a)
    pbs = as_poses("poses_b", poses_b)
    step = positive("step", step)
    if frames < 1:
        raise InvalidValueError(f"frames: must be >= 1, got {frames}")
    eyes, counts = _arc_eyes_many(
        pa[:3, 3].copy(), np.ascontiguousarray(pbs[:, :3, 3]), sphere.center_array, step
    )
    rows, kept = _arc_length_samples_many(eyes, counts, frames)
    poses = look_at_many(
        np.ascontiguousarray(eyes[rows]), sphere.target_array, np.array([0.0, 0.0, 1.0])
    )
    ends = np.cumsum(kept).tolist()
    return [poses[a:b] for a, b in zip([0, *ends[:-1]], ends, strict=True)]


def arc_length_samples(points: npt.ArrayLike, n: int) -> npt.NDArray[np.intp]:
    """Indices of at most ``n`` of a polyline's ``(M, 3)`` points, evenly spaced in arc
    length, the first point excluded (unless it is the only one) and the last
    included."""
    pts = np.asarray(points, dtype=np.float64)
    if len(pts) <= 1:
        return np.arange(len(pts))
    arc = np.concatenate([[0.0], np.cumsum(norm(np.diff(pts, axis=0)))])
    if arc[-1] <= 0:
        return np.array([len(pts) - 1])
    want = arc[-1] * np.arange(1, n + 1) / n
    return np.unique(np.clip(np.searchsorted(arc, want - 1e-12), 1, len(pts) - 1))


def _arc_eyes(ea: FloatArray, eb: FloatArray, center: FloatArray, step: float) -> FloatArray:
    """The eye positions of :func:`interpolate` (``(N, 3)``)."""
    ea, eb = ea.copy(), eb.copy()
    if np.array_equal(ea, eb) or float(norm(eb - ea)) <= MIN_DISTANCE:
        return ea[None, :]
    da, db = ea - center, eb - center
    ra, rb = float(norm(da)), float(norm(db))
    if ra <= MIN_DISTANCE or rb <= MIN_DISTANCE:
        raise InvalidValueError("pose_a, pose_b: eyes must differ from sphere.center")
    ua, ub = da / ra, db / rb
    cos_o = float(np.dot(ua, ub))
    sin_o = float(norm(np.cross(ua, ub)))
    omega = math.atan2(sin_o, cos_o)
    if sin_o > PARALLEL:
        w = ub - cos_o * ua
        w = w / norm(w)
    elif cos_o > 0.0:  # same direction: radial motion only
        omega = 0.0
        w = np.zeros(3)
    else:  # antipodal: go over the top (+z), or through +y between the poles
        axis = np.cross(ua, np.array([0.0, 0.0, 1.0]))
        if float(norm(axis)) < PARALLEL:
            axis = np.cross(ua, np.array([0.0, 1.0, 0.0]))
        axis = axis / norm(axis)
        w = np.cross(axis, ua)
        w = w / norm(w)
        omega = math.pi

    # The speed |d eye / dt| <= sqrt(dr^2 + (r_max omega)^2), so n segments of equal dt are
    # each at most `step` long (chords are shorter than arcs).
    bound = math.hypot(rb - ra, max(ra, rb) * omega)
    n = max(1, math.ceil(bound / step))
    t = np.arange(n + 1, dtype=np.float64) / n
    dirs = np.cos(t * omega)[:, None] * ua[None, :] + np.sin(t * omega)[:, None] * w[None, :]
    radii = (1.0 - t) * ra + t * rb
    eyes = center[None, :] + radii[:, None] * dirs
    eyes[0] = ea
    eyes[-1] = eb
    return eyes


def _arc_eyes_many(
    ea: FloatArray, ebs: FloatArray, center: FloatArray, step: float
) -> tuple[FloatArray, npt.NDArray[np.intp]]:
    """:func:`_arc_eyes` from ``ea`` to every row of ``ebs`` ``(G, 3)`` at once: the
    paths' eyes back to back ``(sum(counts), 3)`` and the number of eyes of each path.
    Every array operation is the one :func:`_arc_eyes` does, element by element (so the
    eyes are bit-identical); the scalar ones stay per path."""
    g = ebs.shape[0]
    # Identical eyes: a single eye, the start.
    moving = ~(np.all(ebs == ea[None, :], axis=1) | (norm(ebs - ea[None, :]) <= MIN_DISTANCE))
    counts = np.ones(g, dtype=np.intp)
    ebm = ebs[moving]
    m = ebm.shape[0]
    if m == 0:
        return np.repeat(ea[None, :], g, axis=0), counts
    da, db = ea - center, ebm - center[None, :]
    ra, rb = float(norm(da)), norm(db)
    if ra <= MIN_DISTANCE or bool(np.any(rb <= MIN_DISTANCE)):
        raise InvalidValueError("pose_a, pose_b: eyes must differ from sphere.center")
    ua, ub = da / ra, db / rb[:, None]
    sin_all = norm(np.cross(ua[None, :], ub))
    cos_all = np.empty(m)
    omega = np.empty(m)
    n = np.empty(m, dtype=np.intp)
    kind = np.empty(m, dtype=np.int8)  # 0: arc, 1: radial, 2: antipodal
    for i in range(m):
        cos_o = float(np.dot(ua, ub[i]))
        sin_o = float(sin_all[i])
        om = math.atan2(sin_o, cos_o)
        if sin_o > PARALLEL:
            kind[i] = 0
        elif cos_o > 0.0:
            kind[i], om = 1, 0.0
        else:
            kind[i], om = 2, math.pi
        rbi = float(rb[i])
        bound = math.hypot(rbi - ra, max(ra, rbi) * om)
        cos_all[i], omega[i], n[i] = cos_o, om, max(1, math.ceil(bound / step))
    w = np.zeros((m, 3))
    arc = kind == 0
    wa = ub[arc] - cos_all[arc][:, None] * ua[None, :]
    w[arc] = wa / norm(wa)[:, None]
    if np.any(kind == 2):
        # Antipodal: the start alone fixes the great circle (as in _arc_eyes).
        axis = np.cross(ua, np.array([0.0, 0.0, 1.0]))
        if float(norm(axis)) < PARALLEL:
            axis = np.cross(ua, np.array([0.0, 1.0, 0.0]))
        axis = axis / norm(axis)
        wp = np.cross(axis, ua)
        w[kind == 2] = wp / norm(wp)

    # t = k / n for k = 0..n on each path, back to back.
    owner = np.repeat(np.arange(m), n + 1)
    first = np.cumsum(n + 1) - (n + 1)
    k = np.arange(owner.shape[0]) - first[owner]
    t = k.astype(np.float64) / n[owner].astype(np.float64)
    tw = t * omega[owner]
    dirs = np.cos(tw)[:, None] * ua[None, :] + np.sin(tw)[:, None] * w[owner]
    radii = (1.0 - t) * ra + t * rb[owner]
    moved = center[None, :] + radii[:, None] * dirs
    moved[first] = ea
    moved[first + n] = ebm

    counts[moving] = n + 1
    eyes = np.empty((int(counts.sum()), 3))
    on_moving = np.repeat(moving, counts)
    eyes[on_moving] = moved
    eyes[~on_moving] = ea
    return eyes, counts


def _arc_length_samples_many(
    points: FloatArray, counts: npt.NDArray[np.intp], n: int
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp]]:
    """:func:`arc_length_samples` of each polyline of ``points`` (``counts[g]`` points
    each, back to back) at once: the kept rows of ``points`` (path by path) and how many
    each path keeps. Bit-identical arc lengths: each path's cumulative sum runs over its
    own segments from 0, as there."""
    g = counts.shape[0]
    first = np.cumsum(counts) - counts
    owner = np.repeat(np.arange(g), counts)
    k = np.arange(points.shape[0]) - first[owner]
    seg = np.zeros((g, int(counts.max())))
    later = k > 0
    seg[owner[later], k[later]] = norm(np.diff(points, axis=0))[later[1:]]
    arc = np.cumsum(seg, axis=1)  # arc[p, 0] = 0; 0 + x = x, so the sums are the same
    end = arc[np.arange(g), counts - 1]
    want = end[:, None] * np.arange(1, n + 1)[None, :] / n
    idx = np.empty((g, n), dtype=np.intp)
    query = want - 1e-12
    for p, c in enumerate(counts.tolist()):
        idx[p] = arc[p, :c].searchsorted(query[p])
    idx = np.clip(idx, 1, (counts - 1)[:, None])
    # One point, or no length: only the last point.
    single = end <= 0
    idx[single] = (counts - 1)[single, None]
    # The indices grow along each row: np.unique drops the repeats.
    keep = np.ones((g, n), dtype=bool)
    keep[:, 1:] = idx[:, 1:] != idx[:, :-1]
    rows = (first[:, None] + idx)[keep]
    return rows, keep.sum(axis=1)


def path_length(poses: npt.ArrayLike) -> float:
    """Length of the polyline through the eye positions of ``poses``.

    Parameters
    ----------
    poses : array_like, shape (N, 4, 4)
        ``cam2world`` poses.

    Returns
    -------
    float
        Sum of the straight segments between consecutive eyes (m); 0 for ``N = 1``.
    """
    arr = np.asarray(poses, dtype=np.float64)
    if arr.ndim != 3 or arr.shape[1:] != (4, 4):
        raise ShapeError(f"poses: expected shape (N, 4, 4), got {arr.shape}")
    if arr.shape[0] < 2:
        return 0.0
    return float(np.sum(norm(np.diff(arr[:, :3, 3], axis=0))))


def mat_to_quat(rot: FloatArray) -> FloatArray:
    """``(N, 3, 3)`` rotations to ``(N, 4)`` unit quaternions ``(w, x, y, z)`` (Shepperd)."""
    q = np.empty((rot.shape[0], 4), dtype=np.float64)
    for i, m in enumerate(rot):
        tr = m[0, 0] + m[1, 1] + m[2, 2]
        if tr > 0.0:
            s = 2.0 * math.sqrt(tr + 1.0)
            q[i] = (
                0.25 * s,
                (m[2, 1] - m[1, 2]) / s,
                (m[0, 2] - m[2, 0]) / s,
                (m[1, 0] - m[0, 1]) / s,
            )
        elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
            s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
            q[i] = (
                (m[2, 1] - m[1, 2]) / s,
                0.25 * s,
                (m[0, 1] + m[1, 0]) / s,
                (m[0, 2] + m[2, 0]) / s,
            )
        elif m[1, 1] > m[2, 2]:
            s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
            q[i] = (
                (m[0, 2] - m[2, 0]) / s,
                (m[0, 1] + m[1, 0]) / s,
                0.25 * s,
                (m[1, 2] + m[2, 1]) / s,
            )
        else:
            s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
            q[i] = (
                (m[1, 0] - m[0, 1]) / s,
                (m[0, 2] + m[2, 0]) / s,
                (m[1, 2] + m[2, 1]) / s,
                0.25 * s,
            )
    return np.asarray(q / norm(q)[:, None], dtype=np.float64)


def quat_to_mat(q: FloatArray) -> FloatArray:
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    out = np.empty((q.shape[0], 3, 3), dtype=np.float64)
    out[:, 0, 0] = 1 - 2 * (y * y + z * z)
    out[:, 0, 1] = 2 * (x * y - z * w)
    out[:, 0, 2] = 2 * (x * z + y * w)
    out[:, 1, 0] = 2 * (x * y + z * w)
    out[:, 1, 1] = 1 - 2 * (x * x + z * z)
    out[:, 1, 2] = 2 * (y * z - x * w)
    out[:, 2, 0] = 2 * (x * z - y * w)
    out[:, 2, 1] = 2 * (y * z + x * w)
    out[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return out


def slerp(q0: FloatArray, q1: FloatArray, alpha: FloatArray) -> FloatArray:
    """Row-wise shortest-path slerp of unit quaternions."""
    dot = np.sum(q0 * q1, axis=-1)
    q1 = np.where((dot < 0.0)[:, None], -q1, q1)
    dot = np.abs(dot)
    omega = np.arccos(np.clip(dot, -1.0, 1.0))
    so = np.sin(omega)
    small = so < 1e-9
    safe = np.where(small, 1.0, so)
    c0 = np.where(small, 1.0 - alpha, np.sin((1.0 - alpha) * omega) / safe)
    c1 = np.where(small, alpha, np.sin(alpha * omega) / safe)
    q = c0[:, None] * q0 + c1[:, None] * q1
    return np.asarray(q / norm(q)[:, None], dtype=np.float64)
