"""scripts/label_agreement.py: one tiny scene, a handful of grasps in physics (and by the
labeller), the record format, resuming, and the summary."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "label_agreement.py"


@pytest.fixture(scope="module")
def agreement() -> ModuleType:
    spec = importlib.util.spec_from_file_location("label_agreement", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["label_agreement"] = module
    spec.loader.exec_module(module)
    return module


def tiny(agreement: ModuleType, scenes: int = 1) -> object:
    return agreement.AgreementConfig(
        scenes=scenes,
        root_seed=3,
        points=4,
        yaws=6,
        positives=2,
        negatives=4,
        max_objects=2,
        all_set_every=0,
    )


def test_one_scene_gives_a_record_per_grasp(agreement: ModuleType) -> None:
    config = tiny(agreement)
    scene, records = agreement.run_scene(config, 0)
    assert scene["status"] == "ok" and scene["grasps"] == len(records) > 0
    assert len(records) <= 6 and scene["sampled"] == 24
    assert sum(scene["sampled_labels"].values()) == 24
    assert set(scene["objects"]) and scene["seconds_physics"] > 0
    assert sorted({r["grasp"] for r in records}) == [r["grasp"] for r in records]
    for rec in records:
        assert rec["scene"] == 0 and 0 <= rec["grasp"] < 24
        assert rec["grasp"] == 6 * rec["point"] + rec["yaw_index"]
        assert rec["weight"] >= 1.0 and rec["stratum"] in scene["sampled_labels"]
        assert rec["scene_seed"] == scene["scene_seed"]
        pose = np.asarray(rec["pose"])
        assert pose.shape == (3, 4)
        r = pose[:, :3]
        assert np.allclose(r.T @ r, np.eye(3), atol=1e-9)
        assert rec["physics"] in agreement.KINDS
        assert rec["physics_success"] == (rec["physics"] == "success")
        if rec["physics_success"]:
            assert rec["physics_object"] in scene["objects"]
            assert 0.0 < rec["physics_width_closed"] <= 0.08
        if rec["physics"].startswith("collision"):
            assert rec["stop_contacts"] and rec["physics_touched"]
        assert rec["target"] in scene["objects"]
        assert rec["target_shape"] == scene["objects"][rec["target"]]["shape"]
        json.dumps(rec)  # a JSONL line
        if scene["labelled"]:
            assert rec["label"] in (0, 1) and rec["label_reason"] == rec["stratum"]
            assert rec["label"] == (rec["label_reason"] == "success")
            assert 0.0 <= rec["label_width"] <= 0.08


def test_the_executed_grasps_are_stratified_by_verdict(agreement: ModuleType) -> None:
    strata = ["collision"] * 90 + ["success"] * 5 + ["empty"] * 3 + ["not-antipodal"] * 2
    picked, weights = agreement.select(strata, np.random.default_rng(0), 4, 9)
    got: dict[str, list[float]] = {}
    for i, w in zip(picked, weights, strict=True):
        got.setdefault(strata[i], []).append(w)
    # Positives capped at 4; the 9 negatives shared: empty and not-antipodal run out
    # (3 and 2), collision takes the rest.
    assert {k: len(v) for k, v in got.items()} == {
        "collision": 4,
        "success": 4,
        "empty": 3,
        "not-antipodal": 2,
    }
    assert got["collision"] == [22.5] * 4 and got["success"] == [1.25] * 4
    assert got["empty"] == [1.0] * 3
    assert sum(weights) == pytest.approx(100.0) and picked == sorted(picked)


def test_a_run_resumes_and_summarizes(agreement: ModuleType, tmp_path: Path) -> None:
    config = tiny(agreement)
    agreement.run(config, tmp_path, workers=1)

    def grasps() -> list[dict[str, object]]:
        rows = [json.loads(line) for line in (tmp_path / "grasps.jsonl").read_text().splitlines()]
        for row in rows:
            row.pop("seconds_physics")
            row.pop("cpu_seconds_physics")
        return rows

    first = grasps()
    assert 0 < len(first) <= 6
    # A kill between a scene's grasps and its scene line: the orphans are dropped and
    # the scene is run again, once.
    (tmp_path / "scenes.jsonl").write_text("")
    agreement.run(config, tmp_path, workers=1)
    assert grasps() == first
    summary = agreement.write_summary(tmp_path, "test")
    assert summary["grasps"] == len(first) and summary["scenes_ok"] == 1
    assert sum(summary["physics_kinds"].values()) == len(first)
    assert (tmp_path / "summary.md").read_text().startswith("# Grasp labeller against physics")
    with pytest.raises(SystemExit, match="other settings"):
        agreement.run(agreement.AgreementConfig(scenes=1, root_seed=4), tmp_path, workers=1)


def test_the_confusion_matrix_takes_physics_as_truth(agreement: ModuleType) -> None:
    def grasp(physics: str, label: int, reason: str) -> dict[str, object]:
        return {
            "physics": physics,
            "physics_success": physics == "success",
            "physics_object": 1 if physics == "success" else None,
            "physics_width_closed": 0.05,
            "seconds_physics": 0.1,
            "label": label,
            "label_reason": reason,
            "label_object": 1 if label else None,
            "label_width": 0.052 if label else None,
            "target_shape": "box",
        }

    grasps = [
        grasp("success", 1, "success"),
        grasp("success", 0, "collision"),
        grasp("dropped-shake", 1, "success"),
        grasp("collision-approach", 0, "collision"),
        grasp("collision-approach", 0, "collision"),
    ]
    scene = {"status": "ok", "layout": "pile", "split": "train", "object_set": "procedural"}
    scene |= {"objects_left": 2, "seconds_build": 1.0, "labelled": True, "seconds_label": 0.01}
    s = agreement.summarize(grasps, [scene])
    assert s["confusion"] == {"tp": 1, "fn": 1, "fp": 1, "tn": 2}
    assert s["agreement"] == 60.0 and s["precision"] == 0.5 and s["recall"] == 0.5
    assert s["width_error"]["mean_mm"] == 2.0
    assert s["by_shape"]["box"]["fp"] == 1 and s["by_shape"]["box"]["fn"] == 1
    rows = {(r["physics"], r["labeller"]): r["disagree"] for r in s["by_reason"]}
    assert (
        rows[("dropped-shake", "success")] == 1 and rows[("collision-approach", "collision")] == 0
    )


def test_a_plan_executes_the_same_grasps_again(agreement: ModuleType) -> None:
    config = tiny(agreement)
    _, records = agreement.run_scene(config, 0)
    plan = [{k: r[k] for k in ("grasp", "pose", "stratum", "weight")} for r in records[:3]]
    _, again = agreement.run_scene(config, 0, plan=plan)
    assert [r["grasp"] for r in again] == [p["grasp"] for p in plan]
    for a, b in zip(again, records[:3], strict=True):  # a fresh world each: the same physics
        assert (
            a["physics"] == b["physics"] and a["physics_width_closed"] == b["physics_width_closed"]
        )
        assert a["weight"] == b["weight"] and a["stratum"] == b["stratum"]
    wrong = [{**plan[0], "pose": (np.asarray(plan[0]["pose"]) + 0.01).tolist()}]
    with pytest.raises(ValueError, match="not the planned one"):
        agreement.run_scene(config, 0, plan=wrong)
