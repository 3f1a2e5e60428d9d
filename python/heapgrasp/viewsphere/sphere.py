"""Natarajan et al.'s viewsphere: a camera on a sphere around the object, moved in discrete steps.

The active-vision benchmark of seed ``001_95c7dd5c6a7c3646.txt`` (§3.1, Fig. 3) keeps the
camera on a sphere of radius ``v_r = 0.40 m`` centred on the object, always looking at
the centre, and moves it in steps of ``v_s = 20°`` of arc in one of ``v_d = 8``
directions: N, NE, E, SE, S, SW, W, NW. A pose is ``(azimuth, polar)`` about the centre
(polar 0: straight above; azimuth measured from world +x toward +y).

A step follows the great circle through the camera in the direction's heading: N toward
the pole (decreasing polar angle), E toward increasing azimuth, the diagonals halfway, so
every step covers the same arc whatever the direction (the public code's "mode B"; its
"mode A", which adds ±20° to the angles, is shorter near the pole and longer on
diagonals). A step across the pole comes down on the other side (the azimuth turns by π).

A pose is valid when its polar angle is at most ``max_polar`` (85°: the camera stays
above the table). :meth:`DiscreteViewsphere.move` falls back, when a direction's step is
invalid, to the directions ``d, d+1, d−1, d+2, d−2, d+3, d−3, d+4`` in that order.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from heapgrasp.geometry.checks import finite, positive
from heapgrasp.geometry.motion import look_at

__all__ = ["DIRECTIONS", "START", "DiscreteViewsphere", "SpherePose", "fallback_order"]

F64 = npt.NDArray[np.float64]

#: The 8 step directions, clockwise from north; a direction is its index here.
DIRECTIONS: tuple[str, ...] = ("N", "NE", "E", "SE", "S", "SW", "W", "NW")

#: Tolerance on the polar limit and at the pole (radians).
_EPS = 1e-9


class SpherePose(NamedTuple):
    """A camera position on the viewsphere (radians)."""

    azimuth: float
    """From world +x toward +y, in ``[0, 2π)``."""
    polar: float
    """From straight above (0), in ``[0, π]``."""


#: Natarajan et al.'s first view: azimuth π, polar π/7.
START = SpherePose(math.pi, math.pi / 7)


@dataclass(frozen=True)
class DiscreteViewsphere:
    """The viewsphere and its steps (module doc); lengths in metres, angles in radians.

    Not HEAPGrasp's :class:`heapgrasp.geometry.motion.ViewSphere` (eq. 12's continuous
    U×V candidates): this one moves in fixed 20° steps. Its angles are measured alike:
    ``polar`` is that class's ``theta`` (from +z), ``azimuth`` its ``phi`` (from +x toward
    +y)."""

    radius: float = 0.40
    step: float = math.radians(20.0)
    max_polar: float = math.radians(85.0)
    centre: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        positive("DiscreteViewsphere.radius", self.radius)
        positive("DiscreteViewsphere.step", self.step)
        if not (math.isfinite(self.step) and self.step < math.pi):
            raise ValueError(f"DiscreteViewsphere.step must be in (0, π), got {self.step}")
        if not (math.isfinite(self.max_polar) and 0.0 < self.max_polar <= math.pi):
            raise ValueError(
                f"DiscreteViewsphere.max_polar must be in (0, π], got {self.max_polar}"
            )
        centre = tuple(float(c) for c in self.centre)
        if len(centre) != 3:
            raise ValueError(f"DiscreteViewsphere.centre must be 3 numbers, got {self.centre}")
        for c in centre:
            finite("DiscreteViewsphere.centre", c)
        object.__setattr__(self, "centre", centre)

    # ------------------------------------------------------------------ poses
    def valid(self, pose: SpherePose) -> bool:
        """Whether the camera may be at ``pose`` (polar angle at most ``max_polar``)."""
        return 0.0 <= pose.polar <= self.max_polar + _EPS

    def position(self, pose: SpherePose) -> F64:
        """The camera's centre (world, m)."""
        return np.asarray(self.centre) + self.radius * _unit(pose)

    def camera_pose(self, pose: SpherePose) -> F64:
        """``(4, 4)`` camera-to-world pose at ``pose`` looking at the centre (OpenCV
        axes, :func:`~heapgrasp.geometry.motion.look_at`)."""
        return look_at(self.position(pose), self.centre)

    def pose_of(self, position: npt.ArrayLike) -> SpherePose:
        """The pose whose direction from the centre is that of ``position`` (its distance
        from the centre is ignored)."""
        d = np.asarray(position, dtype=np.float64).reshape(3) - np.asarray(self.centre)
        norm = float(np.linalg.norm(d))
        if not (math.isfinite(norm) and norm > 0.0):
            raise ValueError(f"position must differ from the centre, got {position!r}")
        return _pose(d / norm)

    # ------------------------------------------------------------------ steps
    def step_from(self, pose: SpherePose, direction: int) -> SpherePose:
        """Where one step in ``direction`` (an index of :data:`DIRECTIONS`) leads, valid or
        not."""
        if not (isinstance(direction, (int, np.integer)) and 0 <= direction < len(DIRECTIONS)):
            raise ValueError(f"direction must be an int in [0, 8), got {direction!r}")
        r = _unit(pose)
        north, east = _tangents(pose)
        heading = math.radians(45.0 * int(direction))
        t = math.cos(heading) * north + math.sin(heading) * east
        nxt = _pose(math.cos(self.step) * r + math.sin(self.step) * t)
        if nxt.polar < _EPS:  # on the pole: keep the meridian it came along
            return SpherePose(pose.azimuth, 0.0)
        return nxt

    def move(self, pose: SpherePose, direction: int) -> tuple[int, SpherePose]:
        """One step toward ``direction``, or toward the first valid of its fallbacks
        (``d, d+1, d−1, d+2, d−2, d+3, d−3, d+4``): the direction taken and the new pose.
        ValueError when no direction leads to a valid pose."""
        for taken in fallback_order(direction):
            nxt = self.step_from(pose, taken)
            if self.valid(nxt):
                return taken, nxt
        raise ValueError(f"no step from {pose} leads to a valid pose")

    def arc(self, a: SpherePose, b: SpherePose) -> float:
        """The angle between two poses seen from the centre (radians)."""
        return float(math.acos(min(1.0, max(-1.0, float(_unit(a) @ _unit(b))))))


def fallback_order(direction: int) -> tuple[int, ...]:
    """The directions :meth:`DiscreteViewsphere.move` tries, in order."""
    if not (isinstance(direction, (int, np.integer)) and 0 <= direction < len(DIRECTIONS)):
        raise ValueError(f"direction must be an int in [0, 8), got {direction!r}")
    d = int(direction)
    offsets = (0, 1, -1, 2, -2, 3, -3, 4)
    return tuple((d + k) % len(DIRECTIONS) for k in offsets)


def _unit(pose: SpherePose) -> F64:
    sa, ca = math.sin(pose.azimuth), math.cos(pose.azimuth)
    sp, cp = math.sin(pose.polar), math.cos(pose.polar)
    return np.array([sp * ca, sp * sa, cp])


def _tangents(pose: SpherePose) -> tuple[F64, F64]:
    """Unit north (toward the pole, −e_polar) and east (e_azimuth) at ``pose``; at the
    pole itself, those of the meridian of ``pose.azimuth``."""
    sa, ca = math.sin(pose.azimuth), math.cos(pose.azimuth)
    sp, cp = math.sin(pose.polar), math.cos(pose.polar)
    north = -np.array([cp * ca, cp * sa, -sp])
    east = np.array([-sa, ca, 0.0])
    return north, east


def _pose(unit: F64) -> SpherePose:
    x, y, z = (float(v) for v in unit)
    polar = math.atan2(math.hypot(x, y), z)
    azimuth = math.atan2(y, x) % (2.0 * math.pi) if math.hypot(x, y) > _EPS else 0.0
    return SpherePose(azimuth, polar)
