"""Joint timing of camera paths for the simulated Panda arm.

:func:`retime_for_arm` slows a Cartesian :class:`~heapgrasp.geometry.motion.TimedPath`
until the Panda's joint velocity, acceleration and jerk limits (datasheet values in
:class:`~heapgrasp.sim.arm_config.ArmConfig`) hold along it, as measured by
:func:`joint_profile` (IK at the path's samples, a cubic spline in arc length, and the
path's timing); a path that needs a re-configuration raises :class:`JointPathError`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from heapgrasp import HeapgraspError
from heapgrasp.geometry.motion import MotionLimits, TimedPath
from heapgrasp.sim.arm import PandaArm
from heapgrasp.sim.arm_config import ArmConfig

__all__ = [
    "JointPathError",
    "JointProfile",
    "joint_profile",
    "retime_for_arm",
]

FloatArray = npt.NDArray[np.float64]


class JointPathError(HeapgraspError):
    """A camera path the arm cannot follow continuously (a ``ValueError``): a joint limit
    forces a re-configuration (a jump of the IK solution) along it."""


@dataclass(frozen=True, eq=False)
class JointProfile:
    """Joint trajectory of the arm along a timed camera path (:func:`joint_profile`).

    Attributes
    ----------
    times : numpy.ndarray, shape (K,)
        Uniform sample times from 0 to the path's duration (s).
    positions, velocities, accelerations, jerks : numpy.ndarray, shape (K, 7)
        Joint angles and their time derivatives (rad, rad/s, rad/s^2, rad/s^3).
    """

    times: FloatArray
    positions: FloatArray
    velocities: FloatArray
    accelerations: FloatArray
    jerks: FloatArray
    discontinuity: int | None = None
    """Index in ``path.poses`` where the arm must re-configure (None: continuous)."""

    def limit_ratios(self, config: ArmConfig) -> tuple[float, float, float]:
        """Largest ``|derivative| / limit`` over joints and samples, for velocity,
        acceleration and jerk (<= 1 means within the limits)."""
        if self.times.shape[0] < 2:
            return 0.0, 0.0, 0.0
        v = float((np.abs(self.velocities) / np.array(config.max_velocity)).max())
        a = float((np.abs(self.accelerations) / np.array(config.max_acceleration)).max())
        j = float((np.abs(self.jerks) / np.array(config.max_jerk)).max())
        return v, a, j


def joint_profile(path: TimedPath, arm: PandaArm, *, rate: float = 100.0) -> JointProfile:
    """The arm's joint trajectory along a timed camera path, sampled at ``rate`` Hz.

    The joint path is solved at the path's geometric samples (``path.poses``, e.g. every
    5 mm) by :meth:`PandaArm.camera_joint_path` (from the arm's current configuration,
    or a re-configured start if that one runs into a joint limit) and interpolated by a
    cubic spline in the arc length ``s``: the polyline of samples stands for a smooth
    curve, whose kinks would otherwise make the acceleration depend on the sampling.
    With ``s(t)`` and its derivatives from the path's timing, ``q' = q_s s'`` and
    ``q'' = q_ss s'^2 + q_s s''`` are exact for the spline; the jerk is the
    finite-difference derivative of ``q''`` at ``rate``. The arm is not moved.

    Parameters
    ----------
    path
        Timed ``cam2world`` path (e.g. from :func:`heapgrasp.geometry.motion.plan_waypoints`).
    arm
        The arm carrying the camera.
    rate
        Sampling rate of the profile (Hz).

    Returns
    -------
    JointProfile

    Raises
    ------
    UnreachableError
        If a pose of the path is out of reach.
    """
    from scipy.interpolate import CubicSpline

    if not (math.isfinite(rate) and rate > 0):
        raise ValueError(f"rate must be finite and > 0 (Hz), got {rate}")
    knots, first = np.unique(np.asarray(path.arclength), return_index=True)
    q_knots, jump = arm.camera_joint_chain(np.asarray(path.poses)[first])
    discontinuity = None if jump is None else int(first[jump])
    n = max(1, math.ceil(path.duration * rate))
    times = np.linspace(0.0, path.duration, n + 1)
    if knots.shape[0] < 2 or path.duration == 0.0:
        q = np.repeat(q_knots[:1], times.shape[0], axis=0)
        zeros = np.zeros_like(q)
        return JointProfile(times, q, zeros, zeros.copy(), zeros.copy(), discontinuity)
    state = np.array([path.state(float(t)) for t in times])
    s, sd, sdd = state[:, 0], state[:, 1:2], state[:, 2:3]
    spline = CubicSpline(knots, q_knots, axis=0)
    q = np.asarray(spline(s), dtype=np.float64)
    q_s = np.asarray(spline(s, 1), dtype=np.float64)
    q_ss = np.asarray(spline(s, 2), dtype=np.float64)
    qd = q_s * sd
    qdd = q_ss * sd**2 + q_s * sdd
    qddd = np.gradient(qdd, times, axis=0)
    return JointProfile(times, q, qd, qdd, qddd, discontinuity)


def retime_for_arm(
    path: TimedPath,
    arm: PandaArm,
    *,
    rate: float = 100.0,
    margin: float = 0.95,
    max_iterations: int = 8,
) -> TimedPath:
    """The path re-timed so the arm's joints respect their velocity, acceleration and
    jerk limits.

    The joint profile along the path (:func:`joint_profile`) is checked against
    :attr:`ArmConfig.max_velocity`, :attr:`~ArmConfig.max_acceleration` and
    :attr:`~ArmConfig.max_jerk`. If a ratio ``r`` exceeds 1, the path is slowed
    uniformly by ``k = max(r_v, sqrt(r_a), cbrt(r_j)) / margin``: its Cartesian
    :class:`~heapgrasp.geometry.motion.MotionLimits` become ``(v / k, a / k^2, j / k^3)``, which
    stretches ruckig's time-optimal profile by ``k`` and so divides every joint velocity,
    acceleration and jerk by ``k``, ``k^2``, ``k^3``; this repeats (finite differences are
    approximate) up to ``max_iterations`` times. Only the timing changes, not the poses;
    a path already within the limits is returned as is. Uniform slowing is simple and
    conservative: the whole path goes at the pace of its most demanding part.

    The joint path is the one :func:`joint_profile` finds; if it starts from a
    re-configured start (see :meth:`PandaArm.camera_joint_path`), put the arm there
    (:meth:`PandaArm.set_joint_positions`) before following the path with it.

    Parameters
    ----------
    path
        Timed ``cam2world`` path.
    arm
        The arm carrying the camera.
    rate
        Sampling rate of the check (Hz).
    margin
        Target fraction of the limits after a re-timing, in (0, 1].
    max_iterations
        Upper bound on re-timings.

    Returns
    -------
    TimedPath
        ``path`` itself, or a slower copy with the same poses and ``fps``.

    Raises
    ------
    UnreachableError
        If a pose of the path is out of reach.
    JointPathError
        If the arm cannot follow the path without a re-configuration (no timing helps),
        or the limits still fail after ``max_iterations`` re-timings.
    """
    if not (math.isfinite(margin) and 0.0 < margin <= 1.0):
        raise ValueError(f"margin must be in (0, 1], got {margin}")
    if max_iterations < 0:
        raise ValueError(f"max_iterations must be >= 0, got {max_iterations}")
    current = path
    rv = ra = rj = 0.0
    for iteration in range(max_iterations + 1):
        profile = joint_profile(current, arm, rate=rate)
        if profile.discontinuity is not None:
            pose = np.asarray(current.poses)[profile.discontinuity]
            p = ", ".join(f"{x:.3f}" for x in pose[:3, 3])
            raise JointPathError(
                f"the arm cannot follow this camera path continuously: at path sample "
                f"{profile.discontinuity} (camera at ({p}) m) a joint limit forces a "
                f"re-configuration (a joint jump > max_joint_jump = "
                f"{arm.config.max_joint_jump} rad), from any start configuration tried; "
                f"no timing can follow it (split the path or change its waypoints)"
            )
        rv, ra, rj = profile.limit_ratios(arm.config)
        if max(rv, ra, rj) <= 1.0:
            return current
        if iteration == max_iterations:
            break
        k = max(rv, math.sqrt(ra), rj ** (1.0 / 3.0), 1.0) / margin
        lim = current.limits
        new = MotionLimits(lim.max_velocity / k, lim.max_acceleration / k**2, lim.max_jerk / k**3)
        current = TimedPath(np.asarray(current.poses), new, current.fps)
    raise JointPathError(
        f"retime_for_arm: joint limits still exceeded after {max_iterations} re-timings "
        f"(velocity ratio {rv:.3f}, acceleration {ra:.3f}, jerk {rj:.3f})"
    )
