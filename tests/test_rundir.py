"""Results you can trust (issue 36): a resume continues the run as it was configured,
records are keyed by scene and checked, one writer per run directory, clean appends."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from heapgrasp.cli import main
from heapgrasp.loop.config import ConfigError, RunConfig
from heapgrasp.results.records import RecordError, RunDir, RunLockedError
from heapgrasp.run import RunExistsError, run

#: Small and fast: two upright objects, one grasp attempt per scene.
ARGS = ["--method", "no-vp", "--objects", "2", "--layout", "packed", "--quiet"]
SETS = ["--set", "max_attempts=1"]


def _config(**changes: object) -> RunConfig:
    base = RunConfig(method="no-vp", objects=2, layout="packed", max_attempts=1)
    return base.replace(changes)


def _interrupted(out: Path, config: RunConfig) -> None:
    def stop(record: dict[str, object]) -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run(config, out, progress=False, on_scene=stop)


# ---------------------------------------------------------------- 1. resume as the hint says
def test_resume_as_the_hint_says_continues_the_run_as_configured(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    config = _config(scenes=3, seed=31337)
    _interrupted(out, config)
    assert [r["scene"] for r in RunDir(out).records()] == [0]
    # exactly the hint: no other flag
    assert main(["run", "--resume", "--out", str(out), "--quiet"]) == 0
    saved = json.loads((out / "config.json").read_text())
    assert saved["scenes"] == 3 and saved["seed"] == 31337
    assert sorted(r["scene"] for r in RunDir(out).records()) == [0, 1, 2]
    assert json.loads((out / "results.json").read_text())["scenes_completed"] == 3
    capsys.readouterr()


def test_flags_given_with_resume_may_only_repeat_the_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    out.mkdir()
    RunDir(out).write_config(_config(scenes=3, seed=31337))
    argv = ["run", "--resume", "--out", str(out), "--quiet"]
    assert main([*argv, "--scenes", "1"]) == 2
    err = capsys.readouterr().err
    assert "would change scenes: 3 -> 1" in err and "Traceback" not in err
    assert main([*argv, "--set", "seed=0"]) == 2
    assert "seed: 31337 -> 0" in capsys.readouterr().err
    # repeating the run's own settings is fine (the print shows what would run)
    assert main([*argv, "--seed", "31337", "--method", "no-vp", "--print-config"]) == 0
    assert '"scenes": 3' in capsys.readouterr().out
    assert main(["run", "--resume", "--quiet"]) == 2
    assert "name the run to continue with --out" in capsys.readouterr().err
    assert main(["run", "--resume", "--out", str(tmp_path / "none"), "--quiet"]) == 2
    assert "holds no run to continue (config.json not found)" in capsys.readouterr().err


def test_a_resume_that_differs_exits_2_from_the_library_too(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    _interrupted(out, _config(scenes=2))
    with pytest.raises(ConfigError, match="objects: 2 -> 3"):
        run(_config(scenes=2, objects=3), out, resume=True, progress=False)
    with pytest.raises(ConfigError, match="scenes: 2 -> 5"):
        run(_config(scenes=5), out, resume=True, progress=False)
    # bench sim resumes each method's run the same way
    bench = tmp_path / "bench"
    RunDir(bench / "no-vp").lock().unlock()
    RunDir(bench / "no-vp").write_config(_config(scenes=2))
    argv = ["bench", "sim", "--methods", "no-vp", "--scenes", "4", "--out", str(bench)]
    assert main([*argv, "--resume", "--quiet", "--no-figures"]) == 2
    assert "scenes: 2 -> 4" in capsys.readouterr().err


# ---------------------------------------------------------------- 3. records keyed by scene
def _run_dir(tmp_path: Path, lines: list[str], scenes: int = 4) -> RunDir:
    out = tmp_path / "run"
    out.mkdir()
    rundir = RunDir(out)
    rundir.write_config(_config(scenes=scenes))
    rundir.scenes_file.write_text("".join(line + "\n" for line in lines))
    return rundir


def _record(scene: int) -> str:
    return json.dumps({"scene": scene, "phases": [], "category": "mixed"})


@pytest.mark.parametrize(
    ("lines", "match"),
    [
        ([_record(0), _record(1), _record(1)], r"scenes.jsonl:3: scene 1 is recorded twice"),
        ([_record(0), _record(7)], r"scenes.jsonl:2: scene 7 is not in this run \(scenes 0 to 3\)"),
        ([_record(0), "{}"], r"scenes.jsonl:2: not a scene record"),
        (["[1, 2]"], r"scenes.jsonl:1: not a scene record"),
        (['{"scene": true}'], r"scenes.jsonl:1: not a scene record"),
        (["not json", _record(0)], r"scenes.jsonl:1: not a JSON record"),
        ([_record(-1)], r"scene -1 is not in this run"),
    ],
)
def test_records_that_cannot_be_trusted_are_refused_naming_the_line(
    tmp_path: Path, lines: list[str], match: str, capsys: pytest.CaptureFixture[str]
) -> None:
    rundir = _run_dir(tmp_path, lines)
    with pytest.raises(RecordError, match=match):
        rundir.records()
    # the command line says so and exits 2, writing nothing
    before = rundir.scenes_file.read_text()
    assert main(["run", "--resume", "--out", str(rundir.path), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "scenes.jsonl" in err and "Traceback" not in err
    assert rundir.scenes_file.read_text() == before


# ---------------------------------------------------------------- 4. one writer
def test_a_second_writer_fails_at_once_naming_the_holder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    with RunDir(out):
        with pytest.raises(RunLockedError, match=rf"being written by pid {os.getpid()}"):
            RunDir(out).lock()
        # another process
        code = (
            "import sys; from heapgrasp.cli import main; "
            f"sys.exit(main(['run', '--out', {str(out)!r}, '--quiet']))"
        )
        done = subprocess.run(
            [sys.executable, "-c", code], capture_output=True, text=True, timeout=300
        )
        assert done.returncode == 2, done.stderr[-2000:]
        assert f"being written by pid {os.getpid()}" in done.stderr
    # released: the lock goes with its holder
    RunDir(out).lock().unlock()


# ---------------------------------------------------------------- 5. clean appends
def test_a_torn_first_record_does_not_swallow_the_next_one(tmp_path: Path) -> None:
    out = tmp_path / "run"
    out.mkdir()
    rundir = RunDir(out)
    config = _config(scenes=2)
    rundir.write_config(config)
    rundir.scenes_file.write_text('{"scene": 0, "phases": [{"outc')  # killed mid-write
    run(config, out, progress=False)  # no --resume: the torn scene never finished
    records = rundir.records()
    assert sorted(r["scene"] for r in records) == [0, 1]
    assert rundir.scenes_file.read_text().count("\n") == 2


# ---------------------------------------------------------------- 6. the saved configuration
def test_a_run_whose_configuration_cannot_be_read_is_not_resumed(tmp_path: Path) -> None:
    rundir = _run_dir(tmp_path, [_record(0)])
    rundir.config_file.write_text('{"method": "no-vp", "objec')
    with pytest.raises(ConfigError, match=r"config.json: cannot be read as a run's config"):
        run(_config(scenes=4), rundir.path, resume=True, progress=False)
    rundir.config_file.unlink()
    with pytest.raises(ConfigError, match=r"config.json is missing, so the 1 record"):
        run(_config(scenes=4), rundir.path, resume=True, progress=False)
    rundir.config_file.write_text("[1, 2]")
    with pytest.raises(ConfigError, match="is a JSON object"):
        rundir.read_config()


def test_a_directory_holding_a_run_needs_resume(tmp_path: Path) -> None:
    rundir = _run_dir(tmp_path, [_record(0)])
    with pytest.raises(RunExistsError, match="--resume"):
        run(_config(scenes=4), rundir.path, progress=False)


# ---------------------------------------------------------------- 7. objects that fit
def test_objects_that_cannot_fit_are_refused_and_those_placed_are_recorded(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "big"
    assert main(["run", "--objects", "100", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "objects: 100 cannot be placed" in err and "side by side" in err
    assert not out.exists()
    # a pile drops some: said, and recorded
    summary = run(
        RunConfig(method="no-vp", objects=12, max_attempts=1), tmp_path / "pile", progress=False
    )
    (record,) = RunDir(tmp_path / "pile").records()
    assert record["objects_requested"] == 12 and record["objects_total"] < 12
    assert summary["objects_requested"] == 12
    assert f"placed {record['objects_total']} of 12 objects" in capsys.readouterr().err


def test_a_configuration_error_exits_2_in_every_command(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "data"
    assert main(["critic", "data", "--set", "nonsense=1", "--out", str(out)]) == 2
    assert "unknown parameter 'nonsense'" in capsys.readouterr().err
    assert main(["bench", "sim", "--set", "nonsense=1", "--out", str(tmp_path / "b")]) == 2
    capsys.readouterr()


def test_a_run_saved_before_look_again_is_read_as_it_ran(tmp_path: Path) -> None:
    # look_again's default (2) is not what runs made before it did: they stopped at once.
    rundir = RunDir(tmp_path / "old")
    rundir.path.mkdir()
    saved = RunConfig().to_dict()
    del saved["look_again"]
    rundir.config_file.write_text(json.dumps(saved))
    config = rundir.read_config()
    assert config is not None and config.look_again == 0
    assert config == RunConfig(look_again=0)
    # a saved value is kept as it is
    rundir.write_config(RunConfig(look_again=1))
    again = rundir.read_config()
    assert again is not None and again.look_again == 1


def test_a_bad_segmentation_file_is_refused_before_any_scene(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    junk = tmp_path / "seg.onnx"
    junk.write_bytes(os.urandom(256))
    out = tmp_path / "run"
    argv = ["run", "--objects", "2", "--quiet", "--out", str(out)]
    assert main([*argv, "--set", "segmenter=network", "--set", f"seg_weights={junk}"]) == 2
    assert "seg_weights" in capsys.readouterr().err
    assert not (out / "scenes.jsonl").exists()
