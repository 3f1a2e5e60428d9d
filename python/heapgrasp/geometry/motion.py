"""Hand-eye camera motion: view spheres, waypoint interpolation and time parameterisation.

This module implements the camera-motion pieces of HEAPGrasp:

* :func:`look_at` -- a ``cam2world`` pose looking at a point (same convention as the Rust
  core's ``Pose::look_at``).
* :class:`ViewSphere` -- the spherical coordinate system of eq. 12 (origin at the bottom
  centre of the scene cube, cameras oriented toward the scene centre) and its ``U x V``
  view-waypoint candidates.
* :func:`interpolate` -- the interpolation function ``f(p_A, p_B)`` of eq. 8: a great-circle
  arc on the view sphere, every pose looking at the scene centre.
* :func:`time_path` / :class:`TimedPath` -- a jerk-limited, rest-to-rest time
  parameterisation of a geometric path (ruckig, 1 DoF along the arc length), sampled at the
  camera frame rate (continuous capture, 30 fps in the paper).
* :func:`plan_waypoints` / :func:`concatenate` -- eq. 8 for a list of view waypoints
  (the robot stops at every waypoint, where the next one is planned).
* :func:`hemisphere_waypoints` (GraspNeRF baseline) and :func:`circle_waypoints`
  (VGN / "HEAPGrasp w/o VP" baseline).

Conventions: metres, radians, seconds; poses are ``(4, 4)`` float64 rigid ``cam2world``
matrices with OpenCV camera axes (x right, y down, z forward). Bad input raises a
:class:`heapgrasp.HeapgraspError` (a ``ValueError``) subclass.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from ruckig import InputParameter, Result, Ruckig, Trajectory  # type: ignore[import-untyped,import-not-found,unused-ignore]

from heapgrasp._core import InvalidValueError, NonFiniteError, NotRigidError, ShapeError

__all__ = [
    "MotionLimits",
    "TimedPath",
    "ViewSphere",
    "arc_length_samples",
    "circle_waypoints",
    "concatenate",
    "hemisphere_waypoints",
    "interpolate",
    "interpolate_sampled",
    "look_at",
    "path_length",
    "plan_waypoints",
    "time_path",
]

FloatArray = npt.NDArray[np.float64]
Vec3 = tuple[float, float, float]

#: Minimum eye-target distance accepted by :func:`look_at` (as in the Rust core).
_MIN_DISTANCE = 1e-12
#: Below this ``|z x up|`` the viewing direction counts as parallel to ``up`` (Rust core).
_PARALLEL = 1e-9
#: Tolerance of the rigidity check of input poses.
_RIGID_TOLERANCE = 1e-6


# --------------------------------------------------------------------------- validation


def _vec3(name: str, value: npt.ArrayLike) -> FloatArray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != (3,):
        raise ShapeError(f"{name}: expected shape (3,), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise NonFiniteError(f"{name}: must be finite, got {arr.tolist()}")
    return arr


def _positive(name: str, value: float) -> float:
    v = float(value)
    if not (math.isfinite(v) and v > 0.0):
        raise InvalidValueError(f"{name}: must be finite and > 0, got {value!r}")
    return v


def _as_poses(name: str, poses: npt.ArrayLike) -> FloatArray:
    arr = np.asarray(poses, dtype=np.float64)
    if arr.ndim != 3 or arr.shape[1:] != (4, 4) or arr.shape[0] < 1:
        raise ShapeError(f"{name}: expected shape (N, 4, 4) with N >= 1, got {arr.shape}")
    _check_rigid(name, arr)
    return arr


def _as_pose(name: str, pose: npt.ArrayLike) -> FloatArray:
    arr = np.asarray(pose, dtype=np.float64)
    if arr.shape != (4, 4):
        raise ShapeError(f"{name}: expected shape (4, 4), got {arr.shape}")
    _check_rigid(name, arr[None])
    return arr


def _check_rigid(name: str, arr: FloatArray) -> None:
    if not np.all(np.isfinite(arr)):
        raise NonFiniteError(f"{name}: must be finite")
    if not np.array_equal(arr[:, 3, :], np.broadcast_to([0.0, 0.0, 0.0, 1.0], arr[:, 3].shape)):
        raise NotRigidError(f"{name}: last row must be [0, 0, 0, 1]")
    rot = arr[:, :3, :3]
    ortho = np.abs(np.swapaxes(rot, 1, 2) @ rot - np.eye(3)).max()
    det = np.linalg.det(rot)
    if ortho > _RIGID_TOLERANCE or np.abs(det - 1.0).max() > _RIGID_TOLERANCE:
        raise NotRigidError(f"{name}: rotation block must be orthonormal with det +1")


def _norm(v: FloatArray) -> FloatArray:
    """Euclidean norm along the last axis (one code path for single and batched input)."""
    return np.asarray(np.sqrt(np.sum(v * v, axis=-1)), dtype=np.float64)


# --------------------------------------------------------------------------- look_at


def _look_at_many(eyes: FloatArray, target: FloatArray, up: FloatArray) -> FloatArray:
    """Vectorised :func:`look_at` for ``(N, 3)`` eyes; returns ``(N, 4, 4)``."""
    direction = target[None, :] - eyes
    dist = _norm(direction)
    if np.any(~(dist > _MIN_DISTANCE)):
        raise InvalidValueError(f"target: {target.tolist()} must differ from eye")
    z = direction / dist[:, None]
    x = np.cross(z, up[None, :])
    parallel = _norm(x) < _PARALLEL
    if np.any(parallel):
        x[parallel] = np.cross(z[parallel], np.array([0.0, 1.0, 0.0]))
    xn = _norm(x)
    if np.any(xn < _PARALLEL):
        raise InvalidValueError(
            f"up: {up.tolist()} is parallel to the viewing direction and to world +y"
        )
    x = x / xn[:, None]
    y = np.cross(z, x)
    out = np.zeros((eyes.shape[0], 4, 4), dtype=np.float64)
    out[:, :3, 0] = x
    out[:, :3, 1] = y
    out[:, :3, 2] = z
    out[:, :3, 3] = eyes
    out[:, 3, 3] = 1.0
    return out


def look_at(
    eye: npt.ArrayLike,
    target: npt.ArrayLike,
    up: npt.ArrayLike = (0.0, 0.0, 1.0),
) -> FloatArray:
    """Camera pose at ``eye`` looking at ``target`` (OpenCV axes).

    Same convention as the Rust core's ``Pose::look_at``: ``z = normalize(target - eye)``
    (forward), ``x = normalize(z x up)`` (image right), ``y = z x x`` (image down). When
    the viewing direction is parallel to ``up`` (``|z x up| < 1e-9``), world ``+y`` serves
    as ``up``, so a camera looking straight down sees world ``+y`` toward the top of the
    image.

    Parameters
    ----------
    eye : array_like, shape (3,)
        Camera centre, world frame (m).
    target : array_like, shape (3,)
        Point on the optical axis, world frame (m).
    up : array_like, shape (3,), optional
        World up direction (default ``+z``); need not be normalised.

    Returns
    -------
    numpy.ndarray, shape (4, 4), float64
        ``cam2world``.

    Raises
    ------
    InvalidValueError
        If ``eye`` and ``target`` coincide (a ``ValueError``).
    ShapeError, NonFiniteError
        For inputs that are not finite 3-vectors.
    """
    e = _vec3("eye", eye)
    t = _vec3("target", target)
    u = _vec3("up", up)
    return np.asarray(_look_at_many(e[None, :], t, u)[0], dtype=np.float64)


# --------------------------------------------------------------------------- view sphere


def _unit_directions(phi: FloatArray, theta: FloatArray) -> FloatArray:
    st = np.sin(theta)
    return np.stack([st * np.cos(phi), st * np.sin(phi), np.cos(theta)], axis=-1)


@dataclass(frozen=True)
class ViewSphere:
    """Spherical coordinate system of the view-waypoint candidates (HEAPGrasp eq. 12).

    A camera at polar angle ``theta`` (from world ``+z``) and azimuth ``phi`` (from world
    ``+x`` toward ``+y``) sits at ``eye = center + radius * (sin(theta) cos(phi),
    sin(theta) sin(phi), cos(theta))`` and looks at ``target``. (The viewsphere
    benchmark's :class:`heapgrasp.viewsphere.sphere.DiscreteViewsphere` is another
    sphere, of 20° steps in 8 directions, for another paper; its ``SpherePose.polar`` and
    ``azimuth`` are this ``theta`` and ``phi``, measured the same way.)

    Parameters
    ----------
    center : tuple of float
        Origin of the sphere, world frame: the bottom centre of the scene cube.
    target : tuple of float
        What every camera looks at: the centre of the scene cube.
    radius : float
        Sphere radius ``r`` (m); 0.33 m in the paper (Table I).
    """

    center: Vec3
    target: Vec3
    radius: float

    def __post_init__(self) -> None:
        c = _vec3("center", self.center)
        t = _vec3("target", self.target)
        object.__setattr__(self, "center", (float(c[0]), float(c[1]), float(c[2])))
        object.__setattr__(self, "target", (float(t[0]), float(t[1]), float(t[2])))
        object.__setattr__(self, "radius", _positive("radius", self.radius))

    @classmethod
    def for_cube(cls, origin: npt.ArrayLike, size: float, radius: float = 0.33) -> ViewSphere:
        """View sphere of a scene cube (``origin`` = minimum corner, ``size`` = side).

        Parameters
        ----------
        origin : array_like, shape (3,)
            Minimum corner of the scene cube (as for ``OccupancyGrid``).
        size : float
            Side of the cube (m).
        radius : float, optional
            Sphere radius (m), default 0.33 (Table I).

        Returns
        -------
        ViewSphere
            ``center`` = bottom centre of the cube, ``target`` = cube centre.
        """
        o = _vec3("origin", origin)
        h = 0.5 * _positive("size", size)
        return cls(
            center=(float(o[0] + h), float(o[1] + h), float(o[2])),
            target=(float(o[0] + h), float(o[1] + h), float(o[2] + h)),
            radius=radius,
        )

    @property
    def center_array(self) -> FloatArray:
        """``center`` as a float64 array of shape (3,)."""
        return np.array(self.center, dtype=np.float64)

    @property
    def target_array(self) -> FloatArray:
        """``target`` as a float64 array of shape (3,)."""
        return np.array(self.target, dtype=np.float64)

    def eye(self, phi: float, theta: float) -> FloatArray:
        """Camera centre at spherical angles ``(phi, theta)`` on this sphere.

        Parameters
        ----------
        phi, theta : float
            Azimuth and polar angle (rad).

        Returns
        -------
        numpy.ndarray, shape (3,)
            World position.
        """
        d = _unit_directions(np.array([phi], dtype=np.float64), np.array([theta], np.float64))
        return np.asarray(self.center_array + self.radius * d[0], dtype=np.float64)

    def pose(self, phi: float, theta: float) -> FloatArray:
        """Camera pose at ``(phi, theta)`` looking at ``target``.

        Parameters
        ----------
        phi, theta : float
            Azimuth and polar angle (rad).

        Returns
        -------
        numpy.ndarray, shape (4, 4)
            ``cam2world`` (see :func:`look_at`).
        """
        return look_at(self.eye(phi, theta), self.target_array)

    @staticmethod
    def candidate_angles(
        U: int = 40, V: int = 20, theta_max: float = math.pi / 5
    ) -> tuple[FloatArray, FloatArray]:
        """Spherical angles of the eq. 12 candidates.

        Parameters
        ----------
        U, V : int, optional
            Number of azimuth / polar divisions (Table I: 40 x 20).
        theta_max : float, optional
            Maximum polar angle (exclusive), Table I: ``pi / 5``.

        Returns
        -------
        phi, theta : numpy.ndarray, shape (U, V)
            ``phi[u-1, v-1] = 2 pi (u-1) / U`` and ``theta[u-1, v-1] = theta_max (v-1) / V``.
        """
        if int(U) < 1 or int(V) < 1:
            raise InvalidValueError(f"U, V: must be >= 1, got {U}, {V}")
        theta_max = _positive("theta_max", theta_max)
        phi = 2.0 * math.pi * np.arange(int(U), dtype=np.float64) / int(U)
        theta = theta_max * np.arange(int(V), dtype=np.float64) / int(V)
        pp, tt = np.meshgrid(phi, theta, indexing="ij")
        return pp, tt

    def candidates(self, U: int = 40, V: int = 20, theta_max: float = math.pi / 5) -> FloatArray:
        """The ``U x V`` view-waypoint candidates of eq. 12.

        Parameters
        ----------
        U, V : int, optional
            Number of azimuth / polar divisions (Table I: 40 x 20).
        theta_max : float, optional
            Maximum polar angle (exclusive), Table I: ``pi / 5``.

        Returns
        -------
        numpy.ndarray, shape (U, V, 4, 4)
            ``[u-1, v-1]`` is the pose at ``phi = 2 pi (u-1)/U``, ``theta = theta_max (v-1)/V``
            looking at ``target``. The ``v = 1`` row (``theta = 0``) is the top of the sphere
            for every ``u`` (identical poses).
        """
        phi, theta = self.candidate_angles(U, V, theta_max)
        eyes = self.center_array + self.radius * _unit_directions(phi, theta)
        poses = _look_at_many(eyes.reshape(-1, 3), self.target_array, np.array([0.0, 0.0, 1.0]))
        return poses.reshape((*phi.shape, 4, 4))

    def spherical(self, position: npt.ArrayLike) -> tuple[float, float, float]:
        """Spherical coordinates of a point (or of the eye of a ``(4, 4)`` pose).

        Parameters
        ----------
        position : array_like, shape (3,) or (4, 4)
            World point, or a ``cam2world`` pose whose translation is used.

        Returns
        -------
        phi : float
            Azimuth in ``[0, 2 pi)`` (0 when the point is on the z axis of the sphere).
        theta : float
            Polar angle in ``[0, pi]`` (0 when the point is the centre).
        r : float
            Distance from ``center``.
        """
        arr = np.asarray(position, dtype=np.float64)
        p = _vec3("position", arr[:3, 3] if arr.shape == (4, 4) else arr)
        d = p - self.center_array
        r = float(_norm(d))
        if r == 0.0:
            return 0.0, 0.0, 0.0
        theta = math.acos(min(1.0, max(-1.0, float(d[2]) / r)))
        phi = math.atan2(float(d[1]), float(d[0])) % (2.0 * math.pi)
        if math.hypot(float(d[0]), float(d[1])) == 0.0 or phi >= 2.0 * math.pi:
            phi = 0.0
        return phi, theta, r


# --------------------------------------------------------------------------- interpolation


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
    pa = _as_pose("pose_a", pose_a)
    pb = _as_pose("pose_b", pose_b)
    step = _positive("step", step)
    eyes = _arc_eyes(pa[:3, 3], pb[:3, 3], sphere.center_array, step)
    return _look_at_many(eyes, sphere.target_array, np.array([0.0, 0.0, 1.0]))


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
    pa = _as_pose("pose_a", pose_a)
    pbs = _as_poses("poses_b", poses_b)
    step = _positive("step", step)
    if frames < 1:
        raise InvalidValueError(f"frames: must be >= 1, got {frames}")
    eyes, counts = _arc_eyes_many(
        pa[:3, 3].copy(), np.ascontiguousarray(pbs[:, :3, 3]), sphere.center_array, step
    )
    rows, kept = _arc_length_samples_many(eyes, counts, frames)
    poses = _look_at_many(
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
    arc = np.concatenate([[0.0], np.cumsum(_norm(np.diff(pts, axis=0)))])
    if arc[-1] <= 0:
        return np.array([len(pts) - 1])
    want = arc[-1] * np.arange(1, n + 1) / n
    return np.unique(np.clip(np.searchsorted(arc, want - 1e-12), 1, len(pts) - 1))


def _arc_eyes(ea: FloatArray, eb: FloatArray, center: FloatArray, step: float) -> FloatArray:
    """The eye positions of :func:`interpolate` (``(N, 3)``)."""
    ea, eb = ea.copy(), eb.copy()
    if np.array_equal(ea, eb) or float(_norm(eb - ea)) <= _MIN_DISTANCE:
        return ea[None, :]
    da, db = ea - center, eb - center
    ra, rb = float(_norm(da)), float(_norm(db))
    if ra <= _MIN_DISTANCE or rb <= _MIN_DISTANCE:
        raise InvalidValueError("pose_a, pose_b: eyes must differ from sphere.center")
    ua, ub = da / ra, db / rb
    cos_o = float(np.dot(ua, ub))
    sin_o = float(_norm(np.cross(ua, ub)))
    omega = math.atan2(sin_o, cos_o)
    if sin_o > _PARALLEL:
        w = ub - cos_o * ua
        w = w / _norm(w)
    elif cos_o > 0.0:  # same direction: radial motion only
        omega = 0.0
        w = np.zeros(3)
    else:  # antipodal: go over the top (+z), or through +y between the poles
        axis = np.cross(ua, np.array([0.0, 0.0, 1.0]))
        if float(_norm(axis)) < _PARALLEL:
            axis = np.cross(ua, np.array([0.0, 1.0, 0.0]))
        axis = axis / _norm(axis)
        w = np.cross(axis, ua)
        w = w / _norm(w)
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
    moving = ~(np.all(ebs == ea[None, :], axis=1) | (_norm(ebs - ea[None, :]) <= _MIN_DISTANCE))
    counts = np.ones(g, dtype=np.intp)
    ebm = ebs[moving]
    m = ebm.shape[0]
    if m == 0:
        return np.repeat(ea[None, :], g, axis=0), counts
    da, db = ea - center, ebm - center[None, :]
    ra, rb = float(_norm(da)), _norm(db)
    if ra <= _MIN_DISTANCE or bool(np.any(rb <= _MIN_DISTANCE)):
        raise InvalidValueError("pose_a, pose_b: eyes must differ from sphere.center")
    ua, ub = da / ra, db / rb[:, None]
    sin_all = _norm(np.cross(ua[None, :], ub))
    cos_all = np.empty(m)
    omega = np.empty(m)
    n = np.empty(m, dtype=np.intp)
    kind = np.empty(m, dtype=np.int8)  # 0: arc, 1: radial, 2: antipodal
    for i in range(m):
        cos_o = float(np.dot(ua, ub[i]))
        sin_o = float(sin_all[i])
        om = math.atan2(sin_o, cos_o)
        if sin_o > _PARALLEL:
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
    w[arc] = wa / _norm(wa)[:, None]
    if np.any(kind == 2):
        # Antipodal: the start alone fixes the great circle (as in _arc_eyes).
        axis = np.cross(ua, np.array([0.0, 0.0, 1.0]))
        if float(_norm(axis)) < _PARALLEL:
            axis = np.cross(ua, np.array([0.0, 1.0, 0.0]))
        axis = axis / _norm(axis)
        wp = np.cross(axis, ua)
        w[kind == 2] = wp / _norm(wp)

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
    seg[owner[later], k[later]] = _norm(np.diff(points, axis=0))[later[1:]]
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
    return float(np.sum(_norm(np.diff(arr[:, :3, 3], axis=0))))


# --------------------------------------------------------------------------- rotations


def _mat_to_quat(rot: FloatArray) -> FloatArray:
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
    return np.asarray(q / _norm(q)[:, None], dtype=np.float64)


def _quat_to_mat(q: FloatArray) -> FloatArray:
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


def _slerp(q0: FloatArray, q1: FloatArray, alpha: FloatArray) -> FloatArray:
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
    return np.asarray(q / _norm(q)[:, None], dtype=np.float64)


# --------------------------------------------------------------------------- timing


@dataclass(frozen=True)
class MotionLimits:
    """Cartesian limits of the camera along its path (jerk-limited time parameterisation).

    The limits bound the derivatives of the path coordinate ``s`` (arc length of the eye
    position), i.e. the camera's speed and its tangential acceleration and jerk; the normal
    (centripetal) acceleration ``v^2 / rho`` of a curved path comes on top (at most
    ``0.25^2 / 0.33 = 0.19 m/s^2`` on the Table I sphere). The defaults are conservative
    for a Franka Emika Panda hand carrying a camera (the Panda's own Cartesian limits are
    1.7 m/s, 13 m/s^2 and 6500 m/s^3).

    Parameters
    ----------
    max_velocity : float
        Maximum camera speed (m/s), default 0.25.
    max_acceleration : float
        Maximum tangential acceleration (m/s^2), default 1.0.
    max_jerk : float
        Maximum tangential jerk (m/s^3), default 5.0.
    """

    max_velocity: float = 0.25
    max_acceleration: float = 1.0
    max_jerk: float = 5.0

    def __post_init__(self) -> None:
        for name in ("max_velocity", "max_acceleration", "max_jerk"):
            object.__setattr__(self, name, _positive(name, getattr(self, name)))


class TimedPath:
    """A geometric camera path with a rest-to-rest, jerk-limited timing (see :func:`time_path`).

    The pose at time ``t`` is found at arc length ``s(t)`` on the polyline through the
    samples' eye positions: the position is interpolated linearly between the two
    neighbouring samples and the orientation is slerped between their rotations (so the
    path needs no knowledge of a look-at target, and every sample pose is reproduced
    exactly at its arc length). For paths made by :func:`interpolate` the slerped camera
    still looks at the target to within about ``(step / distance)^2`` rad.

    Attributes
    ----------
    poses : numpy.ndarray, shape (N, 4, 4)
        The geometric path (read-only copy).
    arclength : numpy.ndarray, shape (N,)
        Cumulative eye arc length at each sample, from 0 to ``length``.
    length : float
        Path length ``L`` (m).
    duration : float
        Time to travel the path from rest to rest (s); 0 when ``L = 0``.
    limits : MotionLimits
        The limits used.
    fps : float
        Default frame rate of :meth:`sample`.
    """

    def __init__(self, poses: FloatArray, limits: MotionLimits, fps: float) -> None:
        self.poses: FloatArray = poses.copy()
        self.poses.flags.writeable = False
        seg = _norm(np.diff(poses[:, :3, 3], axis=0))
        arc = np.concatenate([[0.0], np.cumsum(seg)])
        arc.flags.writeable = False
        self.arclength: FloatArray = arc
        self.length: float = float(arc[-1])
        self.limits: MotionLimits = limits
        self.fps: float = _positive("fps", fps)
        self._quats = _mat_to_quat(poses[:, :3, :3])
        self._trajectory: Trajectory | None = None
        self.duration: float = 0.0
        if self.length > 0.0:
            inp = InputParameter(1)
            inp.current_position = [0.0]
            inp.current_velocity = [0.0]
            inp.current_acceleration = [0.0]
            inp.target_position = [self.length]
            inp.target_velocity = [0.0]
            inp.target_acceleration = [0.0]
            inp.max_velocity = [limits.max_velocity]
            inp.max_acceleration = [limits.max_acceleration]
            inp.max_jerk = [limits.max_jerk]
            traj = Trajectory(1)
            result = Ruckig(1).calculate(inp, traj)
            if result not in (Result.Working, Result.Finished):
                raise RuntimeError(f"ruckig failed to time the path: {result}")
            self._trajectory = traj
            self.duration = float(traj.duration)

    def __repr__(self) -> str:
        return (
            f"TimedPath(samples={self.poses.shape[0]}, length={self.length:.4f} m, "
            f"duration={self.duration:.4f} s)"
        )

    def state(self, t: float) -> tuple[float, float, float]:
        """Path coordinate and its derivatives at time ``t``.

        Parameters
        ----------
        t : float
            Time (s); clamped to ``[0, duration]`` (at rest outside).

        Returns
        -------
        s, s_dot, s_ddot : float
            Arc length (m), speed (m/s) and tangential acceleration (m/s^2).
        """
        t = float(t)
        if not math.isfinite(t):
            raise NonFiniteError(f"t: must be finite, got {t}")
        if self._trajectory is None or t <= 0.0:
            return 0.0, 0.0, 0.0
        if t >= self.duration:
            return self.length, 0.0, 0.0
        pos, vel, acc = self._trajectory.at_time(t)
        return min(max(float(pos[0]), 0.0), self.length), float(vel[0]), float(acc[0])

    def at_arclength(self, s: npt.ArrayLike) -> FloatArray:
        """Poses at arc lengths ``s`` along the geometric path.

        Parameters
        ----------
        s : array_like, shape (K,) or scalar
            Arc lengths (m), clamped to ``[0, length]``.

        Returns
        -------
        numpy.ndarray, shape (K, 4, 4) (or (4, 4) for a scalar)
            ``cam2world`` poses.
        """
        s_arr = np.asarray(s, dtype=np.float64)
        scalar = s_arr.ndim == 0
        s_arr = np.clip(np.atleast_1d(s_arr), 0.0, self.length)
        n = self.poses.shape[0]
        if n == 1:
            out = np.repeat(self.poses, s_arr.shape[0], axis=0)
            return out[0] if scalar else out
        i = np.clip(np.searchsorted(self.arclength, s_arr, side="right") - 1, 0, n - 2)
        seg = self.arclength[i + 1] - self.arclength[i]
        alpha = np.where(seg > 0.0, (s_arr - self.arclength[i]) / np.where(seg > 0, seg, 1.0), 0.0)
        alpha = np.clip(alpha, 0.0, 1.0)
        out = np.zeros((s_arr.shape[0], 4, 4), dtype=np.float64)
        out[:, 3, 3] = 1.0
        p0, p1 = self.poses[i, :3, 3], self.poses[i + 1, :3, 3]
        out[:, :3, 3] = (1.0 - alpha)[:, None] * p0 + alpha[:, None] * p1
        out[:, :3, :3] = _quat_to_mat(_slerp(self._quats[i], self._quats[i + 1], alpha))
        # Reproduce the samples exactly at their arc lengths.
        at0, at1 = alpha == 0.0, alpha == 1.0
        out[at0] = self.poses[i[at0]]
        out[at1] = self.poses[i[at1] + 1]
        return out[0] if scalar else out

    def at(self, t: float) -> FloatArray:
        """Camera pose at time ``t``.

        Parameters
        ----------
        t : float
            Time (s) since the start of the path; clamped to ``[0, duration]``.

        Returns
        -------
        numpy.ndarray, shape (4, 4)
            ``cam2world``; exactly ``poses[0]`` at ``t <= 0`` and ``poses[-1]`` at
            ``t >= duration``.
        """
        return self.at_arclength(self.state(t)[0])

    def frame_times(self, fps: float | None = None) -> FloatArray:
        """Capture times ``0, 1/fps, 2/fps, ...`` plus ``duration`` (always included).

        Parameters
        ----------
        fps : float, optional
            Camera frame rate (Hz); default ``self.fps``.

        Returns
        -------
        numpy.ndarray, shape (K,)
            Strictly increasing times; the last is ``duration`` (the final, resting frame),
            and the gap before it is in ``(1e-9, 1/fps]``. ``[0.0]`` when ``duration = 0``.
        """
        rate = self.fps if fps is None else _positive("fps", fps)
        k = math.floor(self.duration * rate) + 1
        times = np.arange(k, dtype=np.float64) / rate
        times = times[times < self.duration - 1e-9]
        return np.concatenate([times, [self.duration]]) if self.duration > 0 else np.zeros(1)

    def sample(self, fps: float | None = None) -> tuple[FloatArray, FloatArray]:
        """Frames captured at the camera rate while moving along the path.

        Parameters
        ----------
        fps : float, optional
            Camera frame rate (Hz); default ``self.fps`` (30 fps in the paper).

        Returns
        -------
        times : numpy.ndarray, shape (K,)
            See :meth:`frame_times`: ``t = 0, 1/fps, ...`` and the end frame at ``duration``.
        poses : numpy.ndarray, shape (K, 4, 4)
            ``cam2world`` at each time.
        """
        times = self.frame_times(fps)
        s = np.array([self.state(float(t))[0] for t in times], dtype=np.float64)
        return times, self.at_arclength(s)


def time_path(
    poses: npt.ArrayLike, limits: MotionLimits | None = None, *, fps: float = 30.0
) -> TimedPath:
    """Rest-to-rest, jerk-limited time parameterisation of a geometric camera path.

    The path coordinate ``s`` in ``[0, L]`` (arc length of the eye polyline) is planned as
    one degree of freedom with ruckig from rest to rest (zero velocity and acceleration at
    both ends) under ``limits``; the camera speed is exactly ``|ds/dt|``.

    Parameters
    ----------
    poses : array_like, shape (N, 4, 4)
        Geometric path (e.g. from :func:`interpolate`), N >= 1.
    limits : MotionLimits, optional
        Default :class:`MotionLimits()`.
    fps : float, optional
        Default frame rate of :meth:`TimedPath.sample` (Hz), default 30.

    Returns
    -------
    TimedPath
    """
    arr = _as_poses("poses", poses)
    return TimedPath(arr, MotionLimits() if limits is None else limits, fps)


def plan_waypoints(
    start_pose: npt.ArrayLike,
    waypoints: Sequence[npt.ArrayLike] | npt.ArrayLike,
    sphere: ViewSphere,
    limits: MotionLimits | None = None,
    fps: float = 30.0,
    *,
    step: float = 0.005,
) -> list[TimedPath]:
    """Eq. 8: ``f(p^0, p^1), f(p^1, p^2), ..., f(p^{L-1}, p^L)``, each segment timed.

    Every segment starts and ends at rest (the paper stops at each view waypoint to plan
    the next one).

    Parameters
    ----------
    start_pose : array_like, shape (4, 4)
        Initial camera pose ``p^0``.
    waypoints : sequence of (4, 4) arrays, or array of shape (L, 4, 4)
        View waypoints ``p^1 ... p^L``.
    sphere : ViewSphere
        Sphere used by :func:`interpolate`.
    limits : MotionLimits, optional
        Default :class:`MotionLimits()`.
    fps : float, optional
        Camera frame rate stored in each :class:`TimedPath` (Hz), default 30.
    step : float, optional
        Sample spacing of :func:`interpolate` (m).

    Returns
    -------
    list of TimedPath
        One per waypoint (``L`` segments).
    """
    lim = MotionLimits() if limits is None else limits
    wps = np.asarray(waypoints, dtype=np.float64)
    if wps.size == 0:
        return []
    wps = _as_poses("waypoints", wps)
    prev = _as_pose("start_pose", start_pose)
    out: list[TimedPath] = []
    for w in wps:
        geo = interpolate(prev, w, sphere, step=step)
        out.append(TimedPath(geo, lim, fps))
        prev = geo[-1]
    return out


def concatenate(
    paths: Sequence[TimedPath], fps: float | None = None
) -> tuple[FloatArray, FloatArray]:
    """Frames of consecutive timed segments as one trajectory ``P_cam`` (eq. 8).

    Segment ``k`` starts at the end time of segment ``k - 1``; the first frame of every
    segment after the first is dropped, as it repeats the previous end frame.

    Parameters
    ----------
    paths : sequence of TimedPath
        Segments, e.g. from :func:`plan_waypoints`.
    fps : float, optional
        Frame rate (Hz); default each segment's ``fps``.

    Returns
    -------
    times : numpy.ndarray, shape (K,)
        Global capture times (s), non-decreasing.
    poses : numpy.ndarray, shape (K, 4, 4)
        ``cam2world`` at each time.
    """
    all_t: list[FloatArray] = []
    all_p: list[FloatArray] = []
    offset = 0.0
    for k, path in enumerate(paths):
        t, p = path.sample(fps)
        if k > 0:
            t, p = t[1:], p[1:]
        all_t.append(t + offset)
        all_p.append(p)
        offset += path.duration
    if not all_t:
        return np.zeros(0), np.zeros((0, 4, 4))
    return np.concatenate(all_t), np.concatenate(all_p)


# --------------------------------------------------------------------------- baselines


def hemisphere_waypoints(
    rng: np.random.Generator,
    center: npt.ArrayLike,
    n: int = 6,
    radius: float = 0.5,
    theta: float = math.pi / 6,
    *,
    sort: bool = True,
) -> FloatArray:
    """GraspNeRF baseline view waypoints (HEAPGrasp Sec. VI-B).

    ``n`` waypoints on a hemisphere of radius ``radius`` centred in the workspace at polar
    angle ``theta`` with azimuths ``phi ~ U(0, 2 pi)``, all looking at ``center``.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the azimuths (``rng.uniform(0, 2 pi, n)``, one call).
    center : array_like, shape (3,)
        Workspace centre: the sphere origin and the look-at target.
    n : int, optional
        Number of waypoints (6).
    radius : float, optional
        Sphere radius (m), 0.5.
    theta : float, optional
        Polar angle (rad), ``pi / 6``.
    sort : bool, optional
        Visit the waypoints in increasing azimuth (default) instead of draw order.

    Returns
    -------
    numpy.ndarray, shape (n, 4, 4)
        ``cam2world`` poses.
    """
    c = _vec3("center", center)
    if int(n) < 1:
        raise InvalidValueError(f"n: must be >= 1, got {n}")
    r = _positive("radius", radius)
    phi = rng.uniform(0.0, 2.0 * math.pi, int(n))
    if sort:
        phi = np.sort(phi)
    eyes = c + r * _unit_directions(phi, np.full_like(phi, float(theta)))
    return _look_at_many(eyes, c, np.array([0.0, 0.0, 1.0]))


def circle_waypoints(
    sphere: ViewSphere,
    L: int = 3,
    theta: float = math.pi / 5,
    phi0: float = 0.0,
    closed: bool = False,
) -> FloatArray:
    """VGN / "HEAPGrasp w/o VP" baseline: ``L`` waypoints evenly spaced around the scene.

    Parameters
    ----------
    sphere : ViewSphere
        View sphere (waypoints look at ``sphere.target``).
    L : int, optional
        Number of waypoints (Table I: 3).
    theta : float, optional
        Constant polar angle (rad); default ``pi / 5`` (``theta_max`` of Table I).
    phi0 : float, optional
        Azimuth of the first waypoint (rad).
    closed : bool, optional
        Go once around the scene: append the first waypoint again (at ``phi0 + 2 pi``),
        so the camera circles the scene fully and ends where it joined the circle. A
        single waypoint (``L = 1``) has no circle to close and is returned alone.

    Returns
    -------
    numpy.ndarray, shape (L, 4, 4), or (L + 1, 4, 4) when ``closed`` and ``L > 1``
        Poses at ``phi = phi0 + 2 pi l / L``, ``l = 0 .. L-1`` (``.. L`` when closed).
    """
    if int(L) < 1:
        raise InvalidValueError(f"L: must be >= 1, got {L}")
    n = int(L) + 1 if closed and int(L) > 1 else int(L)
    phi = float(phi0) + 2.0 * math.pi * np.arange(n, dtype=np.float64) / int(L)
    eyes = sphere.center_array + sphere.radius * _unit_directions(
        phi, np.full_like(phi, float(theta))
    )
    return _look_at_many(eyes, sphere.target_array, np.array([0.0, 0.0, 1.0]))
