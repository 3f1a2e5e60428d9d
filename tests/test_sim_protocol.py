"""Clutter-removal stop rules, placing, and metrics."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
from heapgrasp.loop.metrics import Phase, aggregate, shortest_trajectory_ratio, trajectory_length
from heapgrasp.loop.protocol import PlanResult, StopReason, run_clutter_removal, stop_reason
from heapgrasp.sim.gripper import Grasp, GraspOutcome, PandaHand
from heapgrasp.sim.object_model import ObjectModel
from heapgrasp.sim.objects import ObjectLibrary
from heapgrasp.sim.robot import SimRobot
from heapgrasp.sim.truth import SimTruth, top_down_grasp
from heapgrasp.sim.world import SimWorld

DOWN = np.array([[1.0, 0, 0], [0, -1.0, 0], [0, 0, -1.0]])


def boxes(tmp: Path, n: int) -> list[ObjectModel]:
    out = []
    for k in range(n):
        size = 0.045 + 0.005 * k
        path = tmp / f"box{k}.obj"
        trimesh.creation.box(extents=(size, size, size)).export(path)
        out.append(
            ObjectModel(f"test/box{k}", "user", path, (path,), 0.1, "test", (size, size, size))
        )
    return out


def tcp_at(p: np.ndarray, yaw: float = 0.0) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    m = np.eye(4)
    m[:3, :3] = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ DOWN
    m[:3, 3] = p
    return m


def test_stop_rules() -> None:
    assert stop_reason(0, 0, True) == StopReason.CLEARED
    assert stop_reason(3, 2, True) == StopReason.TWO_FAILURES
    assert stop_reason(3, 1, False) == StopReason.NO_CANDIDATE
    assert stop_reason(3, 1, True) is None
    # without scene truth (a real robot) the count is unknown: never "cleared"
    assert stop_reason(None, 0, True) is None
    assert stop_reason(None, 2, True) == StopReason.TWO_FAILURES


def run(
    tmp: Path, planner: str, outcomes: list[str] | None = None
) -> tuple[list[Phase], StopReason, SimWorld]:
    models = boxes(tmp, 3)
    world = SimWorld(ObjectLibrary(models))
    world.reset(layout="packed", n_objects=3, category="mixed", seed=1, models=models)
    hand = PandaHand(world)

    def plan() -> PlanResult:
        if planner == "none":
            return PlanResult(None)
        cam = np.array([[0.15, 0.15, 0.5], [0.2, 0.15, 0.45]])
        if planner == "empty":
            return PlanResult(Grasp(tcp_at(np.array([0.02, 0.28, 0.03])), 0.07), cam, 1.0)
        oid = min(world.objects)
        return PlanResult(top_down_grasp(world, oid), cam, 1.0, target_object=oid)

    def told(grasp: Grasp, outcome: GraspOutcome) -> None:
        assert outcomes is not None
        outcomes.append(outcome.value)

    phases, reason = run_clutter_removal(
        SimRobot(hand),
        plan,
        truth=SimTruth(world, hand),
        on_outcome=None if outcomes is None else told,
    )
    return phases, reason, world


def test_scripted_planner_clears_the_table(tmp_path: Path) -> None:
    phases, reason, world = run(tmp_path, "object")
    with world:
        assert reason == StopReason.CLEARED, [p.outcome for p in phases]
        assert [p.outcome for p in phases] == ["success"] * 3
        assert not world.objects
        stats = aggregate(phases, objects_total=3)
        assert stats["grasp_success_rate"] == 1.0 and stats["objects_removed"] == 3
        assert set(stats["per_category"]) == {"transparent", "specular", "opaque"}
        assert stats["execution_time_s"]["mean"] > 1.0


def test_two_consecutive_failures_stop_the_run(tmp_path: Path) -> None:
    phases, reason, world = run(tmp_path, "empty")
    with world:
        assert reason == StopReason.TWO_FAILURES
        assert [p.outcome for p in phases] == ["empty", "empty"]
        assert len(world.objects) == 3
        assert aggregate(phases, 3)["grasp_success_rate"] == 0.0


def test_the_planner_is_told_every_outcome(tmp_path: Path) -> None:
    told: list[str] = []
    phases, _, world = run(tmp_path, "empty", told)
    with world:
        assert told == [p.outcome for p in phases] == ["empty", "empty"]
    told = []
    phases, _, world = run(tmp_path, "object", told)
    with world:
        assert told == ["success"] * 3
    told = []
    phases, _, world = run(tmp_path, "none", told)
    with world:
        assert told == []  # nothing executed


def test_no_candidate_stops_the_run(tmp_path: Path) -> None:
    phases, reason, world = run(tmp_path, "none")
    with world:
        assert reason == StopReason.NO_CANDIDATE
        assert phases[0].outcome == "no_candidate" and not phases[0].attempted


def test_metrics() -> None:
    path = np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0], [3.0, 4.0, 0.0]])
    assert trajectory_length(path) == pytest.approx(7.0)
    assert shortest_trajectory_ratio(path, [3.0, 4.0, 0.0]) == pytest.approx(140.0)
    assert trajectory_length(path[:1]) == 0.0
    with pytest.raises(ValueError, match="grasp_position"):
        shortest_trajectory_ratio(path, [0.0, 0.0, 0.0])
    phase = Phase(path, np.array([3.0, 4.0, 0.0]), "success", 2.0, 0.5, category="opaque")
    d = phase.to_dict()
    assert d["execution_time_s"] == 2.5 and d["shortest_trajectory_ratio"] == pytest.approx(140.0)
    stats = aggregate([phase], 1)
    assert stats["trajectory_length_m"] == {"mean": 7.0, "std": 0.0}
