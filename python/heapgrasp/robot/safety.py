"""Safety checks that run before any command reaches the arm.

A command is refused (:class:`~heapgrasp.robot.errors.SafetyError`, nothing sent) when
any pose it would pass through puts the TCP or the camera outside the configured
workspace box, or when its speeds or accelerations exceed the configured caps. Paths
are checked whole, sample by sample, before the first sample is streamed: a path that
would leave the box half-way never starts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from heapgrasp.robot.config import Limits, Workspace
from heapgrasp.robot.errors import SafetyError

__all__ = [
    "PathCheck",
    "check_inside",
    "check_joint_path",
    "check_move",
    "check_path",
    "measure_path",
    "slowdown",
]

F64 = npt.NDArray[np.float64]


def check_inside(workspace: Workspace, points: npt.ArrayLike, what: str) -> None:
    """Refuses if any of the ``(N, 3)`` world points (of ``what``: "TCP", "camera") lies
    outside the workspace box."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if not np.isfinite(p).all():
        raise SafetyError(f"{what}: a pose is not finite")
    inside = workspace.contains(p)
    if not inside.all():
        i = int(np.flatnonzero(~inside)[0])
        x, y, z = p[i]
        raise SafetyError(
            f"{what} would leave the workspace box at sample {i} of {len(p)}: "
            f"({x:.3f}, {y:.3f}, {z:.3f}) m is outside min {list(workspace.min)} / "
            f"max {list(workspace.max)}; nothing was sent"
        )


def check_move(limits: Limits, speed: float, acceleration: float) -> None:
    """Refuses a linear move whose commanded speed or acceleration exceeds the caps."""
    if not (np.isfinite(speed) and 0 < speed <= limits.tool_speed):
        raise SafetyError(
            f"tool speed {speed} m/s is outside (0, {limits.tool_speed}] ([limits] tool_speed); "
            "nothing was sent"
        )
    if not (np.isfinite(acceleration) and 0 < acceleration <= limits.tool_acceleration):
        raise SafetyError(
            f"tool acceleration {acceleration} m/s² is outside (0, {limits.tool_acceleration}] "
            "([limits] tool_acceleration); nothing was sent"
        )


@dataclass(frozen=True)
class PathCheck:
    """The largest speeds a checked path reaches."""

    tcp_speed: float
    camera_speed: float
    rotation_speed: float
    acceleration: float


def _rotation_angles(r0: F64, r1: F64) -> F64:
    """Angle (rad) of each relative rotation ``r0[i]ᵀ r1[i]``."""
    rel = np.einsum("nji,njk->nik", r0, r1)
    cos = (np.trace(rel, axis1=1, axis2=2) - 1.0) / 2.0
    return np.asarray(np.arccos(np.clip(cos, -1.0, 1.0)))


#: Acceleration is measured over this interval (s): the servo controller's lookahead
#: smooths the kinks of a path's sample polyline, which a per-cycle difference would
#: count as large accelerations.
ACCELERATION_WINDOW = 0.04


def measure_path(
    times: npt.ArrayLike, tcp2world: npt.ArrayLike, cam2tcp: npt.ArrayLike
) -> PathCheck:
    """The largest finite-difference TCP and camera speeds, TCP angular speed and TCP
    acceleration of a timed TCP path (``(N, 4, 4)`` world poses at ``times``)."""
    t = np.asarray(times, dtype=np.float64).reshape(-1)
    tcp = np.asarray(tcp2world, dtype=np.float64).reshape(-1, 4, 4)
    if len(t) != len(tcp) or len(t) == 0:
        raise SafetyError(f"a path needs one time per pose, got {len(t)} times, {len(tcp)} poses")
    if not np.isfinite(t).all() or (np.diff(t) <= 0).any():
        raise SafetyError("a path's times must be finite and increasing")
    if len(t) < 2:
        return PathCheck(0.0, 0.0, 0.0, 0.0)
    cam = tcp @ np.asarray(cam2tcp, dtype=np.float64)
    dt = np.diff(t)
    v_tcp = np.diff(tcp[:, :3, 3], axis=0) / dt[:, None]
    v_cam = np.linalg.norm(np.diff(cam[:, :3, 3], axis=0), axis=1) / dt
    w = _rotation_angles(tcp[:-1, :3, :3], tcp[1:, :3, :3]) / dt
    acc = 0.0
    stride = max(1, round(ACCELERATION_WINDOW / float(np.median(dt))))
    coarse = np.unique(np.r_[np.arange(0, len(t), stride), len(t) - 1])
    if len(coarse) > 2:
        tc, pc = t[coarse], tcp[coarse, :3, 3]
        vc = np.diff(pc, axis=0) / np.diff(tc)[:, None]
        mid = (tc[1:] + tc[:-1]) / 2
        acc = float((np.linalg.norm(np.diff(vc, axis=0), axis=1) / np.diff(mid)).max())
    return PathCheck(
        float(np.linalg.norm(v_tcp, axis=1).max()), float(v_cam.max()), float(w.max()), acc
    )


def slowdown(checked: PathCheck, limits: Limits, joint_speed: float = 0.0) -> float:
    """How many times slower a path must go so that every cap holds: speeds fall as
    ``1/k`` and accelerations as ``1/k²`` when its timing is stretched by ``k`` (the
    finite-difference estimates only approximately: callers measure again); at least 1."""
    return max(
        1.0,
        checked.tcp_speed / limits.tool_speed,
        checked.camera_speed / limits.tool_speed,
        checked.rotation_speed / limits.tool_rotation_speed,
        math.sqrt(checked.acceleration / limits.tool_acceleration),
        joint_speed / limits.joint_speed,
    )


def check_path(
    workspace: Workspace,
    limits: Limits,
    times: npt.ArrayLike,
    tcp2world: npt.ArrayLike,
    cam2tcp: npt.ArrayLike,
    *,
    tolerance: float = 1.05,
) -> PathCheck:
    """Checks a timed TCP path (``(N, 4, 4)`` world poses at ``times``) before it is
    streamed: every TCP and camera position inside the box, and the speeds of
    :func:`measure_path` within the caps (times ``tolerance``, for the differencing of
    a path timed exactly at a cap)."""
    tcp = np.asarray(tcp2world, dtype=np.float64).reshape(-1, 4, 4)
    cam = tcp @ np.asarray(cam2tcp, dtype=np.float64)
    check_inside(workspace, tcp[:, :3, 3], "the TCP")
    check_inside(workspace, cam[:, :3, 3], "the camera")
    checked = measure_path(times, tcp, cam2tcp)
    caps = (
        ("TCP speed", checked.tcp_speed, limits.tool_speed, "m/s", "tool_speed"),
        ("camera speed", checked.camera_speed, limits.tool_speed, "m/s", "tool_speed"),
        (
            "TCP rotation",
            checked.rotation_speed,
            limits.tool_rotation_speed,
            "rad/s",
            "tool_rotation_speed",
        ),
        (
            "TCP acceleration",
            checked.acceleration,
            limits.tool_acceleration,
            "m/s²",
            "tool_acceleration",
        ),
    )
    for what, value, cap, unit, key in caps:
        if value > cap * tolerance:
            raise SafetyError(
                f"the path's {what} reaches {value:.3f} {unit}, above the cap {cap} "
                f"([limits] {key}); nothing was sent"
            )
    return checked


def joint_speed(times: npt.ArrayLike, joints: npt.ArrayLike) -> float:
    """The largest finite-difference joint speed of ``(N, J)`` joint positions."""
    t = np.asarray(times, dtype=np.float64).reshape(-1)
    q = np.asarray(joints, dtype=np.float64).reshape(len(t), -1)
    if len(t) < 2:
        return 0.0
    return float((np.abs(np.diff(q, axis=0)) / np.diff(t)[:, None]).max())


def check_joint_path(limits: Limits, times: npt.ArrayLike, joints: npt.ArrayLike) -> float:
    """Checks the joint speeds along a path (``(N, 6)`` joint positions at ``times``, from
    the controller's inverse kinematics) against ``[limits] joint_speed``; returns the
    largest."""
    t = np.asarray(times, dtype=np.float64).reshape(-1)
    q = np.asarray(joints, dtype=np.float64).reshape(len(t), -1)
    if len(t) < 2:
        return 0.0
    qd = np.abs(np.diff(q, axis=0)) / np.diff(t)[:, None]
    top = float(qd.max())
    if top > limits.joint_speed * 1.05:
        j = int(np.argmax(qd.max(axis=0)))
        raise SafetyError(
            f"the path turns joint {j} at {top:.3f} rad/s, above the cap {limits.joint_speed} "
            "([limits] joint_speed); nothing was sent"
        )
    return top
