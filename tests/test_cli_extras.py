"""A command that needs an optional dependency which is not installed ends with one line
naming the extra that brings it, and exit status 2 — never a traceback."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from heapgrasp.cli import OPTIONAL_MODULES, install_hint, main


@pytest.mark.parametrize(
    ("missing", "argv", "extra"),
    [
        ("torch", ["bench", "seg", "--size", "64x64", "--repeats", "1"], "train"),
        ("cv2", ["robot", "board", "{tmp}/board.png"], "robot"),
        ("cv2", ["robot", "calibrate", "--synthetic", "--out", "{tmp}/cal"], "robot"),
    ],
)
def test_a_missing_extra_is_one_line_and_exit_2(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    missing: str,
    argv: list[str],
    extra: str,
) -> None:
    monkeypatch.setitem(sys.modules, missing, None)  # `import missing` raises ImportError
    code = main([a.replace("{tmp}", str(tmp_path)) for a in argv])
    err = capsys.readouterr().err
    assert code == 2
    assert f"pip install 'heapgrasp[{extra}]'" in err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not list(tmp_path.iterdir())  # nothing written


def test_install_hint_names_the_extra_or_keeps_the_message() -> None:
    err = ModuleNotFoundError("No module named 'rerun'", name="rerun")
    assert install_hint(err).endswith("pip install 'heapgrasp[viz]'")
    own = ImportError("training needs PyTorch: pip install 'heapgrasp[train]'")
    assert install_hint(own) == str(own)
    other = ModuleNotFoundError("No module named 'networkx'", name="networkx")
    assert "reinstall heapgrasp" in install_hint(other)
    assert OPTIONAL_MODULES["cv2"] == "robot" and OPTIONAL_MODULES["torch"] == "train"
