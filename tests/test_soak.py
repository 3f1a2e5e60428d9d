"""The kill soak, short (scripts/kill_soak.py; the long one is recorded in
docs/reliability.md): a run killed with SIGKILL and resumed ends as if never killed."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parent.parent / "scripts" / "kill_soak.py"


def test_a_run_killed_and_resumed_ends_as_an_uninterrupted_one(tmp_path: Path) -> None:
    argv = ["--scenes", "3", "--objects", "2", "--kills", "3", "--max-wait", "4"]
    done = subprocess.run(
        [sys.executable, str(SCRIPT), *argv, "--torn", "0.5", "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    summary = json.loads((tmp_path / "soak.json").read_text())
    assert done.returncode == 0, (summary, done.stderr[-2000:])
    assert summary["scenes_differing"] == [] and summary["results_equal"]
    assert summary["scenes_recorded"] == 3


def test_datasets_and_the_viewsphere_benchmark_survive_kills_of_their_parent(
    tmp_path: Path,
) -> None:
    # the parent alone is killed: its pool's workers must end by themselves, and every
    # rerun resumes to the same shards (byte for byte) and the same pose records
    for target, scenes in (("data-grasps", 8), ("viewsphere", 3)):
        out = tmp_path / target
        argv = ["--target", target, "--scenes", str(scenes), "--kills", "3", "--max-wait", "3"]
        argv += ["--kill", "parent", "--workers", "2", "--out", str(out)]
        done = subprocess.run(
            [sys.executable, str(SCRIPT), *argv],
            capture_output=True,
            text=True,
            timeout=600,
            check=False,
        )
        summary = json.loads((out / "soak.json").read_text())
        assert done.returncode == 0, (target, summary, done.stderr[-2000:])
        assert summary["left_running"] == 0 and summary["results_equal"]
        assert summary["scenes_differing"] == []
