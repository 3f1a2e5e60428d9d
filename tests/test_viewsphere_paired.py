"""scripts/viewsphere_paired.py: episodes paired by object and pose, and the sign test."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "viewsphere_paired.py"


def _script() -> ModuleType:
    spec = importlib.util.spec_from_file_location("viewsphere_paired", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _run(root: Path, policy: str, steps: dict[tuple[str, int], int | None]) -> Path:
    (root / "records").mkdir(parents=True)
    by_object: dict[str, list[str]] = {}
    for (obj, pose), n in steps.items():
        episode = {"steps": n if n is not None else 6, "found": n is not None}
        line = json.dumps({"pose": pose, "policies": {policy: episode}})
        by_object.setdefault(obj, []).append(line)
    for obj, lines in by_object.items():
        (root / "records" / f"{obj}.jsonl").write_text("\n".join(lines) + "\n")
    return root


def test_episodes_pair_by_object_and_pose_and_a_miss_counts_six(tmp_path: Path) -> None:
    s = _script()
    a = _run(tmp_path / "a", "dqn", {("cup", 0): 2, ("cup", 1): None, ("box", 0): 1})
    b = _run(tmp_path / "b", "brick", {("cup", 0): 1, ("cup", 1): 3, ("bowl", 0): 1})
    assert s.episode_steps(a, "dqn") == {("cup", 0): 2, ("cup", 1): 6, ("box", 0): 1}
    out = subprocess.run(
        [sys.executable, str(SCRIPT), str(a), "dqn", str(b), "brick"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    assert "episodes in common: 2 (left out: 2)" in out
    assert "mean steps: dqn 4.00, brick 2.00" in out
    assert "fewer moves in 2, more in 0" in out


def test_the_sign_test_is_exact_and_two_sided() -> None:
    s = _script()
    assert s.sign_test(0, 0) == 1.0
    assert s.sign_test(3, 3) == 1.0
    assert s.sign_test(5, 0) == pytest.approx(2 / 32)
    assert s.sign_test(0, 5) == s.sign_test(5, 0)
    assert s.sign_test(9, 1) == pytest.approx(2 * 11 / 1024)


def test_a_folder_without_records_or_the_policy_is_named(tmp_path: Path) -> None:
    s = _script()
    with pytest.raises(SystemExit, match="no records"):
        s.episode_steps(tmp_path, "dqn")
    run = _run(tmp_path / "a", "dqn", {("cup", 0): 1})
    with pytest.raises(SystemExit, match="no episodes of policy 'brick'"):
        s.episode_steps(run, "brick")
