"""Recording runs for the Rerun viewer: the recorder's entities, ``heapgrasp show`` and
``heapgrasp run --viz``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from fake_robot import FakeRobot, FakeScene, FakeTruth, RedSegmenter
from heapgrasp.cli import main
from heapgrasp.geometry.grid import GridFrame
from heapgrasp.loop.config import RunConfig
from heapgrasp.loop.protocol import run_clutter_removal
from heapgrasp.loop.stages import build_pipeline

pytest.importorskip("rerun")

from heapgrasp.viz.recorder import ENTITIES, RerunRecorder, recorded_entities

BOXES = [((0.11, 0.15, 0.035), (0.05, 0.04, 0.07)), ((0.20, 0.14, 0.03), (0.04, 0.04, 0.06))]


def test_a_recorded_phase_holds_every_entity(tmp_path: Path) -> None:
    scene = FakeScene(BOXES)
    robot = FakeRobot(scene)
    truth = FakeTruth(scene, robot)
    config = RunConfig()
    path = tmp_path / "phase.rrd"
    recorder = RerunRecorder(path, GridFrame((0.0, 0.0, 0.0), 0.30, 40), config.lam)
    pipeline = build_pipeline(
        config, robot, segmenter=RedSegmenter(), truth=truth, observer=recorder
    )
    phases, _ = run_clutter_removal(
        robot, pipeline.plan, truth=truth, max_attempts=1, on_outcome=pipeline.record_outcome
    )
    recorder.close()
    assert phases[0].outcome == "success"
    entities = recorded_entities(path)
    assert set(ENTITIES) <= entities, set(ENTITIES) - entities
    assert "/world/camera/image" in entities  # the fake camera delivers RGB
    # one frame logged per frame the phase integrated
    assert recorder.frames == phases[0].extra["frames"]


def test_recording_changes_nothing_the_phase_does(tmp_path: Path) -> None:
    def phase(observer: RerunRecorder | None) -> dict[str, object]:
        scene = FakeScene(BOXES)
        robot = FakeRobot(scene)
        truth = FakeTruth(scene, robot)
        pipeline = build_pipeline(
            RunConfig(), robot, segmenter=RedSegmenter(), truth=truth, observer=observer
        )
        planned = pipeline.plan()
        assert planned.grasp is not None
        return {"grasp": planned.grasp.pose.tolist(), "path": planned.camera_positions.tolist()}

    frame = GridFrame((0.0, 0.0, 0.0), 0.30, 40)
    recorder = RerunRecorder(tmp_path / "r.rrd", frame, 0.9)
    assert phase(recorder) == phase(None)
    recorder.close()


def test_show_records_a_fresh_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run"
    argv = ["run", "--method", "no-vp", "--objects", "2", "--set", "max_attempts=1"]
    assert main([*argv, "--out", str(out), "--quiet"]) == 0
    capsys.readouterr()
    assert main(["show", str(out)]) == 0
    text = capsys.readouterr().out
    recorded = [p["outcome"] for p in json.loads((out / "scenes.jsonl").read_text())["phases"]]
    assert f"outcomes {recorded}" in text
    rrd = out / "viz" / "scene-000.rrd"
    assert f"recording: {rrd}" in text
    entities = recorded_entities(rrd)
    assert set(ENTITIES) <= entities, set(ENTITIES) - entities
    assert "/world/camera/image" in entities  # rendered for the recording


def test_show_names_what_is_wrong(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["show", str(tmp_path / "nothing")]) == 2
    assert "holds no run (config.json not found)" in capsys.readouterr().err
    run_dir = tmp_path / "old"
    run_dir.mkdir()
    (run_dir / "config.json").write_text(json.dumps({**RunConfig().to_dict(), "stop_after": 2}))
    assert main(["show", str(run_dir)]) == 2
    assert "unknown parameter 'stop_after'" in capsys.readouterr().err
    (run_dir / "config.json").write_text(json.dumps(RunConfig(scenes=2).to_dict()))
    assert main(["show", str(run_dir), "--scene", "5"]) == 2
    assert "--scene 5: the run has scenes 0 to 1" in capsys.readouterr().err
