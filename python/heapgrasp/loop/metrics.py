"""Metrics of HEAPGrasp §VI-D, per phase and aggregated (overall and per category).

A *phase* starts with the hand-eye camera at its initial pose and ends at the grasp
(the place motion is not part of the camera trajectory). For each phase:

* **trajectory length** (m): length of the camera path, the sum of the distances
  between consecutive camera positions;
* **shortest trajectory ratio** (%): trajectory length / Euclidean distance from the
  phase's initial camera position to the grasp position, × 100;
* **execution time** (s): simulated motion time plus measured compute time.

Aggregates: grasp success rate (successes / attempts, with the counts), objects
removed out of the total, and mean/std of the three phase metrics.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = ["Phase", "aggregate", "shortest_trajectory_ratio", "trajectory_length"]

FloatArray = npt.NDArray[np.float64]


def trajectory_length(positions: npt.ArrayLike) -> float:
    """Length (m) of a polyline of ``(N, 3)`` positions (0 for fewer than two)."""
    p = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    if len(p) < 2:
        return 0.0
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())


def shortest_trajectory_ratio(positions: npt.ArrayLike, grasp_position: npt.ArrayLike) -> float:
    """Trajectory length / straight distance from the first position to the grasp, in %.

    Raises
    ------
    ValueError
        If the path is empty or starts at the grasp position.
    """
    p = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    if len(p) == 0:
        raise ValueError("positions: the camera path is empty")
    straight = float(np.linalg.norm(np.asarray(grasp_position, dtype=np.float64) - p[0]))
    if straight <= 0.0:
        raise ValueError("grasp_position: coincides with the initial camera position")
    return 100.0 * trajectory_length(p) / straight


@dataclass
class Phase:
    """One pick attempt: what the camera did, what was grasped, and how long it took."""

    camera_positions: FloatArray
    """``(N, 3)`` camera positions of the phase's frames (world, m)."""
    grasp_position: FloatArray | None
    """Grasp (TCP) position; None when no grasp was attempted."""
    outcome: str
    """``"success"``, ``"collision"``, ``"empty"`` or ``"no_candidate"``."""
    motion_time: float
    """Simulated motion time (s)."""
    compute_time: float
    """Measured planning/perception time (s)."""
    category: str | None = None
    """Optical category of the grasped (or targeted) object, if known."""
    object_id: int | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def attempted(self) -> bool:
        """Whether a grasp was executed."""
        return self.outcome != "no_candidate"

    @property
    def execution_time(self) -> float:
        """Motion plus compute time (s)."""
        return self.motion_time + self.compute_time

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Phase:
        """Inverse of :meth:`to_dict` (derived metrics are recomputed, not read)."""
        own = {
            "outcome",
            "category",
            "object_id",
            "camera_path",
            "grasp_position",
            "motion_time_s",
            "compute_time_s",
        }
        derived = {"trajectory_length_m", "execution_time_s", "shortest_trajectory_ratio"}
        grasp = data.get("grasp_position")
        return cls(
            camera_positions=np.asarray(data["camera_path"], dtype=np.float64).reshape(-1, 3),
            grasp_position=None if grasp is None else np.asarray(grasp, dtype=np.float64),
            outcome=str(data["outcome"]),
            motion_time=float(data["motion_time_s"]),
            compute_time=float(data["compute_time_s"]),
            category=data.get("category"),
            object_id=data.get("object_id"),
            extra={k: v for k, v in data.items() if k not in own | derived},
        )

    def to_dict(self) -> dict[str, Any]:
        """The phase as plain data, with its metrics."""
        out: dict[str, Any] = {
            "outcome": self.outcome,
            "category": self.category,
            "object_id": self.object_id,
            "camera_path": np.asarray(self.camera_positions).tolist(),
            "grasp_position": None
            if self.grasp_position is None
            else np.asarray(self.grasp_position).tolist(),
            "trajectory_length_m": trajectory_length(self.camera_positions),
            "motion_time_s": self.motion_time,
            "compute_time_s": self.compute_time,
            "execution_time_s": self.execution_time,
            **self.extra,
        }
        if self.grasp_position is not None and len(self.camera_positions):
            out["shortest_trajectory_ratio"] = shortest_trajectory_ratio(
                self.camera_positions, self.grasp_position
            )
        return out


def _stats(values: Sequence[float]) -> dict[str, float | None]:
    if not values:
        return {"mean": None, "std": None}
    a = np.asarray(values, dtype=np.float64)
    return {"mean": float(a.mean()), "std": float(a.std())}


def aggregate(phases: Sequence[Phase], objects_total: int) -> dict[str, Any]:
    """Aggregate metrics over phases, overall and per category of the grasped object."""

    def summary(sel: Sequence[Phase], total: int | None) -> dict[str, Any]:
        attempted = [p for p in sel if p.attempted]
        ok = [p for p in attempted if p.outcome == "success"]
        with_grasp = [p for p in attempted if p.grasp_position is not None]
        out: dict[str, Any] = {
            "grasps_attempted": len(attempted),
            "grasps_succeeded": len(ok),
            "grasp_success_rate": len(ok) / len(attempted) if attempted else None,
            "objects_removed": len(ok),
            "trajectory_length_m": _stats(
                [trajectory_length(p.camera_positions) for p in with_grasp]
            ),
            "shortest_trajectory_ratio": _stats(
                [
                    shortest_trajectory_ratio(p.camera_positions, p.grasp_position)
                    for p in with_grasp
                    if p.grasp_position is not None and len(p.camera_positions)
                ]
            ),
            "execution_time_s": _stats([p.execution_time for p in with_grasp]),
        }
        if total is not None:
            out["objects_total"] = total
        return out

    result = summary(phases, objects_total)
    cats = sorted({p.category for p in phases if p.category is not None})
    result["per_category"] = {
        c: summary([p for p in phases if p.category == c], None) for c in cats
    }
    return result
