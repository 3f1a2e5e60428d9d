"""Time along a camera path: a jerk-limited, rest-to-rest parameterisation (ruckig, 1 DoF
along the arc length) sampled at the camera's frame rate (:func:`time_path`,
:class:`TimedPath`), and eq. 8 over a list of view waypoints (:func:`plan_waypoints`,
:func:`concatenate`)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from ruckig import InputParameter, Result, Ruckig, Trajectory  # type: ignore[import-untyped,import-not-found,unused-ignore]

from heapgrasp._core import NonFiniteError
from heapgrasp.geometry.motion.interpolation import interpolate, mat_to_quat, quat_to_mat, slerp
from heapgrasp.geometry.motion.sphere import ViewSphere
from heapgrasp.geometry.motion.validation import (
    FloatArray,
    as_pose,
    as_poses,
    norm,
    positive,
)


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
            object.__setattr__(self, name, positive(name, getattr(self, name)))


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
        seg = norm(np.diff(poses[:, :3, 3], axis=0))
        arc = np.concatenate([[0.0], np.cumsum(seg)])
        arc.flags.writeable = False
        self.arclength: FloatArray = arc
        self.length: float = float(arc[-1])
        self.limits: MotionLimits = limits
        self.fps: float = positive("fps", fps)
        self._quats = mat_to_quat(poses[:, :3, :3])
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
        out[:, :3, :3] = quat_to_mat(slerp(self._quats[i], self._quats[i + 1], alpha))
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
        rate = self.fps if fps is None else positive("fps", fps)
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
    arr = as_poses("poses", poses)
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
    wps = as_poses("waypoints", wps)
    prev = as_pose("start_pose", start_pose)
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
