"""Hand-eye camera motion: view spheres, waypoint interpolation and time parameterisation.

This package implements the camera-motion pieces of HEAPGrasp:

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

Modules: :mod:`~heapgrasp.geometry.motion.sphere`, :mod:`~heapgrasp.geometry.motion.interpolation`,
:mod:`~heapgrasp.geometry.motion.timing`, :mod:`~heapgrasp.geometry.motion.fixed`, and the input
checks in :mod:`~heapgrasp.geometry.motion.validation`.

Conventions: metres, radians, seconds; poses are ``(4, 4)`` float64 rigid ``cam2world``
matrices with OpenCV camera axes (x right, y down, z forward). Bad input raises a
:class:`heapgrasp.HeapgraspError` (a ``ValueError``) subclass.
"""

from heapgrasp.geometry.motion.fixed import circle_waypoints, hemisphere_waypoints
from heapgrasp.geometry.motion.interpolation import (
    arc_length_samples,
    interpolate,
    interpolate_sampled,
    path_length,
)
from heapgrasp.geometry.motion.sphere import ViewSphere, look_at
from heapgrasp.geometry.motion.timing import (
    MotionLimits,
    TimedPath,
    concatenate,
    plan_waypoints,
    time_path,
)

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
