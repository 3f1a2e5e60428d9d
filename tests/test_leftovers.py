"""What a run leaves behind: settling after an attempt (objects knocked out of the
workspace), each leftover described and tried on its true mesh, and the run's counts."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pybullet as pb
import pytest
from conftest import box_model
from fake_robot import FakeRobot, FakeScene, FakeTruth, RedSegmenter
from heapgrasp.loop.config import RunConfig
from heapgrasp.loop.protocol import StopReason, run_clutter_removal
from heapgrasp.loop.stages import build_pipeline
from heapgrasp.results.summary import leftover_summary
from heapgrasp.sim.leftovers import describe_leftovers
from heapgrasp.sim.objects import ObjectLibrary
from heapgrasp.sim.optics import Category
from heapgrasp.sim.truth import SimTruth
from heapgrasp.sim.world import SimWorld


def _at(x: float, y: float, z: float, tilt: float = 0.0) -> np.ndarray:
    pose = np.eye(4)
    c, s = np.cos(tilt), np.sin(tilt)
    pose[:3, :3] = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    pose[:3, 3] = (x, y, z)
    return pose


def test_settle_takes_out_what_left_the_workspace(tmp_path: Path) -> None:
    small = box_model(tmp_path, (0.04, 0.04, 0.06), "small")
    with SimWorld(ObjectLibrary([small]), seed=0) as world:
        inside = world.spawn(small, _at(0.15, 0.15, 0.03), Category.OPAQUE)
        outside = world.spawn(small, _at(0.15, 0.15, 0.03), Category.SPECULAR)
        # knocked off the cube's side onto the table beyond it
        pb.resetBasePositionAndOrientation(
            outside.body, [0.40, 0.15, 0.03], [0, 0, 0, 1], physicsClientId=world.client
        )
        truth = SimTruth(world)
        assert truth.settle() == {outside.id: "specular"}
        assert list(world.objects) == [inside.id] and truth.objects_left() == 1
        assert truth.settle() == {}  # nothing more moves out


def test_leftovers_are_described_and_tried_on_their_meshes(tmp_path: Path) -> None:
    small = box_model(tmp_path, (0.04, 0.05, 0.06), "small")
    # wider than the Panda's 8 cm opening both ways, and lying flat: no grasp holds it
    slab = box_model(tmp_path, (0.12, 0.12, 0.02), "slab")
    with SimWorld(ObjectLibrary([small, slab]), seed=0) as world:
        a = world.spawn(small, _at(0.08, 0.15, 0.03), Category.OPAQUE)
        b = world.spawn(slab, _at(0.20, 0.15, 0.01), Category.TRANSPARENT)
        world.settle()
        out = describe_leftovers(world, np.random.default_rng(0))
        assert [o["object_id"] for o in out] == [a.id, b.id]
        box, flat = out
        assert box["name"] == "test/small" and box["category"] == "opaque"
        assert box["upright"] and box["tilt_deg"] < 5.0
        assert box["graspable"] and 0 < box["grasps_held"] <= box["grasps_tried"]
        assert box["border_m"] == pytest.approx(0.06, abs=0.005)
        assert flat["graspable"] is False and flat["grasps_held"] == 0
        assert sum(flat["failures"].values()) == flat["grasps_tried"] > 0
        # the box's x = 0.10 face and the slab's near edge (x = 0.14) are 4 cm apart
        assert box["neighbour_m"] == pytest.approx(0.04, abs=0.01)
        # the same seed, the same verdicts
        again = describe_leftovers(world, np.random.default_rng(0))
        assert again == out


def test_a_box_on_its_side_is_lying(tmp_path: Path) -> None:
    tall = box_model(tmp_path, (0.04, 0.04, 0.10), "tall")
    with SimWorld(ObjectLibrary([tall]), seed=0) as world:
        world.spawn(tall, _at(0.15, 0.15, 0.02, tilt=np.pi / 2), Category.OPAQUE)
        world.settle()
        (lying,) = describe_leftovers(world, np.random.default_rng(0))
        assert not lying["upright"] and lying["tilt_deg"] == pytest.approx(90.0, abs=5.0)
        assert lying["neighbour_m"] is None


def _record(outcomes: list[str], total: int, leftovers: list[dict[str, Any]] | None) -> Any:
    phases: list[dict[str, Any]] = [{"outcome": o} for o in outcomes]
    phases[-1]["knocked_out"] = {"7": "opaque"}
    record: dict[str, Any] = {"objects_total": total, "phases": phases}
    if leftovers is not None:
        record["leftovers"] = leftovers
    return record


def _left(graspable: bool, name: str = "procedural/box_01") -> dict[str, Any]:
    return {
        "name": name,
        "category": "opaque",
        "upright": False,
        "neighbour_m": 0.0,
        "border_m": 0.01,
        "graspable": graspable,
    }


def test_the_run_counts_removed_knocked_out_and_left() -> None:
    records = [
        _record(["success", "success", "no_candidate"], 5, [_left(True), _left(False)]),
        _record(["empty", "success", "success"], 4, [_left(True)]),
    ]
    s = leftover_summary(records)
    assert s["objects_total"] == 9 and s["objects_removed"] == 4
    assert s["objects_knocked_out"] == 2 and s["objects_left"] == 3
    assert s["leftovers_graspable"] == 2
    assert s["removal_ceiling"] == pytest.approx(6 / 9)
    assert s["graspable_left_rate"] == pytest.approx(2 / 9)
    assert s["leftovers"]["lying"] == 3 and s["leftovers"]["touching"] == 3
    assert s["leftovers"]["ungraspable_by_name"] == {"procedural/box_01": 1}
    # records without the analysis (a real robot's): the left are not counted
    real = leftover_summary([_record(["success"], 3, None)])
    assert real["objects_removed"] == 1 and real["objects_left"] is None
    assert real["removal_ceiling"] is None


def test_a_run_writes_its_summary_and_a_figure(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from heapgrasp.cli import main

    out = tmp_path / "run"
    argv = ["run", "--method", "no-vp", "--objects", "2", "--layout", "packed", "--quiet"]
    assert main([*argv, "--set", "max_attempts=1", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    summary = (out / "summary.md").read_text()
    table = printed.split("results:")[0].strip()
    assert table and table in summary  # the printed table, kept
    assert "objects:" in summary and "removal ceiling" in summary
    assert (out / "summary.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert f"summary: {out / 'summary.md'}, {out / 'summary.png'}" in printed


class _KnockingTruth(FakeTruth):
    """The fake robot's truth, whose every settle takes out all the objects still there
    (as if the attempt had swept them off the table)."""

    def settle(self) -> dict[int, str | None]:
        gone = dict.fromkeys(self.scene.ids, "opaque")
        for oid in gone:
            self.scene.meshes.remove(oid)
            del self.scene.ids[oid]
        return gone


def test_objects_knocked_out_are_recorded_and_can_clear_the_scene() -> None:
    scene = FakeScene(
        [((0.11, 0.15, 0.035), (0.05, 0.04, 0.07)), ((0.20, 0.14, 0.03), (0.04, 0.04, 0.06))]
    )
    robot = FakeRobot(scene)
    truth = _KnockingTruth(scene, robot)
    pipeline = build_pipeline(
        RunConfig(method="no-vp"), robot, segmenter=RedSegmenter(), truth=truth
    )
    phases, reason = run_clutter_removal(robot, pipeline.plan, truth=truth)
    assert reason == StopReason.CLEARED and len(phases) == 1
    (phase,) = phases
    knocked = phase.extra["knocked_out"]
    removed = int(phase.outcome == "success")
    assert len(knocked) == 2 - removed and set(knocked.values()) == {"opaque"}
    record = {"scene": 0, "objects_total": 2, "phases": [phase.to_dict()], "leftovers": []}
    s = leftover_summary([record])
    assert s["objects_knocked_out"] == 2 - removed and s["objects_left"] == 0
    assert s["objects_removed"] == removed
