"""The fixed-view baselines' waypoints: :func:`hemisphere_waypoints` (GraspNeRF's six) and
:func:`circle_waypoints` (VGN's and HEAPGrasp w/o VP's circle)."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from heapgrasp._core import InvalidValueError
from heapgrasp.geometry.motion.sphere import ViewSphere, look_at_many, unit_directions
from heapgrasp.geometry.motion.validation import (
    FloatArray,
    positive,
    vec3,
)


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
    c = vec3("center", center)
    if int(n) < 1:
        raise InvalidValueError(f"n: must be >= 1, got {n}")
    r = positive("radius", radius)
    phi = rng.uniform(0.0, 2.0 * math.pi, int(n))
    if sort:
        phi = np.sort(phi)
    eyes = c + r * unit_directions(phi, np.full_like(phi, float(theta)))
    return look_at_many(eyes, c, np.array([0.0, 0.0, 1.0]))


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
    eyes = sphere.center_array + sphere.radius * unit_directions(
        phi, np.full_like(phi, float(theta))
    )
    return look_at_many(eyes, sphere.target_array, np.array([0.0, 0.0, 1.0]))
