"""heapgrasp.bench.breakdown: where a run's grasps fail (bench compare --breakdown)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest
from heapgrasp.bench.breakdown import (
    SCORE_BANDS,
    breakdown,
    candidates,
    collision_kind,
    format_breakdown,
    memory,
    objects_left,
    score_band,
    viewing,
)
from heapgrasp.bench.compare import compare_runs
from heapgrasp.cli import main


def _phase(
    outcome: str, score: float | None, *, stopped: bool = False, waypoints: int = 3
) -> dict[str, Any]:
    return {
        "outcome": outcome,
        "grasp_position": None if outcome == "no_candidate" else [0.1, 0.1, 0.05],
        "trajectory_length_m": 1.0,
        "target_grasp": None if score is None else {"score": score},
        "stopped_early": {"worth_max": 0.0} if stopped else None,
        "waypoints": [{}] * waypoints,
    }


@pytest.mark.parametrize(
    ("score", "band"),
    [
        (0.0, "[0.00, 0.70)"),
        (0.6999, "[0.00, 0.70)"),
        (0.7, "[0.70, 0.80)"),
        (0.9, "[0.90, 0.95)"),
        (0.95, "[0.95, 1.00]"),
        (1.0, "[0.95, 1.00]"),
        (3.5, "[0.95, 1.00]"),  # the planner's own scale, without a critic
        (-0.1, "[0.00, 0.70)"),
        (None, "no score"),
        (math.nan, "no score"),
        (True, "no score"),
        ("0.9", "no score"),
    ],
)
def test_score_band(score: object, band: str) -> None:
    assert score_band(score) == band


def test_every_band_edge_starts_its_band() -> None:
    labels = [score_band(lo) for lo in SCORE_BANDS[:-1]]
    assert len(set(labels)) == len(SCORE_BANDS) - 1
    assert all(
        label.startswith(f"[{lo:.2f},") for label, lo in zip(labels, SCORE_BANDS[:-1], strict=True)
    )


def test_viewing_names_the_early_stop() -> None:
    assert viewing(_phase("success", 0.9, stopped=True, waypoints=1)) == "stopped after 1 waypoint"
    assert viewing(_phase("success", 0.9, stopped=True, waypoints=2)) == (
        "stopped after 2 waypoints"
    )
    assert viewing(_phase("success", 0.9)) == "all waypoints"
    assert viewing({"outcome": "success"}) == "all waypoints"  # a fixed-view record


def test_candidates_counts_the_grid_the_grasp_came_from() -> None:
    assert candidates({"final_candidates": 1}) == "1 candidate"
    assert candidates({"final_candidates": 2}) == "2 candidates"
    assert candidates({"final_candidates": 7}) == "3+ candidates"
    # Where the viewing stopped early, the grasps planned there are the final grid's.
    stopped = {"stopped_early": {"grasp_candidates": 1}, "final_candidates": 4}
    assert candidates(stopped) == "1 candidate"
    assert candidates({"stopped_early": {"grasp_candidates": None}, "final_candidates": 2}) == (
        "2 candidates"
    )
    for record in (
        {},
        {"final_candidates": 0},
        {"final_candidates": True},
        {"final_candidates": "1"},
    ):
        assert candidates(record) == "not recorded"


def test_objects_left_names_the_clutter() -> None:
    assert objects_left({"objects_left": 5}) == "5 objects"
    assert objects_left({"objects_left": 1}) == "1 object"
    for record in ({}, {"objects_left": -1}, {"objects_left": True}, {"objects_left": 2.0}):
        assert objects_left(record) == "not recorded"


def test_breakdown_counts_each_attempt_once_per_table() -> None:
    phases = [
        _phase("success", 0.97, stopped=True, waypoints=1),
        _phase("empty", 0.91, stopped=True, waypoints=1),
        _phase("collision", 0.93, stopped=True, waypoints=2),
        _phase("success", 0.92),
        _phase("success", None),
        _phase("no_candidate", None),  # not an attempt
    ]
    b = breakdown(phases)
    assert list(b["score"]) == ["[0.90, 0.95)", "[0.95, 1.00]", "no score"]
    assert b["score"]["[0.90, 0.95)"] == {
        "succeeded": 1,
        "attempted": 3,
        "outcomes": {"empty": 1, "collision": 1},
    }
    assert b["score"]["no score"]["attempted"] == 1
    assert b["viewing"]["stopped after 1 waypoint"] == {
        "succeeded": 1,
        "attempted": 2,
        "outcomes": {"empty": 1},
    }
    assert b["viewing"]["all waypoints"]["succeeded"] == 2
    assert b["candidates"] == {"not recorded": b["candidates"]["not recorded"]}
    assert list(b["objects"]) == ["not recorded"]
    for key in ("score", "viewing", "candidates", "objects"):
        part = b[key]
        assert sum(c["attempted"] for c in part.values()) == 5
        assert sum(c["succeeded"] for c in part.values()) == 3
    text = format_breakdown("A", b)
    assert "stopped after 2 waypoints" in text and "0/1 (0.0 %)" in text
    assert text.splitlines()[1].split() == ["success", "collision", "empty"]
    assert b["collisions"] == {"not recorded": 1}


def test_collisions_are_counted_by_what_the_hand_touched() -> None:
    def hit(
        stage: str | None, touched: list[str], parts: list[str] | None = None
    ) -> dict[str, Any]:
        record: dict[str, Any] = {"stage": stage, "touched": touched}
        if parts is not None:
            record["parts"] = parts
        return {**_phase("collision", 0.9), "collision": record}

    phases = [
        hit("approach", ["object", "target"]),
        hit("approach", ["object", "target"]),
        hit("pregrasp", ["table"]),
        hit(None, []),
        _phase("collision", 0.9),  # a record from before contacts were kept
        {**_phase("empty", 0.9), "collision": {"stage": "approach", "touched": ["table"]}},
        hit("approach", ["target"], ["palm"]),
        hit("approach", ["object", "target"], ["finger", "palm"]),
        hit("approach", ["target"], []),  # no part seen: as before parts were kept
    ]
    assert collision_kind(phases[0]) == "approach: object+target"
    assert collision_kind(phases[3]) == "unknown: nothing"
    assert collision_kind(phases[6]) == "approach: target (palm)"
    assert collision_kind(phases[7]) == "approach: object+target (finger+palm)"
    b = breakdown(phases)
    assert b["collisions"] == {
        "approach: object+target": 2,
        "approach: object+target (finger+palm)": 1,
        "approach: target": 1,
        "approach: target (palm)": 1,
        "not recorded": 1,
        "pregrasp: table": 1,
        "unknown: nothing": 1,
    }
    text = format_breakdown("A", b)
    assert "collisions, by where and what the hand touched (with which part)" in text
    assert "approach: object+target (finger+palm)" in text
    assert "collisions" not in format_breakdown("A", breakdown([_phase("success", 0.9)]))


def test_a_run_with_scene_memory_is_broken_down_by_how_each_phase_began() -> None:
    phases = [
        {**_phase("success", 0.95), "memory": None},
        {**_phase("empty", 0.95), "memory": {"restored_voxels": 0, "kept": True}},
        {**_phase("success", 0.95), "memory": {"restored_voxels": 3, "kept": True}},
        {**_phase("collision", 0.9), "memory": {"restored_voxels": 40, "kept": False}},
        {**_phase("no_candidate", None), "memory": {"restored_voxels": 0, "kept": True}},
    ]
    assert [memory(p) for p in phases] == [
        "no memory yet",
        "memory kept",
        "memory kept",
        "memory dropped",
        "memory kept",
    ]
    b = breakdown(phases)
    assert list(b["memory"]) == ["no memory yet", "memory kept", "memory dropped"]
    assert b["memory"]["memory kept"] == {
        "succeeded": 1,
        "attempted": 2,
        "outcomes": {"empty": 1},
    }
    assert "by the scene memory" in format_breakdown("A", b)
    # A run without it has no such table.
    assert memory(_phase("success", 0.9)) is None
    plain = breakdown([_phase("success", 0.9)])
    assert "memory" not in plain
    assert "scene memory" not in format_breakdown("A", plain)


def test_breakdown_refuses_a_record_without_outcome() -> None:
    with pytest.raises(ValueError, match=r"phase 1: no outcome in the record \(got None\)"):
        breakdown([_phase("success", 0.9), {"target_grasp": {"score": 0.5}}])


def test_compare_breakdown_cli(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    def write(out: Path, phases: list[dict[str, Any]]) -> Path:
        out.mkdir()
        record = {"scene": 0, "seed": 3, "objects_total": 3, "phases": phases}
        (out / "scenes.jsonl").write_text(json.dumps(record) + "\n")
        return out

    a = write(tmp_path / "a", [_phase("success", 0.96, stopped=True, waypoints=1)])
    lone = {**_phase("success", 0.99), "final_candidates": 1}
    b = write(tmp_path / "b", [_phase("empty", 0.85), lone, _phase("success", 0.9)])
    c = compare_runs(a, b)
    assert c["b"]["breakdown"]["score"]["[0.80, 0.90)"]["outcomes"] == {"empty": 1}
    # The scene's objects_total (3): a failure leaves them all, a success takes one.
    assert c["b"]["breakdown"]["objects"] == {
        "3 objects": {"succeeded": 1, "attempted": 2, "outcomes": {"empty": 1}},
        "2 objects": {"succeeded": 1, "attempted": 1, "outcomes": {}},
    }
    assert c["b"]["breakdown"]["candidates"]["1 candidate"]["succeeded"] == 1
    assert main(["bench", "compare", str(a), str(b)]) == 0
    assert "by viewing" not in capsys.readouterr().out
    out = tmp_path / "c.json"
    assert main(["bench", "compare", str(a), str(b), "--breakdown", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "A: attempted grasps" in text and "stopped after 1 waypoint" in text
    assert "B: attempted grasps" in text and "2/3 (66.7 %)" in text
    assert "by the objects on the table" in text and "3 objects" in text
    saved = json.loads(out.read_text())
    assert saved["a"]["breakdown"]["viewing"]["stopped after 1 waypoint"]["succeeded"] == 1
