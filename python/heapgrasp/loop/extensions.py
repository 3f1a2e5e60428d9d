"""Extensions of HEAPGrasp's phase that the loop calls (not in the paper).

Each is an object built from :class:`~heapgrasp.loop.config.RunConfig` and asked one
question at one point of :meth:`heapgrasp.loop.phase.Pipeline.plan`; a phase without
them is the paper's (exactly ``L`` view waypoints).

* :class:`EarlyStop` — at a view waypoint, stop looking where no candidate view would
  carve enough of the target grasp's column to be worth its detour, and the target is
  sure enough (``stop_below``, ``stop_detour_weight``, ``stop_confidence``);
* :class:`RimSweep` — a phase that took every view waypoint without becoming sure goes
  on along the rim of the candidates until a grasp is sure (``sweep_degrees``,
  ``sweep_step``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from heapgrasp.geometry.motion import ViewSphere
from heapgrasp.loop.config import RunConfig
from heapgrasp.planning.selection import detour
from heapgrasp.planning.views import sweep_waypoints
from heapgrasp.planning.volumes import GraspCandidate

__all__ = ["EarlyStop", "RimSweep"]

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]


@dataclass(frozen=True)
class EarlyStop:
    """Stop viewing early (``RunConfig.stop_below`` > 0)."""

    below: float
    """The least eq. 14 score on the target's column, less its detour, worth a move."""
    detour_weight: float
    """Weight (per metre) of the path a look adds on the way to the grasp."""
    confidence: float
    """The least score of the target grasp for the phase to stop."""
    after: int = 1
    """The fewest view waypoints a phase visits before it may stop."""

    @classmethod
    def from_config(cls, config: RunConfig) -> EarlyStop | None:
        """The early stop of ``config``, or None where it is off."""
        if config.stop_below <= 0.0:
            return None
        return cls(config.stop_below, config.stop_detour_weight, config.stop_confidence)

    def applies(self, waypoint: int) -> bool:
        """Whether the test runs at view waypoint ``waypoint`` (0-based)."""
        return waypoint >= self.after

    def considers(self, target: GraspCandidate | None) -> bool:
        """Whether a phase with this target may stop at all."""
        return target is not None and target.score >= self.confidence

    def worth(self, region_scores: F32, candidates: F64, current: F64, target: F64) -> F64:
        """Each candidate's score on the target's region less its detour's weight."""
        return np.asarray(
            region_scores - self.detour_weight * detour(candidates, current, target),
            dtype=np.float64,
        )

    def stops(self, worth: F64) -> bool:
        """No candidate is worth its move."""
        return float(worth.max()) < self.below


@dataclass(frozen=True)
class RimSweep:
    """Sweep the rim of the candidates until a grasp is sure (``sweep_degrees`` > 0)."""

    degrees: float
    step: float
    confidence: float
    """The score (with the critic: probability) at which the sweep ends."""

    @classmethod
    def from_config(cls, config: RunConfig) -> RimSweep | None:
        """The sweep of ``config``, or None where it is off."""
        if config.sweep_degrees <= 0.0:
            return None
        return cls(config.sweep_degrees, config.sweep_step, config.stop_confidence)

    def waypoints(
        self, sphere: ViewSphere, current: F64, seen: F64, theta_max: float, V: int
    ) -> F64:
        """The sweep's waypoints on the rim (the lowest candidates, ``θ_max (V-1)/V``),
        turning toward the azimuths ``seen`` lacks (:func:`~heapgrasp.planning.views.
        sweep_waypoints`)."""
        rim = theta_max * (V - 1) / V
        return sweep_waypoints(
            sphere, current, seen, degrees=self.degrees, step=self.step, theta=rim
        )

    def sure(self, best: GraspCandidate | None) -> bool:
        """The sweep may end: the best grasp scores at least :attr:`confidence`."""
        return best is not None and best.score >= self.confidence
