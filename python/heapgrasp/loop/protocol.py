"""The clutter-removal protocol of HEAPGrasp §VI-C, on any robot.

A scene is handled until (i) every object has been picked and placed, (ii) two
consecutive grasp attempts fail, or (iii) no grasp candidate is found. A successful
grasp carries the object to a bin beside the workspace and opens the hand
(:func:`heapgrasp.robot.grasping.place`).

With a :class:`~heapgrasp.robot.interfaces.SceneTruth` (simulation) the protocol also
knows how many objects are left (rule i), which object each grasp took and what a
collision touched; without one (a real robot) rule (i) is left to the operator. After
every attempt the scene truth lets the objects come to rest and takes out those that
ended outside the workspace (VGN's simulation protocol): the phase records them as
``knocked_out`` (id → category), and they count neither as removed nor as left.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

import numpy as np

from heapgrasp.loop.metrics import Phase
from heapgrasp.robot.grasping import BIN_POSE, Grasp, GraspOutcome, execute_grasp, place
from heapgrasp.robot.interfaces import Contact, Robot, SceneTruth

__all__ = ["PlanResult", "StopReason", "run_clutter_removal", "stop_reason"]


class StopReason(StrEnum):
    """Why a clutter-removal run ended."""

    CLEARED = "cleared"
    TWO_FAILURES = "two_consecutive_failures"
    NO_CANDIDATE = "no_candidate"
    MAX_ATTEMPTS = "max_attempts"


def stop_reason(
    objects_left: int | None, consecutive_failures: int, candidate_found: bool
) -> StopReason | None:
    """The protocol's stop rules, checked in order; None means "keep going".
    ``objects_left`` None: unknown (no scene truth)."""
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


def _releaser(truth: SceneTruth | None, object_id: int | None) -> Callable[[], None] | None:
    """What :func:`~heapgrasp.robot.grasping.place` calls on release: the scene truth
    learns that the object left the scene."""
    if truth is None or object_id is None:
        return None
    return lambda: truth.placed(object_id)


def run_clutter_removal(
    robot: Robot,
    plan: Callable[[], PlanResult],
    *,
    truth: SceneTruth | None = None,
    max_attempts: int = 50,
    on_outcome: Callable[[Grasp, GraspOutcome], None] | None = None,
    bin_pose: np.ndarray = BIN_POSE,
) -> tuple[list[Phase], StopReason]:
    """Runs the protocol with a pick planner (called once per phase) and returns the
    phases and why it stopped.

    ``on_outcome``, when given, is told every executed grasp and how it ended (before
    the next phase is planned), e.g. :meth:`heapgrasp.loop.phase.Pipeline.record_outcome`.
    ``bin_pose`` is the TCP pose over the bin where a held object is released.
    """
    phases: list[Phase] = []
    consecutive = 0
    while True:
        if len(phases) >= max_attempts:
            return phases, StopReason.MAX_ATTEMPTS
        left = None if truth is None else truth.objects_left()
        if (reason := stop_reason(left, consecutive, True)) is not None:
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
        result = execute_grasp(robot, planned.grasp)
        held = None
        if truth is not None and result.outcome in (GraspOutcome.SUCCESS, GraspOutcome.EMPTY):
            held = truth.held_object()
        if on_outcome is not None:
            on_outcome(planned.grasp, result.outcome)
        target = held if held is not None else planned.target_object
        category = None if truth is None else truth.category(target)
        motion = planned.motion_time + result.duration
        if result.outcome == GraspOutcome.SUCCESS and (held is not None or truth is None):
            motion += place(robot, bin_pose, released=_releaser(truth, held))
            consecutive = 0
        else:
            consecutive += 1
            robot.arm.park()
        extra = dict(planned.extra)
        if result.outcome == GraspOutcome.COLLISION:
            contact = Contact(result.touched, result.parts)
            extra["collision"] = {
                "stage": result.stage,
                "touched": [] if truth is None else truth.touched(contact, planned.target_object),
                "parts": sorted(result.parts),
            }
        if truth is not None:  # after what the collision touched was named
            knocked = truth.settle()
            extra["knocked_out"] = {str(k): v for k, v in sorted(knocked.items())}
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
