"""``heapgrasp viewsphere bench`` (seed 001's benchmark): outputs, resume, objects from a
folder, bad input, the sensor model and executing the found grasps."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from heapgrasp.cli import main
from heapgrasp.viewsphere.episode import POLICIES
from heapgrasp.viewsphere.report import classify, summarize


@pytest.fixture(autouse=True)
def _cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Object files go to the test's folder, not the user's cache."""
    monkeypatch.setenv("HEAPGRASP_CACHE", str(tmp_path / "cache"))


FAST = ["--workers", "1", "--quiet", "--no-figures", "--set", "bfs_max_sets=40"]


def _run(out: Path, *extra: str) -> int:
    return main(["viewsphere", "bench", "--out", str(out), *FAST, *extra])


def test_a_small_run_writes_results_a_table_and_resumes(tmp_path: Path) -> None:
    out = tmp_path / "run"
    args = ["--objects", "005_tomato_soup_can", "--poses", "2", "--no-execute"]
    assert _run(out, *args) == 0
    results = json.loads((out / "results.json").read_text())
    assert set(results["policies"]) == set(POLICIES)  # all by default
    can = results["policies"]["bfs"]["objects"]["005_tomato_soup_can"]
    assert len(can["success_at_step"]) == 7 and len(can["poses"]) == 2
    assert all(np.diff(can["success_at_step"]) >= 0)
    for name in ("random", "brick", "heuristic-2d", "heuristic-3d"):  # BFS: the fewest steps
        other = results["policies"][name]["objects"]["005_tomato_soup_can"]
        assert can["mean_steps"] <= other["mean_steps"]
        for p in other["poses"]:  # one decision per move, timed; one step of arc per move
            assert len(p["decisions_s"]) == p["steps"]
            assert p["travelled_steps"] == pytest.approx(p["steps"])
    gain = results["policies"]["information-gain"]["objects"]["005_tomato_soup_can"]
    for p in gain["poses"]:  # viewpoints anywhere: at least a step of arc each
        assert p["path"] == [] and len(p["decisions_s"]) == p["steps"]
        assert p["travelled_steps"] >= p["steps"] - 1e-9
    row = results["table1"]["objects"]["005_tomato_soup_can"]
    assert row["viewpoints"] == gain["mean_steps"]
    assert row["effective_steps"] == gain["mean_travelled_steps"]
    paper = {"step_reduction_pct": 41.0, "time_reduction_pct": 73.0}
    assert results["table1"]["paper_mean"] == paper
    assert set(results["bfs_ratios"]) == set(POLICIES) - {"bfs", "information-gain"}
    table = (out / "table.md").read_text()
    assert "(Fig. 11)" in table and "(Table 1)" in table and "## Decision time" in table
    assert table.strip() in (out / "summary.md").read_text()
    pose = can["poses"][0]
    assert {"path", "steps", "grasp", "quality_deg", "executed", "views_deg"} <= set(pose)
    assert pose["executed"] is None  # --no-execute
    assert "| 005_tomato_soup_can |" in (out / "table.md").read_text()
    lines = (out / "records" / "005_tomato_soup_can.jsonl").read_text().splitlines()
    assert len(lines) == 2
    # A rerun finds every pose done and runs nothing.
    assert _run(out, *args) == 0
    assert len((out / "records" / "005_tomato_soup_can.jsonl").read_text().splitlines()) == 2
    # A run stopped half-way (one pose recorded, a torn line) continues from there.
    (out / "records" / "005_tomato_soup_can.jsonl").write_text(lines[1] + '\n{"pose": 0, ')
    assert _run(out, *args) == 0
    # the torn fragment was cut, so the pose run again is a whole line of its own
    rerun = (out / "records" / "005_tomato_soup_can.jsonl").read_text().splitlines()
    assert len(rerun) == 2 and sorted(json.loads(x)["pose"] for x in rerun) == [0, 1]
    again = json.loads((out / "results.json").read_text())
    assert (
        again["policies"]["bfs"]["objects"]["005_tomato_soup_can"]["success_at_step"]
        == (can["success_at_step"])
    )


def test_a_second_run_into_the_same_folder_is_refused_while_the_first_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from heapgrasp.results.records import RunDir

    out = tmp_path / "run"
    holder = RunDir(out).lock()  # the first run, still going
    try:
        args = ["--objects", "005_tomato_soup_can", "--poses", "1", "--no-execute"]
        assert _run(out, *args) == 2
        assert "is being written by" in capsys.readouterr().err
        assert not (out / "records").exists()  # it did none of the work
    finally:
        holder.unlock()


def test_other_settings_in_the_same_folder_are_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    base = ["--objects", "025_mug", "--poses", "1", "--no-execute", "--policies", "brick"]
    assert _run(out, *base) == 0
    before = (out / "results.json").read_text()
    capsys.readouterr()
    assert _run(out, *base, "--seed", "3") == 2  # refused
    assert "other settings (seed)" in capsys.readouterr().err
    assert (out / "results.json").read_text() == before


def test_the_same_seed_gives_the_same_episodes(tmp_path: Path) -> None:
    args = ["--objects", "013_apple", "--poses", "2", "--no-execute", "--policies", "random"]
    runs = []
    for k in range(2):
        assert _run(tmp_path / f"r{k}", *args) == 0
        results = json.loads((tmp_path / f"r{k}" / "results.json").read_text())
        poses = results["policies"]["random"]["objects"]["013_apple"]["poses"]
        runs.append([(p["path"], p["steps"], p["grasp"]) for p in poses])
    assert runs[0] == runs[1]


def test_bad_objects_are_reported_and_the_others_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = tmp_path / "objects"
    good = folder / "small_box"
    good.mkdir(parents=True)
    trimesh.creation.box(extents=(0.03, 0.05, 0.06)).export(str(good / "box.obj"))
    (good / "model.urdf").write_text(
        '<robot name="b"><link name="base"><visual><geometry><mesh filename="box.obj"/>'
        "</geometry></visual></link></robot>"
    )
    broken = folder / "broken"
    broken.mkdir()
    (broken / "model.urdf").write_text('<robot name="x"><link name="base"></link></robot>')
    huge = folder / "huge"
    huge.mkdir()
    trimesh.creation.box(extents=(0.5, 0.5, 0.5)).export(str(huge / "huge.obj"))
    (huge / "model.urdf").write_text(
        '<robot name="h"><link name="base"><visual><geometry><mesh filename="huge.obj"/>'
        "</geometry></visual></link></robot>"
    )
    out = tmp_path / "run"
    args = ["--object-dir", str(folder), "--poses", "1", "--no-execute", "--policies", "brick"]
    assert _run(out, *args) == 1  # errors: exit 1, results kept
    err = capsys.readouterr().err
    assert "broken" in err and "huge" in err and "larger than the workspace" in err
    results = json.loads((out / "results.json").read_text())
    assert set(results["errors"]) == {"broken", "huge"}
    small = results["policies"]["brick"]["objects"]["small_box"]
    assert len(small["poses"]) == 1
    # At rest on its largest face (the most stable pose): the 6 cm side is not vertical.
    grasp = small["poses"][0]["grasp"]
    assert grasp is None or grasp["contacts"][0][2] < 0.05


def test_a_ycb_download_runs_the_protocol_objects_asked_for_as_they_rest(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from heapgrasp.viewsphere.objects import stand_in

    ((v, f),) = stand_in("003_cracker_box")
    y_up = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    folder = tmp_path / "ycb"
    for name, mesh in (
        ("003_cracker_box", "google_16k/textured.obj"),
        ("004_sugar_box", "textured.obj"),
    ):
        (folder / name / mesh).parent.mkdir(parents=True)
        trimesh.Trimesh(v @ y_up, f).export(str(folder / name / mesh))
    args = ["--object-dir", str(folder), "--objects", "003_cracker_box,025_mug"]
    assert _run(tmp_path / "run", *args, "--poses", "1", "--no-execute", "--policies", "brick") == 1
    results = json.loads((tmp_path / "run" / "results.json").read_text())
    assert list(results["policies"]["brick"]["objects"]) == ["003_cracker_box"]
    placed = results["placements"]["003_cracker_box"]
    assert placed["protocol"] == "003_cracker_box" and placed["exact"]
    assert placed["placement"].startswith("its stable pose 0.210 m tall")
    assert results["errors"] == {"025_mug": f"no object of {folder} is 025_mug"}
    assert "004_sugar_box" not in results["placements"]


@pytest.mark.parametrize(
    "bad, message",
    [
        (["--poses", "101"], "--poses must be at most 100"),
        (["--poses", "0"], "must be >= 1"),
        (["--objects", "teapot"], "unknown object(s) 'teapot'"),
        (["--policies", "greedy"], "unknown policy(s) 'greedy'"),
        (["--policies", "all,brick"], "unknown policy(s) 'all'"),
        (["--set", "voxels=0.01"], "unknown viewsphere setting(s) voxels"),
        (["--set", "voxel=-1"], "ViewsphereConfig.voxel must be > 0"),
    ],
)
def test_bad_arguments_are_refused_naming_them(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], bad: list[str], message: str
) -> None:
    assert _run(tmp_path / "run", *bad) in (1, 2)
    assert message in capsys.readouterr().err


def test_classes_follow_randoms_share_of_bfs() -> None:
    assert classify(0.2, 0.8) == "hard"
    assert classify(0.5, 0.8) == "medium"
    assert classify(0.8, 0.8) == "easy"
    assert classify(0.0, 0.0) == "hard" and classify(None, 0.5) is None
    settings = {
        "policies": ["random", "bfs"],
        "config": {"max_steps": 2, "bfs_max_sets": 10},
        "poses": 2,
    }

    def rec(pose: int, steps_random: int, steps_bfs: int) -> dict[str, object]:
        def entry(s: int) -> dict[str, object]:
            return {"found": s <= 2, "steps": min(s, 2), "seconds": 0.1, "executed": None}

        return {
            "pose": pose,
            "yaw_deg": 0.0,
            "policies": {"random": entry(steps_random), "bfs": entry(steps_bfs)},
        }

    results = summarize(settings, {"box": [rec(0, 1, 1), rec(1, 9, 2)]}, {})
    assert results["policies"]["random"]["objects"]["box"]["success_at_step"] == [0.0, 0.5, 0.5]
    assert results["policies"]["bfs"]["objects"]["box"]["success_at_step"] == [0.0, 0.5, 1.0]
    assert results["policies"]["random"]["objects"]["box"]["mean_steps"] == 1.5
    assert results["classes"]["box"] == {
        "random_at_2": 0.5,
        "bfs_at_2": 1.0,
        "ratio": 0.5,
        "class": "medium",
    }


def test_found_grasps_are_executed_with_the_simulated_hand(tmp_path: Path) -> None:
    out = tmp_path / "run"
    assert _run(out, "--objects", "005_tomato_soup_can", "--poses", "1", "--policies", "brick") == 0
    results = json.loads((out / "results.json").read_text())
    can = results["policies"]["brick"]["objects"]["005_tomato_soup_can"]
    assert can["poses"][0]["found"]
    assert can["poses"][0]["executed"] in {"success", "collision", "empty", "unreachable"}
    assert can["executed"] == 1


def test_the_sensor_model_drops_a_transparent_objects_depth() -> None:
    from heapgrasp.sim.optics import Category
    from heapgrasp.viewsphere.objects import stand_in
    from heapgrasp.viewsphere.world import ViewsphereWorld

    meshes = stand_in("005_tomato_soup_can")
    ideal = ViewsphereWorld(meshes)
    glass = ViewsphereWorld(meshes, sensor=Category.TRANSPARENT, seed=1)
    start = ideal.start
    assert len(glass.object_points([start])[0]) < 0.6 * len(ideal.object_points([start])[0])
    again = ViewsphereWorld(meshes, sensor=Category.TRANSPARENT, seed=1)
    np.testing.assert_array_equal(glass.depth(start), again.depth(start))


def test_ray_without_ray_is_a_clear_message(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import sys

    monkeypatch.setitem(sys.modules, "ray", None)  # importing it fails
    args = ["--objects", "025_mug", "--poses", "1", "--no-execute", "--policies", "brick", "--ray"]
    assert _run(tmp_path / "run", *args) == 2
    assert "pip install 'heapgrasp[ray]'" in capsys.readouterr().err


def _policy_file(path: Path, model: str) -> Path:
    from heapgrasp.viewsphere.learned import N_FEATURES, policy_onnx

    w, b = np.zeros((8, N_FEATURES)), np.arange(8, dtype=np.float64)  # NW first
    path.write_bytes(policy_onnx([(w, b)], hparams={"model": model}, provenance={}))
    return path


def test_a_learned_policy_runs_from_a_given_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    f = _policy_file(tmp_path / "mine.onnx", "dqn")
    out = tmp_path / "run"
    args = ["--objects", "013_apple", "--poses", "1", "--no-execute", "--policies", "dqn"]
    assert _run(out, *args, "--weights", f"dqn={f}") == 0
    results = json.loads((out / "results.json").read_text())
    pose = results["policies"]["dqn"]["objects"]["013_apple"]["poses"][0]
    assert set(pose["path"]) <= {"NW"} and len(pose["decisions_s"]) == pose["steps"]
    assert results["settings"]["weights"]["dqn"]["path"] == str(f)
    # Another file is another run.
    other = _policy_file(tmp_path / "other.onnx", "dqn")
    capsys.readouterr()
    assert _run(out, *args, "--weights", f"dqn={other}") == 2
    assert "other settings (weights)" in capsys.readouterr().err
    # A file of another model, a bad entry, a missing file: refused, naming them.
    wrong = _policy_file(tmp_path / "wrong.onnx", "pca-lr")
    for bad, message in [
        (f"dqn={wrong}", "holds a pca-lr policy, not dqn"),
        ("svm=x.onnx", "--weights wants MODEL=FILE"),
        (f"dqn={tmp_path / 'none.onnx'}", "not found"),
    ]:
        assert _run(tmp_path / "bad", *args, "--weights", bad) == 2
        assert message in capsys.readouterr().err
