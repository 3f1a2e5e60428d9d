"""``heapgrasp bench topk``: every planner's top grasps on the loop's own grids, labelled
on the true meshes, and the summary computed from exactly those labels."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from heapgrasp.bench.topk import KS, TopKConfig, reliability, run_scene, summarize
from heapgrasp.cli import main


def test_each_phase_ranks_every_planner_on_the_same_grid() -> None:
    config = TopKConfig(scenes=1, objects=3, method="no-vp", planners=("antipodal", "network"))
    record = run_scene(config, 0)
    phases = record["phases"]
    # one ranking per phase the driver planned; its executed grasps' outcomes recorded
    assert len(phases) == len(record["driver_outcomes"])
    executed = [o for o in record["driver_outcomes"] if o != "no_candidate"]
    assert executed == [p["driver_outcome"] for p in phases if "driver_outcome" in p]
    for phase in phases:
        assert set(phase["rankings"]) == {"antipodal", "network"}
        for ranking in phase["rankings"].values():
            n = min(max(KS), ranking["candidates"])
            assert len(ranking["labels"]) == len(ranking["scores"]) == n
            assert ranking["scores"] == sorted(ranking["scores"], reverse=True)  # best first
            for ok, reason, held in zip(
                ranking["labels"], ranking["reasons"], ranking["objects"], strict=True
            ):
                assert ok == (reason == "success") and ok == (held >= 0)
    # the summary is the labels' share, rank by rank
    summary = summarize([record], ("antipodal", "network"))
    for name in ("antipodal", "network"):
        labels = [v for p in phases for v in p["rankings"][name]["labels"][:1]]
        expected = sum(labels) / len(labels) if labels else None
        assert summary[name]["precision@1"] == expected
        assert summary[name]["labelled@1"] == len(labels)


def test_the_vgn_baseline_ranks_on_its_tsdf_and_takes_no_critic(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = TopKConfig(scenes=1, objects=2, method="vgn", planners=("antipodal", "network"))
    record = run_scene(config, 0)
    assert record["phases"], record
    for phase in record["phases"]:
        assert set(phase["rankings"]) == {"antipodal", "network"}
    argv = ["bench", "topk", "--scenes", "1", "--method", "vgn", "--quiet"]
    out = tmp_path / "critic"
    assert main([*argv, "--planners", "antipodal+critic", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "antipodal+critic" in err and "silhouette method" in err
    assert not out.exists()  # refused before anything is written


def test_the_command_writes_its_table_and_refuses_bad_settings(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "topk"
    argv = ["bench", "topk", "--scenes", "1", "--objects", "2", "--method", "no-vp"]
    assert main([*argv, "--planners", "antipodal", "--quiet", "--out", str(out)]) == 0
    payload = json.loads((out / "results.json").read_text())
    assert payload["summary"]["antipodal"]["phases"] >= 1
    assert "precision@1" in (out / "summary.md").read_text()
    assert (out / "reliability.png").stat().st_size > 0
    assert "reliability.png" in (out / "summary.md").read_text()
    capsys.readouterr()
    assert main([*argv, "--planners", "magic", "--out", str(tmp_path / "x")]) == 2
    assert "magic" in capsys.readouterr().err
    assert main([*argv, "--set", "lamb=0.5", "--out", str(tmp_path / "y")]) == 2
    assert "lamb" in capsys.readouterr().err
    assert not (tmp_path / "y").exists()


def test_reliability_bins_scores_and_measures_their_calibration() -> None:
    """Per bin the grasps, their mean score and the share held; the calibration error
    is the grasps' weighted mean gap, 0 where scores match the shares held."""
    scores = [0.55, 0.55, 0.92, 0.92, 0.92, 0.92, 1.0]
    labels = [True, False, True, True, True, False, True]
    r = reliability(scores, labels)
    assert r["grasps"] == 7
    assert [(b["from"], b["grasps"]) for b in r["bins"]] == [(0.5, 2), (0.9, 4), (0.95, 1)]
    assert r["bins"][1]["held"] == 0.75 and r["bins"][1]["mean_score"] == pytest.approx(0.92)
    gap = 2 * abs(0.55 - 0.5) + 4 * abs(0.92 - 0.75) + 1 * 0.0
    assert r["ece"] == pytest.approx(gap / 7)
    assert reliability([0.5, 0.5], [True, False])["ece"] == pytest.approx(0.0)
    assert reliability([], [])["ece"] is None
