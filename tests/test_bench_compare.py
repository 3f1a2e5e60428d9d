"""heapgrasp bench compare: two run directories on the same scenes."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from heapgrasp.bench.compare import CompareError, compare_runs
from heapgrasp.cli import main
from heapgrasp.results.stats import success_interval


def _write_run(out: Path, scenes: dict[int, list[tuple[str, float]]]) -> Path:
    """A run directory with one record per seed: (outcome, trajectory) per phase."""
    out.mkdir(parents=True)
    lines = []
    for i, (seed, phases) in enumerate(scenes.items()):
        record = {
            "scene": i,
            "seed": seed,
            "phases": [
                {
                    "outcome": o,
                    "grasp_position": None if o == "no_candidate" else [0.1, 0.1, 0.05],
                    "trajectory_length_m": t,
                }
                for o, t in phases
            ],
        }
        lines.append(json.dumps(record))
    lines.append('{"scene": 99, "seed": 7, "error": "boom"}')  # a failed scene is skipped
    (out / "scenes.jsonl").write_text("\n".join(lines) + "\n")
    return out


def test_compare_matches_scenes_by_seed(tmp_path: Path) -> None:
    a = _write_run(
        tmp_path / "a",
        {
            5: [("success", 1.0), ("empty", 1.0), ("no_candidate", 0.5)],
            6: [("success", 1.0)],
            8: [("success", 3.0)],
        },
    )
    # The same scenes in another order, seed 8 missing, seed 9 extra.
    b = _write_run(
        tmp_path / "b",
        {6: [("success", 2.0)], 5: [("success", 2.0), ("success", 2.0)], 9: [("empty", 2.0)]},
    )
    c = compare_runs(a, b)
    assert c["a"]["grasps_succeeded"] == 3 and c["a"]["grasps_attempted"] == 4
    assert c["a"]["grasp_success_ci"] == pytest.approx([100 * x for x in success_interval(3, 4)])
    assert c["a"]["trajectory_length_m"] == pytest.approx(1.5)
    assert c["b"]["scenes"] == 3 and c["b"]["grasp_success_rate"] == pytest.approx(0.75)
    d = c["success_difference"]
    # Common seeds 5 and 6: A 2/3, B 3/3.
    assert d["scenes"] == 2 and d["difference"] == pytest.approx(100 * (2 / 3 - 1))
    assert c["trajectory_ratio"] == pytest.approx(1.5 / 2.0)


def test_compare_cli(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a = _write_run(tmp_path / "a", {1: [("success", 1.0)], 2: [("success", 1.0)]})
    b = _write_run(tmp_path / "b", {1: [("success", 2.0)], 2: [("collision", 2.0)]})
    out = tmp_path / "c.json"
    assert main(["bench", "compare", str(a), str(b), "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "A - B: +50.0 points" in text and "trajectory A / B: 50.0 %" in text
    assert json.loads(out.read_text())["success_difference"]["difference"] == pytest.approx(50.0)


def test_compare_refuses_what_it_cannot_compare(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    a = _write_run(tmp_path / "a", {1: [("success", 1.0)]})
    b = _write_run(tmp_path / "b", {2: [("success", 1.0)]})
    with pytest.raises(CompareError, match="no scene"):
        compare_runs(a, b)
    with pytest.raises(CompareError, match="not a directory"):
        compare_runs(tmp_path / "missing", b)
    (tmp_path / "empty").mkdir()
    with pytest.raises(CompareError, match="no finished scene"):
        compare_runs(tmp_path / "empty", b)
    assert main(["bench", "compare", str(a), str(b)]) == 2
    assert "no scene (seed) in common" in capsys.readouterr().err
    assert main(["bench", "compare", str(a), str(a), "--level", "1.5"]) == 2
    assert "level must be in (0, 1), got 1.5" in capsys.readouterr().err


def _world(records_file: Path, objects: int, category: str) -> None:
    """Gives every record of a run the scene a run of ``objects`` ``category`` objects
    would have placed."""
    records = [json.loads(x) for x in records_file.read_text().splitlines()]
    for r in records:
        if "error" in r:
            continue
        r["category"] = category
        r["objects_requested"] = objects
        r["world"] = {
            "layout": "pile",
            "workspace": {"origin": [0.0, 0.0, 0.0], "size": 0.3},
            "objects": [
                {"id": i + 1, "name": f"procedural/box_{i:02d}", "category": category}
                for i in range(objects)
            ],
        }
    records_file.write_text("".join(json.dumps(r) + "\n" for r in records))


def test_compare_refuses_runs_on_other_scenes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    a = _write_run(tmp_path / "a", {1: [("success", 1.0)], 2: [("success", 1.0)]})
    b = _write_run(tmp_path / "b", {1: [("success", 2.0)], 2: [("collision", 2.0)]})
    same = _write_run(tmp_path / "same", {1: [("empty", 2.0)], 2: [("collision", 2.0)]})
    _world(a / "scenes.jsonl", 3, "mixed")
    _world(same / "scenes.jsonl", 3, "mixed")
    _world(b / "scenes.jsonl", 5, "transparent")
    assert compare_runs(a, same)["different_scenes"] == []
    with pytest.raises(CompareError, match=r"2 of the 2 common seeds hold different scenes"):
        compare_runs(a, b)
    assert main(["bench", "compare", str(a), str(b)]) == 2
    err = capsys.readouterr().err
    assert "seed 1:" in err and "'mixed' in A, 'transparent' in B" in err
    assert "--different-scenes" in err
    # asked for, compared anyway and said so
    assert main(["bench", "compare", str(a), str(b), "--different-scenes"]) == 0
    assert "WARNING: 2 paired seed(s) hold different scenes" in capsys.readouterr().out


def test_compare_pools_runs_on_other_seeds(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # Two pairs of runs on disjoint seeds: pooled, the comparison is over all four
    # scenes, as if each side had been one run.
    a1 = _write_run(tmp_path / "a1", {1: [("success", 1.0)], 2: [("empty", 1.0)]})
    b1 = _write_run(tmp_path / "b1", {1: [("success", 2.0)], 2: [("success", 2.0)]})
    a2 = _write_run(tmp_path / "a2", {101: [("success", 3.0)], 102: [("success", 3.0)]})
    b2 = _write_run(tmp_path / "b2", {101: [("collision", 2.0)], 102: [("success", 2.0)]})
    c = compare_runs([a1, a2], [b1, b2])
    assert c["a"]["paths"] == [str(a1), str(a2)] and c["a"]["scenes"] == 4
    assert (c["a"]["grasps_succeeded"], c["a"]["grasps_attempted"]) == (3, 4)
    assert (c["b"]["grasps_succeeded"], c["b"]["grasps_attempted"]) == (3, 4)
    assert c["a"]["trajectory_length_m"] == pytest.approx(2.0)
    assert c["success_difference"]["scenes"] == 4
    assert c["success_difference"]["difference"] == pytest.approx(0.0)
    assert c["trajectory_ratio"] == pytest.approx(1.0)
    # The CLI: --pool adds the second pair.
    out = tmp_path / "c.json"
    args = ["bench", "compare", str(a1), str(b1), "--pool", str(a2), str(b2), "--json", str(out)]
    assert main(args) == 0
    assert "over 4 common scenes" in capsys.readouterr().out
    assert json.loads(out.read_text())["b"]["paths"] == [str(b1), str(b2)]
    # A seed on one side twice (overlapping runs, or one run given twice) is refused.
    with pytest.raises(CompareError, match=r"seed 1 is in both"):
        compare_runs([a1, _write_run(tmp_path / "a3", {1: [("success", 1.0)]})], b1)
    with pytest.raises(CompareError, match="given twice"):
        compare_runs([a1, a1], b1)
    with pytest.raises(CompareError, match="no run directory"):
        compare_runs([], b1)
    assert main(["bench", "compare", str(a1), str(b1), "--pool", str(a1), str(b2)]) == 2
    assert "given twice" in capsys.readouterr().err
