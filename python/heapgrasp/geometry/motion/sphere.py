""":func:`look_at` (a ``cam2world`` pose looking at a point, as the Rust core's
``Pose::look_at``) and :class:`ViewSphere`, the spherical coordinate system of eq. 12 and
its ``U x V`` view-waypoint candidates."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from heapgrasp._core import InvalidValueError
from heapgrasp.geometry.motion.validation import (
    MIN_DISTANCE,
    PARALLEL,
    FloatArray,
    Vec3,
    norm,
    positive,
    vec3,
)


def look_at_many(eyes: FloatArray, target: FloatArray, up: FloatArray) -> FloatArray:
    """Vectorised :func:`look_at` for ``(N, 3)`` eyes; returns ``(N, 4, 4)``."""
    direction = target[None, :] - eyes
    dist = norm(direction)
    if np.any(~(dist > MIN_DISTANCE)):
        raise InvalidValueError(f"target: {target.tolist()} must differ from eye")
    z = direction / dist[:, None]
    x = np.cross(z, up[None, :])
    parallel = norm(x) < PARALLEL
    if np.any(parallel):
        x[parallel] = np.cross(z[parallel], np.array([0.0, 1.0, 0.0]))
    xn = norm(x)
    if np.any(xn < PARALLEL):
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
    e = vec3("eye", eye)
    t = vec3("target", target)
    u = vec3("up", up)
    return np.asarray(look_at_many(e[None, :], t, u)[0], dtype=np.float64)


def unit_directions(phi: FloatArray, theta: FloatArray) -> FloatArray:
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
        c = vec3("center", self.center)
        t = vec3("target", self.target)
        object.__setattr__(self, "center", (float(c[0]), float(c[1]), float(c[2])))
        object.__setattr__(self, "target", (float(t[0]), float(t[1]), float(t[2])))
        object.__setattr__(self, "radius", positive("radius", self.radius))

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
        o = vec3("origin", origin)
        h = 0.5 * positive("size", size)
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
        d = unit_directions(np.array([phi], dtype=np.float64), np.array([theta], np.float64))
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
        theta_max = positive("theta_max", theta_max)
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
        eyes = self.center_array + self.radius * unit_directions(phi, theta)
        poses = look_at_many(eyes.reshape(-1, 3), self.target_array, np.array([0.0, 0.0, 1.0]))
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
        p = vec3("position", arr[:3, 3] if arr.shape == (4, 4) else arr)
        d = p - self.center_array
        r = float(norm(d))
        if r == 0.0:
            return 0.0, 0.0, 0.0
        theta = math.acos(min(1.0, max(-1.0, float(d[2]) / r)))
        phi = math.atan2(float(d[1]), float(d[0])) % (2.0 * math.pi)
        if math.hypot(float(d[0]), float(d[1])) == 0.0 or phi >= 2.0 * math.pi:
            phi = 0.0
        return phi, theta, r
