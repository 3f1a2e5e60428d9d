"""The clutter-removal protocol of HEAPGrasp §VI-C and placing into the bin.

A scene is handled until (i) every object has been picked and placed, (ii) two
consecutive grasp attempts fail, or (iii) no grasp candidate is found. A successful
grasp carries the object to a bin beside the workspace, opens the hand, and the object
leaves the scene.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

import numpy as np

from heapgrasp.sim.gripper import Grasp, GraspOutcome, execute_grasp
from heapgrasp.sim.metrics import Phase
from heapgrasp.sim.robot import Robot
from heapgrasp.sim.world import SimWorld

__all__ = [
    "PlanResult",
    "StopReason",
    "place_in_bin",
    "run_clutter_removal",
    "stop_reason",
    "top_down_grasp",
    "touched_labels",
]

#: TCP pose above the bin (beside the workspace, -y side), pointing down.
BIN_POSE = np.array(
    [[1.0, 0.0, 0.0, 0.15], [0.0, -1.0, 0.0, -0.25], [0.0, 0.0, -1.0, 0.25], [0.0, 0.0, 0.0, 1.0]]
)


#: How far below an object's top a top-down grasp places the TCP at most (m).
FINGER_DEPTH = 0.035


class StopReason(StrEnum):
    """Why a clutter-removal run ended."""

    CLEARED = "cleared"
    TWO_FAILURES = "two_consecutive_failures"
    NO_CANDIDATE = "no_candidate"
    MAX_ATTEMPTS = "max_attempts"


def stop_reason(
    objects_left: int, consecutive_failures: int, candidate_found: bool
) -> StopReason | None:
    """The protocol's stop rules, checked in order; None means "keep going"."""
    if objects_left == 0:
        return StopReason.CLEARED
    if consecutive_failures >= 2:
        return StopReason.TWO_FAILURES
    if not candidate_found:
        return StopReason.NO_CANDIDATE
    return None


@dataclass
class PlanResult:
    """What a pick planner returns for one phase."""

    grasp: Grasp | None
    camera_positions: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """Camera positions of the frames captured in this phase (world, m)."""
    motion_time: float = 0.0
    """Simulated time of the camera motions of this phase (s)."""
    target_object: int | None = None
    compute_time: float | None = None
    """Planning time measured by the planner (s); None = the wall time of the whole
    ``plan()`` call (which then includes simulating the camera)."""
    extra: dict[str, Any] = field(default_factory=dict)
    """Planner-specific records (waypoints, targets, latencies), kept in the phase."""


def top_down_grasp(world: SimWorld, object_id: int, width: float = 0.08) -> Grasp:
    """A top-down grasp of an upright object from its true pose (a ground-truth baseline
    for tests and benchmarks, not a perception-based planner): TCP at the object's
    origin (raised so the fingers reach at most ``FINGER_DEPTH`` below its top), fingers
    closing along its x or y axis: among the axes along which the object
    is narrower than the opening, the one that keeps the fingers farther from the other
    objects."""
    pose = world.object_pose(object_id)
    extents = world.objects[object_id].model.extents
    others = [world.object_pose(o)[:3, 3] for o in world.objects if o != object_id]

    def clearance(yaw: float) -> float:
        y_axis = np.array([-np.sin(yaw), np.cos(yaw), 0.0])
        fingers = [pose[:3, 3] + s * 0.05 * y_axis for s in (-1.0, 1.0)]
        return float(min((np.linalg.norm(f - o) for f in fingers for o in others), default=1.0))

    # Fingers close along the TCP's y axis: object y at yaw = base, object x at base + 90°.
    base = float(np.arctan2(pose[1, 0], pose[0, 0]))
    options = [
        yaw for yaw, ext in ((base, extents[1]), (base + np.pi / 2, extents[0])) if ext < width
    ]
    yaw = max(options or [base], key=clearance)
    c, s = np.cos(yaw), np.sin(yaw)
    tcp = np.eye(4)
    tcp[:3, :3] = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ np.diag(
        [1.0, -1.0, -1.0]
    )
    # No deeper than the fingers reach: the palm is ~4.7 cm above the TCP.
    top = pose[2, 3] + 0.5 * extents[2]
    tcp[:3, 3] = (pose[0, 3], pose[1, 3], max(pose[2, 3], top - FINGER_DEPTH))
    return Grasp(tcp, width)


def touched_labels(world: SimWorld, bodies: Iterable[int], target: int | None) -> list[str]:
    """What a collision touched, by name: ``"table"``, ``"target"`` (the object the grasp
    was planned on, :attr:`PlanResult.target_object`), ``"object"`` (another object) or
    ``"other"``; sorted, without repeats."""
    by_body = {obj.body: oid for oid, obj in world.objects.items()}
    labels: set[str] = set()
    for body in bodies:
        if body == world.table:
            labels.add("table")
        elif body in by_body:
            labels.add("target" if by_body[body] == target else "object")
        else:
            labels.add("other")
    return sorted(labels)


def place_in_bin(hand: Robot, object_id: int) -> float:
    """Carries the held object to the bin, drops it, and removes it from the world.
    Returns the simulated time spent (s)."""
    t0 = hand.time
    up = hand.tcp.copy()
    up[2, 3] = max(up[2, 3], BIN_POSE[2, 3])
    hand.move_linear(up, speed=0.5)
    hand.move_linear(BIN_POSE, speed=0.5)
    hand.open()
    if object_id in hand.world.objects:
        hand.world.remove(object_id)
    hand.park()
    return hand.time - t0


def run_clutter_removal(
    hand: Robot,
    plan: Callable[[], PlanResult],
    *,
    max_attempts: int = 50,
    on_outcome: Callable[[Grasp, GraspOutcome], None] | None = None,
) -> tuple[list[Phase], StopReason]:
    """Runs the protocol with a pick planner (called once per phase) and returns the
    phases and why it stopped.

    ``on_outcome``, when given, is told every executed grasp and how it ended (before
    the next phase is planned), e.g. :meth:`heapgrasp.pipeline.Pipeline.record_outcome`.
    """
    world = hand.world
    total_failures = 0
    phases: list[Phase] = []
    consecutive = 0
    while True:
        if len(phases) >= max_attempts:
            return phases, StopReason.MAX_ATTEMPTS
        if (reason := stop_reason(len(world.objects), consecutive, True)) is not None:
            return phases, reason
        t0 = time.perf_counter()
        planned = plan()
        compute = time.perf_counter() - t0
        if planned.compute_time is not None:
            compute = planned.compute_time
        if planned.grasp is None:
            phases.append(
                Phase(
                    planned.camera_positions,
                    None,
                    "no_candidate",
                    planned.motion_time,
                    compute,
                    extra=planned.extra,
                )
            )
            return phases, StopReason.NO_CANDIDATE
        result = execute_grasp(hand, planned.grasp)
        if on_outcome is not None:
            on_outcome(planned.grasp, result.outcome)
        held = result.object_id
        target = held if held is not None else planned.target_object
        category = world.objects[target].category.value if target in world.objects else None
        motion = planned.motion_time + result.duration
        if result.outcome == GraspOutcome.SUCCESS and held is not None:
            motion += place_in_bin(hand, held)
            consecutive = 0
        else:
            consecutive += 1
            total_failures += 1
            hand.park()
        extra = dict(planned.extra)
        if result.outcome == GraspOutcome.COLLISION:
            extra["collision"] = {
                "stage": result.stage,
                "touched": touched_labels(world, result.touched, planned.target_object),
                "parts": sorted(result.parts),
            }
        phases.append(
            Phase(
                camera_positions=planned.camera_positions,
                grasp_position=planned.grasp.pose[:3, 3].copy(),
                outcome=result.outcome.value,
                motion_time=motion,
                compute_time=compute,
                category=category,
                object_id=target,
                extra=extra,
            )
        )
