"""heapgrasp bench sim: scene groups, argument errors, the table from real runs."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from heapgrasp.bench.sim import markdown_tables, run_bench, scene_groups
from heapgrasp.cli import main
from heapgrasp.loop.config import ConfigError, RunConfig


def test_scene_groups_are_four_equal_blocks() -> None:
    groups = scene_groups(20)
    assert [groups.count(g) for g in ("transparent", "opaque", "specular", "mixed")] == [5] * 4
    assert groups[:5] == ["transparent"] * 5 and groups[-1] == "mixed"
    assert scene_groups(1) == ["transparent"]


def test_unknown_methods_are_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(ConfigError, match="magic"):
        run_bench(RunConfig(), ["no-vp", "magic"], tmp_path / "b")
    assert main(["bench", "sim", "--methods", "magic", "--out", str(tmp_path / "c")]) == 2
    assert "magic" in capsys.readouterr().err


def test_tables_from_a_small_run(tmp_path: Path) -> None:
    base = RunConfig(scenes=1, objects=2, layout="packed", max_attempts=2)
    summaries = run_bench(base, ["no-vp"], tmp_path, progress=False, figures=False)
    text = (tmp_path / "table.md").read_text()
    assert text == markdown_tables(summaries, base)
    assert text.strip() in (tmp_path / "summary.md").read_text()  # the folder's page
    assert "| no-vp (antipodal grasps, critic) |" in text and "92.7 (458/494)" in text
    assert (tmp_path / "no-vp" / "results.json").exists()
    assert "| Success (%) | 95 % CI |" in text and "| Grasp planning / call (ms) |" in text
    # objects removed beside those left, the graspable ones among them, and the ceiling
    assert "| Removed | Left (graspable) | Ceiling (%) |" in text
    objects = summaries["no-vp"]["objects"]
    left = f"| {objects['objects_left']} ({objects['leftovers_graspable']})"
    assert left in text and f"| {100 * objects['removal_ceiling']:.1f} |" in text
    saved = json.loads((tmp_path / "summary.json").read_text())["no-vp"]
    # one grasp-planning call per phase's end and per waypoint that planned grasps
    phases = json.loads((tmp_path / "no-vp" / "results.json").read_text())["phases"]
    assert all(p["final_replanned"] for p in phases)  # no-vp never stops viewing early
    calls = [p["final_planning_s"] for p in phases] + [
        w["grasp_planning_s"]
        for p in phases
        for w in p.get("waypoints", [])
        if w.get("grasp_candidates") is not None
    ]
    assert calls and saved["grasp_planning_per_call_s"]["mean"] == pytest.approx(
        sum(calls) / len(calls)
    )
    if saved["grasps_attempted"]:
        low, high = saved["grasp_success_ci95"]
        assert low <= 100 * saved["grasp_success_rate"] <= high
    else:
        assert saved["grasp_success_ci95"] is None
