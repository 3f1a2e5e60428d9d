"""What a phase tells an observer as it runs (a recorder, a progress display).

:class:`PhaseObserver` is called by :class:`heapgrasp.loop.phase.Pipeline` at fixed
points of a phase; every method has a default that does nothing, so an observer
implements only what it shows. With no observer (the default) nothing is called and
nothing is computed for it. :mod:`heapgrasp.viz` records these events with rerun-sdk.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from heapgrasp import OccupancyGrid
from heapgrasp.perception.frames import Frame
from heapgrasp.planning.volumes import GraspCandidate
from heapgrasp.robot.grasping import Grasp, GraspOutcome

__all__ = ["PhaseObserver"]

F64 = npt.NDArray[np.float64]


class PhaseObserver:
    """Receives a phase's events; subclass and override what you need."""

    def phase_started(self, index: int, start: F64) -> None:
        """Phase ``index`` (0-based within the scene) begins with the camera at ``start``."""

    def frame(
        self, frame: Frame, mask: npt.NDArray[np.bool_] | None, grid: OccupancyGrid | None
    ) -> None:
        """A frame was captured and integrated: its silhouette (None for depth
        perception) and the occupancy grid right after it (None for depth perception)."""

    def waypoint(self, pose: F64, kind: str) -> None:
        """The camera is about to move to a waypoint: ``view`` (eq. 18), ``fixed`` (a
        baseline's), ``sweep`` (the rim sweep) or ``look-again`` (the start turned, where
        the phase found no grasp: ``RunConfig.look_again``)."""

    def candidates(self, candidates: Sequence[GraspCandidate]) -> None:
        """Grasp candidates were planned on the current grid (eq. 15, best first)."""

    def target(self, target: GraspCandidate | None) -> None:
        """The target grasp of eq. 16 (None: no candidate)."""

    def grasp(self, grasp: Grasp, outcome: GraspOutcome) -> None:
        """A grasp was executed and ended with ``outcome``."""

    def phase_ended(self, grasp: Grasp | None) -> None:
        """The phase planned ``grasp`` (None: no candidate)."""
